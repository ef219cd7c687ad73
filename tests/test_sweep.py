"""Parameter sweeps (model.studies.sweep): --set parsing and its one-line errors, grid and zip, the run
hash, validation of every run before any starts, and (serial only: they start processes) sweeps whose
probes equal separate runs, a sweep killed with SIGKILL and restarted, and failed runs as rows."""

from __future__ import annotations

import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import environment, example, run_raw, serial_only, write_toml

from model.config.overrides import apply
from model.errors import ConfigError
from model.studies import runs
from model.studies.sweep import combinations, parse_set, parse_sets, plan, split_values, sweep

TIME_COLUMNS = ["solve_time_s", "wall_time_s"]


def tiny(steps: int = 1) -> dict:
    """The uniaxial example on a 2x2x2 mesh, ``steps`` load steps, no PNG or VTU."""
    raw = example("uniaxial")
    raw["mesh"]["cells"] = [2, 2, 2]
    raw["loading"]["steps"] = steps
    raw["output"].update(png=False, vtu=False)
    return raw


@pytest.fixture
def config(shared_tmp: Path) -> Path:
    from mpi4py import MPI

    path = shared_tmp / "tiny.toml"
    if MPI.COMM_WORLD.rank == 0:
        write_toml(tiny(), path)
    MPI.COMM_WORLD.barrier()
    return path


# --- parsing, no processes -------------------------------------------------------------------------------------

def test_split_values_only_at_top_level_commas() -> None:
    assert split_values("1e4,2e4") == ["1e4", "2e4"]
    assert split_values("[0.1,0],[0.2,0]") == ["[0.1,0]", "[0.2,0]"]
    assert split_values('"a,b",{ x = [1,2] }, c') == ['"a,b"', "{ x = [1,2] }", "c"]


def test_parse_set_values_are_toml() -> None:
    assert parse_set("material.0.E=1e4,2e4") == ("material.0.E", [1e4, 2e4])
    assert parse_set("boundary.0.value=[0.1,0],[0.2,0]") == ("boundary.0.value", [[0.1, 0], [0.2, 0]])
    assert parse_set("material.0.law=neo_hookean,stvk") == ("material.0.law", ["neo_hookean", "stvk"])
    assert parse_set("output.png=true,false") == ("output.png", [True, False])


@pytest.mark.parametrize("items, words", [
    (["material.0.E"], ["--set 'material.0.E'", "KEY=V1,V2"]),
    (["material.0.E="], ["--set 'material.0.E='", "KEY=V1,V2"]),
    (["material.0.E=1e4,,2e4"], ["--set material.0.E", "empty value"]),
    (["material.0.E=1e4,[1,"], ["--set material.0.E", "[1,"]),
    (["loading.steps=1", "loading.steps=2"], ["--set loading.steps", "given twice"]),
])
def test_bad_set_is_one_line_naming_the_key(items: list[str], words: list[str]) -> None:
    with pytest.raises(ConfigError) as err:
        parse_sets(items)
    message = str(err.value)
    assert "\n" not in message
    for word in words:
        assert word in message


def test_grid_is_the_cartesian_product_and_zip_pairs() -> None:
    values = {"a": [1, 2], "b": ["x", "y", "z"]}
    grid = combinations(values, "grid")
    assert grid == [{"a": a, "b": b} for a in (1, 2) for b in ("x", "y", "z")]
    assert combinations({"a": [1, 2], "b": [3, 4]}, "zip") == [{"a": 1, "b": 3}, {"a": 2, "b": 4}]
    with pytest.raises(ConfigError, match=r"^--zip .*: a has 2, b has 3$"):
        combinations(values, "zip")
    with pytest.raises(ConfigError, match="^a: give a non-empty list"):
        combinations({"a": []})
    with pytest.raises(ConfigError, match="^mode: 'diagonal'"):
        combinations({"a": [1]}, "diagonal")


