"""A fixed-seed sample of tools/fuzz.py: bad inputs, each refused before any solve (1-3 s per case).

Each case runs ``python -m model run ...`` in a subprocess, as the tool does, and fails on a traceback, a hang, a
crash or a silent exit 0 (tools/fuzz.py's classes; docs/verification.md, "Fuzzing the inputs"). The whole tool:
``python tools/fuzz.py --cases 500 --seed 1 --jobs 2 --out fuzz.json``.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import serial_only

from tools import fuzz

SEED, CASES = 7, 30
#: cases the sample holds that are still open (reported, outside the configuration layer): what -> why
OPEN: dict[str, str] = {}


def _cases(work: Path) -> list[fuzz.Case]:
    return fuzz.make_cases(CASES, SEED, work, bad_only=True, timeout=60.0)


SAMPLE = _cases(Path("unused"))


@serial_only
@pytest.mark.parametrize("index", range(len(SAMPLE)),
                         ids=[f"{c.id:02d}-{c.kind}-{c.what[:60]}" for c in SAMPLE])
def test_fuzz_sample(index: int, tmp_path: Path) -> None:
    case = _cases(tmp_path)[index]
    if case.what in OPEN:
        pytest.xfail(OPEN[case.what])
    outcome = fuzz.run_case(case)
    assert outcome.outcome not in fuzz.FAILING, \
        f"{outcome.outcome}: {case.what}\n{outcome.command}\n{outcome.stderr[-1500:]}"
    assert outcome.outcome in ("one-line error", "usage error"), \
        f"{outcome.outcome} (exit {outcome.exit_code}): {case.what}\n{outcome.command}\n{outcome.stderr[-1500:]}"


def test_classification() -> None:
    assert fuzz.classify("bad", 2, "error: loading.steps: must be an integer, got 'abc'\n", False) == "one-line error"
    assert fuzz.classify("bad", 2, "scale check: ...\nerror: mesh.file: cannot read x\n", False) == "one-line error"
    assert fuzz.classify("bad", 1, "Traceback (most recent call last):\n  ...\nValueError: x\n", False) == "traceback"
    assert fuzz.classify("bad", 59, "[0]PETSC ERROR: --- Error Message ---\n", False) == "traceback"
    assert fuzz.classify("bad", 3, "error: internal error (a bug of this program: please report it with "
                                   "/tmp/t.txt): TypeError: x\n", False) == "internal error"
    assert fuzz.classify("bad", None, "", True) == "hang"
    assert fuzz.classify("bad", -11, "", False) == "crash"
    assert fuzz.classify("bad", 0, "", False) == "silent exit 0 on bad input"
    assert fuzz.classify("either", 0, "", False) == "ran"
    assert fuzz.classify("valid", 1, "error: step 1 did not converge: DIVERGED_MAX_IT\n", False) == "solve failed"
    assert fuzz.classify("bad", 2, "usage: python -m model run ...\npython -m model run: error: unrecognized "
                                   "arguments: --outt\n", False) == "usage error"


def test_sample_covers_every_kind_of_bad_input() -> None:
    assert {c.kind for c in SAMPLE} == set(fuzz.KINDS) - {"valid"}
    assert all(c.expect == "bad" for c in SAMPLE)
