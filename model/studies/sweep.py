"""Parameter sweeps: many runs of one configuration with some keys set to lists of values, one table.

    sweep(config, {"material.0.E": [1e4, 2e4], "loading.steps": [1, 2]}, jobs=1, mode="grid", out=DIR)

runs the Cartesian product of the values (mode "grid"; "zip" pairs the i-th values of every key, which
needs equal numbers of values) and returns a pandas DataFrame, also written to DIR/sweep.csv (and
DIR/sweep.parquet when pyarrow imports). Before any run starts every run's document (the file with its
overrides, model.config.overrides.apply) is checked like a file (model.config.parse): one bad value
stops the sweep with a one-line ConfigError naming the run, the key and the value, and nothing runs.

Each run lives in DIR/runs/HASH/ (HASH = model.studies.runs.config_hash of its resolved document) with
resolved.toml, stdout.log, stderr.log and the run's outputs; it runs in a child process
(model.studies.runs), at most ``jobs`` at a time, so a crash or kill of one run never ends the sweep.
Sweeping again into DIR skips the runs whose summary.json says "completed" and redoes the others
(failed, interrupted, killed). Runs whose resolved documents are equal run once.

The table has one row per run and converged step (a run with no converged step has one row, with empty
step columns): the swept keys (one column each, named by the key; arrays and tables as JSON text), "run"
(the hash), "status" (completed, failed, interrupted, crashed, invalid: model.studies.runs.outcome),
"snes_reason" (the SNES reason name of its last failed step), "reason" (why the run did not complete: the
run's failure message, or the last line of its stderr), "step" (1, 2, ... over the converged steps),
"load_factor", "time" (dynamic runs), "probe.NAME.x|y|z",
"reaction.BOUNDARY.x|y|z", the energies (strain_energy, ..., total_potential, kinetic_energy),
"volume.REGION", "newton_iterations", "linear_iterations", "residual_norm", "solve_time_s" and the run's
"wall_time_s". Column order: keys, run columns, step columns as they first appear.
"""

from __future__ import annotations

import itertools
import json
import logging
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from model.config import parse, read
from model.config.overrides import apply, parse_value, split_values
from model.errors import ConfigError
from model.studies import runs

log = logging.getLogger(__name__)

MODES = ("grid", "zip")
COMPONENTS = ("x", "y", "z")
#: step entries that are not numbers of the table (or are spread into columns of their own)
_SKIP = {"converged", "snes_reason", "snes_reason_name", "probes", "reactions", "volumes", "activation",
         "reactions_exclusive", "reactions_shared",
         "contact", "sliding", "largest_residual"}


def parse_set(item: str) -> tuple[str, list[Any]]:
    """"KEY=V1,V2,..." -> (KEY, [values parsed as TOML]); ConfigError naming the item otherwise."""
    key, sep, text = item.partition("=")
    key = key.strip()
    if not sep or not key or not text.strip():
        raise ConfigError(f"--set {item!r}: write KEY=V1,V2,... e.g. material.0.E=1e4,2e4")
    texts = split_values(text)
    if any(not t for t in texts):
        raise ConfigError(f"--set {key}: an empty value in {text!r}")
    values = []
    for t in texts:
        try:
            values.append(parse_value(t))
        except ConfigError as err:
            raise ConfigError(f"--set {key}: {err}") from None
    return key, values


def parse_sets(items: Sequence[str]) -> dict[str, list[Any]]:
    """{KEY: values} from --set items (ConfigError when a key is given twice)."""
    out: dict[str, list[Any]] = {}
    for item in items:
        key, values = parse_set(item)
        if key in out:
            raise ConfigError(f"--set {key}: given twice (list all its values in one --set)")
        out[key] = values
    return out


def combinations(values: Mapping[str, Sequence[Any]], mode: str = "grid") -> list[dict[str, Any]]:
    """The overrides of each run: grid, the Cartesian product (the last key varies fastest); zip, the i-th
    value of every key (equal numbers of values)."""
    if mode not in MODES:
        raise ConfigError(f"mode: {mode!r} is not one of {', '.join(MODES)}")
    if not values:
        raise ConfigError("--set: give at least one KEY=V1,V2,... to sweep")
    keys = list(values)
    lists = []
    for key in keys:
        v = values[key]
        if isinstance(v, (str, bytes)) or not isinstance(v, Sequence) or len(v) == 0:
            raise ConfigError(f"{key}: give a non-empty list of values, not {v!r}")
        lists.append(list(v))
    if mode == "zip":
        lengths = {len(v) for v in lists}
        if len(lengths) > 1:
            counts = ", ".join(f"{k} has {len(v)}" for k, v in zip(keys, lists))
            raise ConfigError(f"--zip needs the same number of values for every key: {counts}")
        rows = zip(*lists)
    else:
        rows = itertools.product(*lists)
    return [dict(zip(keys, row)) for row in rows]