def test_hash_is_sha256_of_canonical_json_and_tells_configs_apart() -> None:
    raw = tiny()
    expected = hashlib.sha256(json.dumps(raw, sort_keys=True, separators=(",", ":")).encode()).hexdigest()[:16]
    assert runs.config_hash(raw) == expected
    reordered = {k: raw[k] for k in reversed(list(raw))}
    reordered["mesh"] = {k: raw["mesh"][k] for k in reversed(list(raw["mesh"]))}
    assert runs.config_hash(reordered) == expected
    other = apply(raw, {"material.0.E": 2e4})
    assert runs.config_hash(other) != expected
    assert runs.config_hash(apply(raw, {"loading.steps": 2})) != expected


@serial_only
def test_hash_is_the_same_in_another_process() -> None:
    raw = tiny()
    code = ("import json, sys; from model.studies.runs import config_hash; "
            "print(config_hash(json.loads(sys.stdin.read())))")
    env = {**environment(), "PYTHONHASHSEED": "12345"}
    out = subprocess.run([sys.executable, "-c", code], input=json.dumps(raw), capture_output=True, text=True,
                         env=env, check=True, timeout=120)
    assert out.stdout.strip() == runs.config_hash(raw)


def test_resolved_toml_reads_back() -> None:
    import tomllib

    raw = apply(tiny(), {"boundary.0.value": [0.1], "solver.petsc_options.ksp_rtol": 1e-12})
    assert tomllib.loads(runs.toml_text(raw)) == raw


def test_outcome_reads_status_and_reason(tmp_path: Path) -> None:
    folder = tmp_path / "run"
    folder.mkdir()
    assert runs.outcome(folder, -9) == runs.Outcome("crashed", "killed by signal 9")
    (folder / "stderr.log").write_text("Traceback ...\nMemoryError: out of memory\n\n")
    assert runs.outcome(folder, 1).reason == "MemoryError: out of memory"
    steps = [{"converged": True}, {"converged": False, "snes_reason_name": "DIVERGED_MAX_IT"}]
    (folder / "summary.json").write_text(json.dumps({"status": "running", "steps": steps}))
    killed = runs.outcome(folder, -9)
    assert (killed.status, killed.reason, killed.snes_reason) == ("crashed", "DIVERGED_MAX_IT", "DIVERGED_MAX_IT")
    assert runs.outcome(folder).status == "running"  # no exit code: a folder found by a later sweep
    (folder / "summary.json").write_text(json.dumps({"status": "failed", "failure": "gave up", "steps": steps}))
    assert runs.outcome(folder, 1) == runs.Outcome("failed", "gave up", json.loads((folder / "summary.json")
                                                                                   .read_text()), "DIVERGED_MAX_IT")
    (folder / "summary.json").write_text(json.dumps({"status": "completed", "steps": steps}))
    assert runs.outcome(folder, -15).status == "completed"


def test_every_run_is_checked_before_any_starts(config: Path) -> None:
    values = {"material.0.E": [1e4, 2e4, 3e4, -1.0], "loading.steps": [1, 2]}
    with pytest.raises(ConfigError) as err:
        plan(config, values)
    message = str(err.value)
    assert "\n" not in message
    # the grid's 7th run is (E=-1, steps=1): the message names the run, its values and the key
    assert message.startswith("run 7 (material.0.E=-1.0, loading.steps=1): material[0].E")
    assert len(plan(config, {"material.0.E": [1e4, 2e4, 3e4], "loading.steps": [1, 2]})) == 6


@serial_only
def test_bad_run_means_nothing_runs(config: Path, tmp_path: Path) -> None:
    out = tmp_path / "sweep"
    with pytest.raises(ConfigError, match=r"^run 2 \(loading\.steps=0\): loading\.steps"):
        sweep(config, {"loading.steps": [1, 0]}, out=out)
    assert not out.exists()


# --- sweeps: child processes, serial only ------------------------------------------------------------------------

def _table_equal(a, b) -> None:  # noqa: ANN001
    import pandas as pd

    keep = [c for c in a.columns if c not in TIME_COLUMNS]
    pd.testing.assert_frame_equal(a[keep].reset_index(drop=True), b[keep].reset_index(drop=True),
                                  check_exact=False, rtol=1e-12, atol=1e-12)


