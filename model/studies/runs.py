"""One run of a resolved configuration in a child process, and what it left behind.

A study (model.studies.sweep, model.studies.convergence) writes each run's resolved configuration
(the TOML document after its overrides) to ``RUN_DIR/resolved.toml`` and starts

    python -m model.studies.runs RUN_DIR/resolved.toml --base BASE --out RUN_DIR

(started as ``python -c "...main(...)"`` with these arguments) which checks the document exactly like
``python -m model run`` (file paths in it relative to BASE,
the folder of the study's configuration file) and runs it, with the exit codes of ``model run``
(0 completed, 1 solve failed, 2 bad input). Its standard output and error go to RUN_DIR/stdout.log and
RUN_DIR/stderr.log. The child has one OpenMP/BLAS thread, so N children use N cores; on Linux it is
killed when the study's process dies (PR_SET_PDEATHSIG), so a killed study leaves no runs behind.

A run is keyed by ``config_hash(raw)``: the first 16 hex digits of SHA-256 of the canonical JSON of the
resolved document (keys sorted, no whitespace, ASCII), the same in every process and on every machine.
``outcome(run_dir, returncode)`` reads RUN_DIR/summary.json: its status ("completed", "failed",
"running" when the run was killed, "interrupted") and the reason a run failed (summary "failure", else
the SNES reason of its last failed step, else the last line of stderr.log) and that SNES reason name.
"""

from __future__ import annotations

import argparse
import ctypes
import hashlib
import json
import logging
import math
import os
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

RESOLVED = "resolved.toml"
SUMMARY = "summary.json"
STDOUT, STDERR = "stdout.log", "stderr.log"
_PROJECT = Path(__file__).resolve().parents[2]
#: the child's program (``-c`` rather than ``-m model.studies.runs``, which the package's own import of this
#: module makes runpy warn about)
_CHILD = "import sys; from model.studies.runs import main; sys.exit(main(sys.argv[1:]))"


def canonical_json(raw: Any) -> str:
    """The canonical JSON of a document: keys sorted, separators without spaces, ASCII only."""
    return json.dumps(raw, sort_keys=True, separators=(",", ":"), ensure_ascii=True, default=str)


def config_hash(raw: dict[str, Any]) -> str:
    """hash = sha256(canonical_json(raw))[:16] (hex): the key of a run, stable across processes."""
    return hashlib.sha256(canonical_json(raw).encode("ascii")).hexdigest()[:16]


def toml_value(value: Any, where: str = "value") -> str:
    """One TOML value (inline tables and arrays; nan and +-inf as TOML writes them); ValueError naming ``where``."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v, where) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{json.dumps(str(k))} = {toml_value(v, where)}" for k, v in value.items()) + " }"
    raise ValueError(f"{where}: cannot write {value!r} as TOML")


def toml_text(raw: dict[str, Any]) -> str:
    """A parsed configuration document as TOML: top-level values, then one [table] per section and one
    [[table]] per entry of an array of tables, nested tables inline. tomllib.loads(toml_text(raw)) == raw."""
    lines = [f"{json.dumps(k)} = {toml_value(v, k)}" for k, v in raw.items()
             if not isinstance(v, dict) and not (isinstance(v, list) and v and all(isinstance(t, dict) for t in v))]
    for key, body in raw.items():
        if isinstance(body, dict):
            lines.append(f"[{json.dumps(key)}]")
            lines += [f"{json.dumps(k)} = {toml_value(v, f'{key}.{k}')}" for k, v in body.items()]
        elif isinstance(body, list) and body and all(isinstance(t, dict) for t in body):
            for i, table in enumerate(body):
                lines.append(f"[[{json.dumps(key)}]]")
                lines += [f"{json.dumps(k)} = {toml_value(v, f'{key}.{i}.{k}')}" for k, v in table.items()]
    return "\n".join(lines) + "\n"


def write_resolved(raw: dict[str, Any], run_dir: Path) -> Path:
    """RUN_DIR/resolved.toml (atomically), checked to read back as ``raw``."""
    import tomllib

    text = toml_text(raw)
    if tomllib.loads(text) != raw:  # nan != nan: compare the canonical forms
        if canonical_json(tomllib.loads(text)) != canonical_json(raw):
            raise ValueError(f"{run_dir}: the resolved configuration does not survive a TOML round trip")
    run_dir.mkdir(parents=True, exist_ok=True)
    path = run_dir / RESOLVED
    tmp = path.with_suffix(".toml.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)
    return path


def child_environment() -> dict[str, str]:
    """This process's environment with the project first on PYTHONPATH and one OpenMP/BLAS thread."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(_PROJECT), os.environ.get("PYTHONPATH")]))
    env.update(OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    return env


def _die_with_parent() -> None:  # pragma: no cover - runs in the child between fork and exec
    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, 9)  # PR_SET_PDEATHSIG = 1, SIGKILL = 9
    except (OSError, AttributeError):
        pass