@dataclass(frozen=True)
class PlannedRun:
    """One run of a sweep: its overrides, resolved document and hash."""

    index: int
    overrides: dict[str, Any]
    raw: dict[str, Any]
    hash: str


def _show(value: Any) -> str:
    return json.dumps(value) if isinstance(value, (list, dict, str)) else str(value)


def plan(config: str | Path, values: Mapping[str, Sequence[Any]], mode: str = "grid") -> list[PlannedRun]:
    """Every run's resolved document, each checked like a file before any run starts.

    ConfigError "run I (KEY=VALUE, ...): MESSAGE" (MESSAGE the checker's, starting with the dotted key)
    for the first run that does not check.
    """
    config = Path(config)
    raw = read(config)
    planned = []
    for i, overrides in enumerate(combinations(values, mode), start=1):
        what = ", ".join(f"{k}={_show(v)}" for k, v in overrides.items())
        try:
            resolved = apply(raw, overrides)
            parse(resolved, config.parent)
        except ConfigError as err:
            raise ConfigError(f"run {i} ({what}): {err}") from None
        planned.append(PlannedRun(i, dict(overrides), resolved, runs.config_hash(resolved)))
    return planned


class _Progress:
    """A tqdm bar with ETA when standard output is a terminal, else one log line per finished run."""

    def __init__(self, total: int) -> None:
        self.total, self.done = total, 0
        self.bar = None
        if sys.stdout.isatty() and total:
            from tqdm import tqdm

            self.bar = tqdm(total=total, unit="run", desc="sweep", file=sys.stdout)

    def finished(self, run: PlannedRun, result: runs.Outcome, seconds: float) -> None:
        self.done += 1
        what = ", ".join(f"{k}={_show(v)}" for k, v in run.overrides.items())
        line = f"run {self.done}/{self.total} {run.hash} ({what}): {result.status}" + \
            (f" ({result.reason})" if result.reason else "") + f", {seconds:.1f} s"
        if self.bar is not None:
            self.bar.set_postfix_str(f"{run.hash} {result.status}", refresh=False)
            self.bar.update(1)
            if result.status != "completed":
                self.bar.write(line)
        else:
            log.info("%s", line)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def execute(todo: Sequence[PlannedRun], base: Path, out: Path, jobs: int = 1,
            poll: float = 0.05) -> dict[str, runs.Outcome]:
    """Run each planned run in a child process, at most ``jobs`` at a time; {hash: Outcome}."""
    results: dict[str, runs.Outcome] = {}
    progress = _Progress(len(todo))
    pending = list(todo)
    active: dict[str, tuple[PlannedRun, Any, float]] = {}
    try:
        while pending or active:
            while pending and len(active) < jobs:
                run = pending.pop(0)
                run_dir = out / "runs" / run.hash
                runs.write_resolved(run.raw, run_dir)
                active[run.hash] = (run, runs.start(run_dir, base), time.perf_counter())
            for key, (run, process, started) in list(active.items()):
                code = process.poll()
                if code is None:
                    continue
                del active[key]
                results[key] = runs.outcome(out / "runs" / key, code)
                progress.finished(run, results[key], time.perf_counter() - started)
            if active:
                time.sleep(poll)
    finally:
        for _, process, _ in active.values():  # only when interrupted: stop the children too
            process.kill()
            process.wait()
        progress.close()
    return results


def _flatten_step(step: Mapping[str, Any]) -> dict[str, Any]:
    row: dict[str, Any] = {}
    for key, value in step.items():
        if key in _SKIP or isinstance(value, (dict, list)) or isinstance(value, bool):
            continue
        if isinstance(value, (int, float)):
            row[key] = value
    for prefix, section in (("probe", "probes"), ("reaction", "reactions")):
        for name, vector in (step.get(section) or {}).items():
            vector = vector if isinstance(vector, list) else [vector]
            names = COMPONENTS if len(vector) == 3 else [str(i) for i in range(len(vector))]
            for comp, v in zip(names, vector):
                row[f"{prefix}.{name}.{comp}"] = v
    for name, v in (step.get("volumes") or {}).items():
        row[f"volume.{name}"] = v
    return row