@serial_only
def test_grid_and_zip_sweeps_equal_separate_runs(config: Path, tmp_path: Path) -> None:
    import pandas as pd

    values = {"material.0.E": [1e4, 2e4], "loading.steps": [1, 2]}
    frame = sweep(config, values, jobs=2, out=tmp_path / "grid")
    assert frame.attrs["ran"] == 4 and frame.attrs["skipped"] == 0 and frame.attrs["failed"] == 0
    # one row per run and converged step: steps=1 gives one row, steps=2 two
    assert len(frame) == 2 * (1 + 2)
    assert set(frame["status"]) == {"completed"}
    assert list(frame.columns[:2]) == ["material.0.E", "loading.steps"]
    on_disk = pd.read_csv(tmp_path / "grid" / "sweep.csv")
    assert len(on_disk) == len(frame) and list(on_disk.columns) == list(frame.columns)
    for E in values["material.0.E"]:
        for steps in values["loading.steps"]:
            raw = apply(tiny(), {"material.0.E": E, "loading.steps": steps})
            rows = frame[(frame["material.0.E"] == E) & (frame["loading.steps"] == steps)]
            assert list(rows["run"].unique()) == [runs.config_hash(raw)]
            assert (tmp_path / "grid" / "runs" / runs.config_hash(raw) / "resolved.toml").is_file()
            assert list(rows["step"]) == list(range(1, steps + 1))
            summary = run_raw(raw, tmp_path / f"separate_{E}_{steps}")
            for (_, row), step in zip(rows.iterrows(), summary["steps"]):
                assert abs(row["load_factor"] - step["load_factor"]) < 1e-14
                np.testing.assert_allclose([row[f"probe.corner.{c}"] for c in "xyz"], step["probes"]["corner"],
                                           rtol=0, atol=1e-12)
                np.testing.assert_allclose([row[f"reaction.xmin.{c}"] for c in "xyz"], step["reactions"]["xmin"],
                                           rtol=1e-12, atol=1e-9)
                assert row["newton_iterations"] == step["newton_iterations"]
                assert abs(row["strain_energy"] - step["strain_energy"]) <= 1e-12 * abs(step["strain_energy"])
                assert abs(row["volume.all"] - step["volumes"]["all"]) < 1e-12
    # zip: (1e4, 2) is a run of the grid, (3e4, 1) a new one
    zipped = sweep(config, {"material.0.E": [1e4, 3e4], "loading.steps": [2, 1]}, mode="zip", out=tmp_path / "zip")
    assert zipped.attrs["ran"] == 2 and len(zipped) == 2 + 1
    first = zipped[zipped["material.0.E"] == 1e4]
    _table_equal(first, frame[(frame["material.0.E"] == 1e4) & (frame["loading.steps"] == 2)])
    last = zipped[zipped["material.0.E"] == 3e4].iloc[0]
    separate = run_raw(apply(tiny(), {"material.0.E": 3e4}), tmp_path / "separate_3e4")["steps"][-1]
    np.testing.assert_allclose([last[f"probe.corner.{c}"] for c in "xyz"], separate["probes"]["corner"],
                               rtol=0, atol=1e-12)


def _status(path: Path) -> str:
    try:
        return json.loads(path.read_text()).get("status", "")
    except (OSError, json.JSONDecodeError):
        return ""


