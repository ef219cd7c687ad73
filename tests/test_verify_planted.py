"""``verify check`` against the planted bugs of tests/planted_bugs.py: each bug is detected at the default sampling
(``deformation_samples(60, seed)``), gets the diagnosis its entry names (``Report.diagnoses``: a Diagnosis of that
kind whose text contains the entry's substring), and the right formulas pass with no diagnosis.

One Report per entry (``_report``, cached per process), reused by the detection and the hint tests; the entries
are ordered by law so that each law's kernels are compiled (or read from the disk cache) once per process. Runs
serially and under ``mpirun -n 2``: every rank evaluates on MPI.COMM_SELF, writes its own files (a directory per
rank) and must get the same answer; the command-line runs start processes of their own (serial run only, as in
tests/test_verify.py), their files are checked in-process on every rank.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import planted_bugs as pb
import pytest
from conftest import ROOT, environment, serial_only
from mpi4py import MPI

import forms
from model.verify import check, check_file, deformation_samples
from model.verify.report import Report
from model.verify.samples import field_samples

SAMPLES, SEED = 60, 17
#: the kinds a Diagnosis may have, and the regions a "region" diagnosis names
KINDS = ("offset", "factor", "zero", "term", "column_major", "transpose", "layout", "region")
REGIONS = ("det F < 0", "compress", "large stretch", "nearly flat", "rest", "fibre")


def _by_law(entries: list[pb.Planted]) -> list[pb.Planted]:
    order = list(pb.LAWS)
    return sorted(entries, key=lambda e: order.index(e.law))


API_BUGS = _by_law([b for b in pb.BUGS if not b.cli])
CLI_BUGS = _by_law([b for b in pb.BUGS if b.cli])
HINTED = _by_law([b for b in pb.BUGS if b.kind is not None])
CORRECT = _by_law(pb.CORRECT)

_REPORTS: dict[str, Report] = {}
_RUNS: dict[str, subprocess.CompletedProcess] = {}


def ids(entries: list[pb.Planted]) -> list[str]:
    return [e.name for e in entries]


def _samples(law: pb.Law) -> tuple[np.ndarray, list[str], dict[str, np.ndarray]]:
    """The default sampling (whatever deformation_samples draws by default) and the law's fields."""
    F, labels = deformation_samples(SAMPLES, seed=SEED)
    fields = field_samples(law.spec, SAMPLES, SEED) if forms.resolve_law(law.spec).fields else {}
    return F, labels, fields