def rows(run: PlannedRun, result: runs.Outcome) -> list[dict[str, Any]]:
    """The table rows of one run: one per converged step (one with the run columns only when none)."""
    head = {k: (json.dumps(v) if isinstance(v, (list, dict)) else v) for k, v in run.overrides.items()}
    head.update(run=run.hash, status=result.status, snes_reason=result.snes_reason, reason=result.reason)
    wall = result.summary.get("wall_time_s")
    converged = [s for s in result.summary.get("steps", []) if isinstance(s, dict) and s.get("converged")]
    if not converged:
        return [{**head, "wall_time_s": wall}]
    return [{**head, "step": i, **_flatten_step(s), "wall_time_s": wall} for i, s in enumerate(converged, start=1)]


def table(planned: Sequence[PlannedRun], results: Mapping[str, runs.Outcome]) -> Any:
    """The sweep's DataFrame (module docstring) from the planned runs and their outcomes."""
    import pandas as pd

    records = [r for run in planned for r in rows(run, results[run.hash])]
    columns: dict[str, None] = {}
    for record in records:
        columns.update(dict.fromkeys(record))
    frame = pd.DataFrame.from_records(records, columns=list(columns))
    if "step" in frame:
        frame["step"] = frame["step"].astype("Int64")
    return frame


def write_table(frame: Any, out: Path) -> list[Path]:
    """DIR/sweep.csv, and DIR/sweep.parquet when pyarrow imports; the paths written."""
    written = [out / "sweep.csv"]
    frame.to_csv(written[0], index=False)
    try:
        import pyarrow  # noqa: F401
    except ImportError:
        return written
    written.append(out / "sweep.parquet")
    frame.to_parquet(written[1], index=False)
    return written


def sweep(config: str | Path, values: Mapping[str, Sequence[Any]], jobs: int = 1, mode: str = "grid",
          out: str | Path = "sweep") -> Any:
    """Run ``config`` for every combination of ``values`` ({dotted key: [values]}); the table as a DataFrame.

    Values are Python values (the command line parses them as TOML). Every run is checked before any
    starts (ConfigError naming the run, key and value); runs completed by an earlier sweep into ``out``
    are skipped. A failed run is rows with its status and reason, never an exception. ``frame.attrs``
    holds "ran" and "skipped" (numbers of runs) and "files" (the table files). Serial only: the runs
    are child processes (ConfigError under mpirun with more than one rank).
    """
    from mpi4py import MPI

    if MPI.COMM_WORLD.size > 1:
        raise ConfigError(f"sweep: runs on one rank and starts its runs as child processes; start it without "
                          f"mpirun (it has {MPI.COMM_WORLD.size} ranks)")
    if not isinstance(jobs, int) or isinstance(jobs, bool) or jobs < 1:
        raise ConfigError(f"--jobs: {jobs!r} is not a positive whole number")
    config, out = Path(config), Path(out)
    planned = plan(config, values, mode)
    unique = list({run.hash: run for run in planned}.values())
    results: dict[str, runs.Outcome] = {}
    todo = []
    for run in unique:
        done = runs.outcome(out / "runs" / run.hash)
        if done.status == "completed":
            results[run.hash] = done
        else:
            todo.append(run)
    log.info("sweep of %d runs (%s) into %s: %d completed earlier, %d to run, %d at a time", len(planned), mode,
             out, len(results), len(todo), min(jobs, max(len(todo), 1)))
    out.mkdir(parents=True, exist_ok=True)
    results.update(execute(todo, config.parent.resolve(), out, jobs))
    frame = table(planned, results)
    files = write_table(frame, out)
    failed = sum(1 for r in unique if results[r.hash].status != "completed")
    log.info("sweep done: %d runs, %d failed; table %s", len(unique), failed, ", ".join(str(f) for f in files))
    frame.attrs.update(ran=len(todo), skipped=len(unique) - len(todo), failed=failed,
                       files=[str(f) for f in files])
    return frame
