"""Serial and 2-rank runs of the same configuration give the same probes and reactions to 1e-10 relative.

The serial run is made in this process; the 2-rank run by ``mpirun -n 2 python -m model run``.
Cook's membrane (Taylor-Hood) is a non-homogeneous state, so the comparison means something.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
from conftest import ROOT, environment, example, run_raw, serial_only, write_toml


@serial_only
def test_two_ranks_match_serial(tmp_path: Path) -> None:
    raw = example("cook")
    raw["mesh"]["cells"] = 8
    raw["loading"] = {"steps": 2}
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    config = tmp_path / "cook.toml"
    write_toml(raw, config)
    serial = run_raw(raw, tmp_path / "serial")
    env = environment()
    cmd = ["mpirun", "-n", "2", "--oversubscribe", sys.executable, "-m", "model", "run", str(config),
           "--out", str(tmp_path / "parallel")]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=ROOT, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    parallel = json.loads((tmp_path / "parallel" / "summary.json").read_text())
    assert parallel["ranks"] == 2 and serial["ranks"] == 1
    assert parallel["dofs"] == serial["dofs"]
    for s, p in zip(serial["steps"], parallel["steps"], strict=True):
        assert s["load_factor"] == p["load_factor"]
        for name in s["probes"]:
            a, b = np.array(s["probes"][name]), np.array(p["probes"][name])
            assert np.max(np.abs(a - b)) <= 1e-10 * np.max(np.abs(a)), (name, a, b)
        for name in s["reactions"]:
            a, b = np.array(s["reactions"][name]), np.array(p["reactions"][name])
            assert np.max(np.abs(a - b)) <= 1e-10 * np.max(np.abs(a)), (name, a, b)