def _user_arrays(entry: pb.Planted, F: np.ndarray, fields: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    with np.errstate(all="ignore"):  # ln J at det F < 0: NaN, as the reference (left out there)
        return entry.make(F, fields)


@pytest.fixture(scope="module")
def rank_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A directory of this rank's own."""
    return tmp_path_factory.mktemp(f"planted_rank{MPI.COMM_WORLD.rank}")


def _npz(entry: pb.Planted, folder: Path) -> Path:
    """The entry's arrays as ``verify emit`` writes them: F, psi/P/A, the fields, material, params_json, labels
    (and layout)."""
    law = pb.LAWS[entry.law]
    F, labels, fields = _samples(law)
    user = _user_arrays(entry, F, fields)
    data = {"F": F, **{("A" if k == "tangent" else k): v for k, v in user.items()}, **fields,
            "material": np.array(law.spec), "params_json": np.array(json.dumps(law.params)),
            "labels": np.array(labels)}
    if entry.layout != "ijkl":
        data["layout"] = np.array(entry.layout)
    path = folder / f"{entry.name}.npz"
    np.savez(path, **data)
    return path


def _report(entry: pb.Planted, folder: Path) -> Report:
    """The entry's Report (computed once per process): check(...), or check_file of its .npz for a CLI entry."""
    if entry.name not in _REPORTS:
        if entry.cli:
            _REPORTS[entry.name] = check_file(_npz(entry, folder), rtol=entry.rtol)
        else:
            law = pb.LAWS[entry.law]
            F, labels, fields = _samples(law)
            extra = {} if entry.atol is None else {"atol": entry.atol}
            _REPORTS[entry.name] = check(F, **_user_arrays(entry, F, fields), law=law.spec, params=law.params,
                                         fields=fields, layout=entry.layout, rtol=entry.rtol, labels=labels, **extra)
    return _REPORTS[entry.name]


def _cli(entry: pb.Planted, folder: Path) -> subprocess.CompletedProcess:
    """``python -m model verify check FILE`` on the entry's .npz, from the worktree's root (run once)."""
    if entry.name not in _RUNS:
        path = _npz(entry, folder)
        _RUNS[entry.name] = subprocess.run([sys.executable, "-m", "model", "verify", "check", str(path)],
                                           capture_output=True, text=True, env=environment(), cwd=ROOT, timeout=300)
    return _RUNS[entry.name]


def _same_on_every_rank(value: object) -> None:
    values = MPI.COMM_WORLD.allgather(value)
    assert all(v == values[0] for v in values), values


def _diagnoses(report: Report) -> list[str]:
    return [f"{d.quantity} {d.kind}: {d.text}" for d in report.diagnoses]


# --- the catalogue itself ---------------------------------------------------------------------------------------

def test_catalogue_is_complete() -> None:
    names = [b.name for b in pb.BUGS]
    assert len(names) == len(set(names)) and len(names) >= 34
    assert len(CLI_BUGS) >= 3
    assert set(pb.LAWS) >= {"neo_hookean", "stvk", "stable_neo_hookean", "corotated", "fibre"}
    for bug in pb.BUGS:
        assert bug.law in pb.LAWS and bug.quantity in ("psi", "P", "A"), bug.name
        assert set(bug.given) <= {"psi", "P", "tangent"} and bug.given, bug.name
        assert bug.kind is None or bug.kind in KINDS, bug.name
        assert bug.kind is None or bug.contains, bug.name
        if bug.kind == "region":
            assert bug.contains in REGIONS, bug.name
        assert "detect" not in bug.name and "correct" not in bug.name  # the names are test ids


def test_most_bugs_expect_a_hint() -> None:
    """At least 80 % of the planted bugs name the diagnosis they should get."""
    assert len(HINTED) >= 0.8 * len(pb.BUGS), [b.name for b in pb.BUGS if b.kind is None]


# --- detection --------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("bug", API_BUGS, ids=ids(API_BUGS))
def test_detected(bug: pb.Planted, rank_dir: Path) -> None:
    report = _report(bug, rank_dir)
    _same_on_every_rank(report.ok)
    assert not report.ok, str(report)


@pytest.mark.parametrize("bug", CLI_BUGS, ids=ids(CLI_BUGS))
def test_detected_in_the_file(bug: pb.Planted, rank_dir: Path) -> None:
    """The .npz the command line reads, checked in-process (every rank, its own file)."""
    report = _report(bug, rank_dir)
    _same_on_every_rank(report.ok)
    assert not report.ok, str(report)


@serial_only
@pytest.mark.parametrize("bug", CLI_BUGS, ids=ids(CLI_BUGS))
def test_detected_by_the_command_line(bug: pb.Planted, rank_dir: Path) -> None:
    run = _cli(bug, rank_dir)
    assert run.returncode == 1, run.stdout + run.stderr


# --- diagnoses ----------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("bug", HINTED, ids=ids(HINTED))
def test_hint(bug: pb.Planted, rank_dir: Path) -> None:
    report = _report(bug, rank_dir)
    found = any(d.kind == bug.kind and bug.contains in d.text for d in report.diagnoses)
    _same_on_every_rank(found)
    assert found, f"expected a {bug.kind!r} diagnosis containing {bug.contains!r}; got {_diagnoses(report)}"


@serial_only
@pytest.mark.parametrize("bug", CLI_BUGS, ids=ids(CLI_BUGS))
def test_hint_printed_by_the_command_line(bug: pb.Planted, rank_dir: Path) -> None:
    run = _cli(bug, rank_dir)
    assert run.returncode == 1 and bug.contains in run.stdout, run.stdout + run.stderr


# --- right formulas -----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("entry", CORRECT, ids=ids(CORRECT))
def test_correct_formula_passes(entry: pb.Planted, rank_dir: Path) -> None:
    report = _report(entry, rank_dir)
    _same_on_every_rank(report.ok)
    assert report.ok, str(report)


@pytest.mark.parametrize("entry", CORRECT, ids=ids(CORRECT))
def test_right_formula_has_no_diagnosis(entry: pb.Planted, rank_dir: Path) -> None:
    report = _report(entry, rank_dir)
    assert not list(report.diagnoses), _diagnoses(report)