def start(run_dir: Path, base: Path) -> subprocess.Popen:
    """Start ``python -m model.studies.runs RUN_DIR/resolved.toml --base BASE --out RUN_DIR`` (logs in RUN_DIR)."""
    run_dir = Path(run_dir)
    command = [sys.executable, "-c", _CHILD, str(run_dir / RESOLVED), "--base", str(base), "--out", str(run_dir)]
    with open(run_dir / STDOUT, "wb") as out, open(run_dir / STDERR, "wb") as err:
        return subprocess.Popen(command, stdout=out, stderr=err, stdin=subprocess.DEVNULL, env=child_environment(),
                                preexec_fn=_die_with_parent if sys.platform.startswith("linux") else None)


@dataclass
class Outcome:
    """What a finished child left: status ("completed", "failed", "running", "interrupted", "crashed",
    "invalid"), the reason it did not complete ("" when completed) and its summary ({} when none)."""

    status: str
    reason: str = ""
    summary: dict[str, Any] = field(default_factory=dict)
    #: the SNES reason name of the last unconverged step ("" when none)
    snes_reason: str = ""


def read_summary(run_dir: Path) -> dict[str, Any]:
    """RUN_DIR/summary.json, or {} when missing or unreadable."""
    try:
        data = json.loads((Path(run_dir) / SUMMARY).read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return {}
    return data if isinstance(data, dict) else {}


def _last_line(path: Path) -> str:
    try:
        lines = [line.strip() for line in path.read_text(errors="replace").splitlines() if line.strip()]
    except OSError:
        return ""
    return lines[-1] if lines else ""


def outcome(run_dir: Path, returncode: int | None = None) -> Outcome:
    """The status and failure reason of the run in RUN_DIR (after its child ended with ``returncode``).

    A summary that says "completed" is a completed run whatever the exit code. Otherwise the status is
    the summary's (a run killed mid-way still says "running"), "invalid" for exit code 2 without a summary,
    else "crashed"; the reason is the summary's "failure", else the "snes_reason_name" of its last
    unconverged step, else the last line of stderr.log, else the exit code.
    """
    run_dir = Path(run_dir)
    summary = read_summary(run_dir)
    status = str(summary.get("status", ""))
    if status == "completed":
        return Outcome("completed", "", summary)
    if not status:
        status = "invalid" if returncode == 2 else "crashed"
    reason = str(summary.get("failure") or "")
    failed = [s for s in summary.get("steps", []) if isinstance(s, dict) and not s.get("converged", True)]
    snes = str(failed[-1].get("snes_reason_name") or "") if failed else ""
    if not reason:
        reason = snes
    if not reason:
        reason = _last_line(run_dir / STDERR)
    if not reason and returncode is not None:
        reason = f"exit code {returncode}" if returncode >= 0 else f"killed by signal {-returncode}"
    if status == "running" and returncode is not None and returncode != 0:
        status = "crashed"  # the child ended without finishing its summary
    return Outcome(status, reason, summary, snes)


def main(argv: list[str] | None = None) -> int:
    """The child: check RESOLVED (paths relative to --base) and run it into --out; exit codes of ``model run``."""
    parser = argparse.ArgumentParser(prog="python -m model.studies.runs", description=main.__doc__)
    parser.add_argument("resolved", type=Path)
    parser.add_argument("--base", type=Path, required=True)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    handler = logging.StreamHandler(sys.stdout)
    handler.setFormatter(logging.Formatter("%(message)s"))
    logger = logging.getLogger("model")
    logger.handlers[:] = [handler]
    logger.setLevel(logging.INFO)
    logger.propagate = False
    from model.config import parse, read
    from model.errors import ConfigError, SolveFailed
    from model.pipeline import run

    try:
        run(parse(read(args.resolved), args.base), args.out)
    except ConfigError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except SolveFailed as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