@serial_only
def test_killed_sweep_restarts_only_the_remaining_runs(config: Path, tmp_path: Path) -> None:
    values = {"material.0.E": [1e4, 2e4, 3e4]}
    out = tmp_path / "killed"
    hashes = [run.hash for run in plan(config, values)]
    command = [sys.executable, "-m", "model", "sweep", str(config), "--set", "material.0.E=1e4,2e4,3e4",
               "--out", str(out)]
    process = subprocess.Popen(command, env=environment(), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                               start_new_session=True)
    first = out / "runs" / hashes[0] / "summary.json"
    deadline = time.monotonic() + 300
    while _status(first) != "completed":
        assert process.poll() is None, process.stderr.read().decode()
        assert time.monotonic() < deadline, "the first run did not complete in 300 s"
        time.sleep(0.02)
    os.kill(process.pid, signal.SIGKILL)  # the sweep only: its running child must die with it
    process.wait()
    deadline = time.monotonic() + 30
    while True:
        try:
            os.killpg(process.pid, 0)
        except ProcessLookupError:
            break  # no process of the sweep's group is left
        assert time.monotonic() < deadline, "a child run outlived the killed sweep"
        time.sleep(0.1)
    process.stderr.close()
    assert not (out / "sweep.csv").exists()
    completed = [h for h in hashes if _status(out / "runs" / h / "summary.json") == "completed"]
    assert hashes[0] in completed and len(completed) < len(hashes)
    stamps = {h: (out / "runs" / h / "summary.json").stat().st_mtime_ns for h in completed}
    resumed = sweep(config, values, out=out)
    assert resumed.attrs["ran"] == len(hashes) - len(completed)
    assert resumed.attrs["skipped"] == len(completed)
    assert {h: (out / "runs" / h / "summary.json").stat().st_mtime_ns for h in completed} == stamps
    whole = sweep(config, values, jobs=2, out=tmp_path / "whole")
    assert whole.attrs["ran"] == len(hashes)
    _table_equal(resumed, whole)
    again = sweep(config, values, out=out)
    assert again.attrs["ran"] == 0 and again.attrs["skipped"] == len(hashes)


@serial_only
def test_failed_runs_are_rows_and_the_sweep_exits_1(config: Path, tmp_path: Path) -> None:
    import pandas as pd

    out = tmp_path / "failing"
    # run 2: a traction of 100 E in one step with no cut-back; run 3: a region the mesh does not have
    command = [sys.executable, "-m", "model", "sweep", str(config), "--zip",
               "--set", "boundary.3.value=[2e3,0,0],[1e6,0,0],[2e3,0,0]", "--set", "material.0.region=all,all,nope",
               "--set", "loading.max_cutbacks=0,0,0", "--out", str(out)]
    done = subprocess.run(command, env=environment(), capture_output=True, text=True, timeout=600)
    assert done.returncode == 1, done.stderr
    # not a terminal: one line per finished run
    assert [line.split()[:2] for line in done.stdout.splitlines() if line.startswith("run ")] == \
        [["run", f"{i}/3"] for i in (1, 2, 3)]
    frame = pd.read_csv(out / "sweep.csv", keep_default_na=False)
    assert list(frame["status"]) == ["completed", "failed", "invalid"]
    failed = frame.iloc[1]
    assert failed["snes_reason"].startswith("DIVERGED")
    assert "max_cutbacks" in failed["reason"] and failed["step"] == ""
    invalid = frame.iloc[2]
    assert invalid["reason"].startswith("error: material[0].region") and "nope" in invalid["reason"]
    assert frame.iloc[0]["reason"] == "" and frame.iloc[0]["step"] == "1"  # read as text: the column has blanks


@serial_only
def test_cli_errors_are_one_line_exit_2(config: Path, tmp_path: Path) -> None:
    cases = [(["--set", "material.0.E=1e4,-1"], "error: run 2 (material.0.E=-1): material[0].E"),
             (["--zip", "--set", "material.0.E=1e4,2e4", "--set", "loading.steps=1,2,3"],
              "error: --zip needs the same number of values for every key: material.0.E has 2, loading.steps has 3"),
             (["--set", "material.0.E"], "error: --set 'material.0.E': write KEY=V1,V2"),
             (["--jobs", "0", "--set", "material.0.E=1e4"], "error: --jobs: 0 is not a positive whole number")]
    for args, start in cases:
        out = tmp_path / "bad"
        done = subprocess.run([sys.executable, "-m", "model", "sweep", str(config), *args, "--out", str(out)],
                              env=environment(), capture_output=True, text=True, timeout=300)
        assert done.returncode == 2, (args, done.stderr)
        assert done.stderr.count("\n") == 1 and done.stderr.startswith(start), (args, done.stderr)
        assert not out.exists()
