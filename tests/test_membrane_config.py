"""Membrane runs from a configuration (model.config.membrane, model.experiments.membrane_run; docs/membranes.md).

- examples/membrane_balloon.toml (the StVK octant balloon, pressure ramp): every step's pressure against the
  closed form p(lambda) = h E / ((1 - nu) R) (lambda^2 - 1) / lambda at the measured stretch
  lambda = (V/V0)^(1/3) (0.4 % at size 0.2, as tests/test_membrane.py), the written surface (VTU: the nodes at
  radius ~ lambda; XDMF);
- the same balloon in a rigid cavity R_c = 1.1 stopped at half contact: the pressure just above the free
  balloon's p_m(R_c / R) (the contact starts there, the faceting spreads it over ~1 %);
- Hencky's clamped disc (override surface = "disc"): centre deflection w0 = 0.6534 a (p a / (E h))^(1/3);
- examples/membrane_discs.toml (two clamped discs on non-matching meshes inflated against each other,
  [[contact]]): action = reaction of the pair at every step, and the force between the forces of one disc
  against the rigid plane z = H/2 with penalty 2k (the symmetric equivalent, tests/test_membrane_contact.py) on
  the two meshes, within 0.5 % of the slave mesh's; the augmented Lagrangian leaves no penetration;
- bad input: one-line ConfigError naming the key, before any mesh or solve (the command line: exit code 2,
  nothing written).
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import jsonschema
import meshio
import numpy as np
import pytest
from conftest import EXAMPLES, MEMBRANE_EXAMPLES, ROOT, environment, serial_only, write_toml
from mpi4py import MPI

from model.config.membrane import load_membrane
from model.config.reference import MEMBRANE_SCHEMA_FILE, membrane_schema_text
from model.errors import ConfigError

BALLOON = EXAMPLES / "membrane_balloon.toml"
DISCS = EXAMPLES / "membrane_discs.toml"


def _run(shared_tmp: Path, overrides: dict | None = None, name: str = "out") -> dict:
    from model.experiments.membrane_run import run_membrane

    return run_membrane(load_membrane(BALLOON, overrides), shared_tmp / name, MPI.COMM_WORLD)


def stvk_balloon_pressure(young: float, nu: float, h: float, radius: float, stretch: np.ndarray) -> np.ndarray:
    """p(lambda) = h E / ((1 - nu) R) (lambda^2 - 1) / lambda: the thin StVK sphere (docs/membranes.md)."""
    return h * young / ((1.0 - nu) * radius) * (stretch**2 - 1.0) / stretch


def test_balloon_example_follows_the_closed_form(shared_tmp: Path) -> None:
    summary = _run(shared_tmp)
    assert summary["status"] == "completed"
    raw = tomllib.loads(BALLOON.read_text())["membrane"]
    V0 = summary["surface"]["rest_volume"]
    volume = np.array([s["volume"] for s in summary["steps"]])
    pressure = np.array([s["pressure"] for s in summary["steps"]])
    lam = (volume / V0) ** (1.0 / 3.0)
    np.testing.assert_allclose(pressure, 6e-3 * np.arange(1, 7) / 6, rtol=1e-12)
    error = pressure / stvk_balloon_pressure(raw["young"], raw["nu"], raw["thickness"], raw["radius"], lam) - 1.0
    assert lam[-1] > 1.22
    assert np.all(np.abs(error) < 5e-3), error  # measured 3.65e-3 ... 3.89e-3 (faceting of the 0.2 octant)
    np.testing.assert_allclose([s["stretch"] for s in summary["steps"]], lam, rtol=1e-12)
    np.testing.assert_allclose([s["balloon_pressure"] for s in summary["steps"]], pressure / (1 + error), rtol=1e-10)
    out = shared_tmp / "out"
    assert summary["files"][-1] == "summary.json"
    assert all((out / f).is_file() for f in summary["files"])
    if MPI.COMM_WORLD.rank == 0:
        import meshio

        assert json.loads((out / "summary.json").read_text())["steps"] == summary["steps"]
        mesh = meshio.read(out / "surface_0006.vtu")
        radius = np.linalg.norm(mesh.points + mesh.point_data["u"], axis=1)
        assert len(mesh.cells_dict["triangle"]) == summary["surface"]["triangles"]
        assert abs(radius.mean() / lam[-1] - 1.0) < 5e-3  # the nodes on the sphere of the volume's radius
        assert radius.max() - radius.min() < 0.02
        xdmf = (out / "surface.xdmf").read_text()
        assert "displacement" in xdmf and xdmf.count("<Time ") == 6  # one grid per pressure step


def test_balloon_in_a_cavity_stops_at_the_contact_fraction(shared_tmp: Path) -> None:
    """R_c = 1.1: free until p_m(1.1) = h E/((1 - nu) R)(1.1^2 - 1)/1.1 = 2.727e-3, then the fraction jumps to 1;
    the stop at half contact lies within 1.5 % above p_m (docs/membranes.md: 1.0084 p_m)."""
    cavity = {"obstacle": "sphere", "centre": [0.0, 0.0, 0.0], "radius": 1.1, "penalty": 1.0, "inside": True}
    summary = _run(shared_tmp, {"obstacle": [cavity], "inflation": {"contact_fraction": 0.5}})
    last = summary["steps"][-1]
    p_m = float(stvk_balloon_pressure(1.0, 0.3, 0.01, 1.0, np.array(1.1)))
    assert last["contact_fraction"] >= 0.5
    assert 1.0 <= last["pressure"] / p_m < 1.015
    assert all(s["contact_fraction"] < 0.5 for s in summary["steps"] if s["pressure"] < last["pressure"])
    # every equilibrium (growth and bisection) recorded once, the accepted one last
    pressures = [s["pressure"] for s in summary["steps"]]
    assert len(set(pressures)) == len(pressures) and last["pressure"] == min(
        s["pressure"] for s in summary["steps"] if s["contact_fraction"] >= 0.5)
    report = summary["contacts"][0]
    assert report["contact_fraction"] == pytest.approx(last["contact_fraction"], rel=1e-12)
    assert 0.0 < report["max_penetration"] < 2.0 * last["pressure"] / 1.0  # delta ~ lambda^2 (p - p_m) / k
    assert np.all(np.array(report["force"]) < 0.0)  # the cavity pushes the octant back towards the centre


def test_hencky_disc_from_the_config(shared_tmp: Path) -> None:
    """A clamped StVK disc (E = 1, nu = 0.3, h = 0.01, a = 1) at p a / (E h) = 1e-4: w0 within 1 % of Hencky."""
    summary = _run(shared_tmp, {"membrane.surface": "disc", "membrane.fixed": {"rim": [0, 1, 2]},
                                "membrane.bump": 0.03, "inflation": {"pressures": [1e-6]}, "output.xdmf": False})
    step = summary["steps"][-1]
    assert step["hencky_deflection"] == pytest.approx(0.6534 * 1e-4 ** (1 / 3), rel=1e-3)
    assert abs(step["centre_deflection"] / step["hencky_deflection"] - 1.0) < 0.01


@pytest.mark.parametrize(("overrides", "message"), [
    ({"membrane.thicknes": 0.1},
     r"^membrane\.thicknes: unknown key, did you mean 'thickness'\? \(allowed: .*thickness"),
    ({"membrane.law": "mooney"}, r"^membrane\.law: 'mooney' is not one of stvk, neo_hookean$"),
    ({"membrane.thickness": -0.01}, r"^membrane\.thickness: -0\.01 is out of range, must be > 0$"),
    ({"membrane.mu": 2.0}, r"^membrane\.mu: only applies to law = 'neo_hookean', not 'stvk'$"),
    ({"membrane.fixed": {"rim": [0]}}, r"^membrane\.fixed\.rim: sphere_octant has no boundary 'rim'"),
    ({"inflation": {"contact_fraction": 0.5}}, r"^inflation\.contact_fraction: needs an \[\[obstacle\]\]"),
    ({"obstacle": [{"obstacle": "sphere", "radius": 1.1, "penalty": 1.0}]}, r"^obstacle\[0\]\.centre: missing"),
    ({"inflation.pressures": [1e-3]}, r"^inflation\.pressures: not with pressure"),
])
def test_bad_input_names_the_key(overrides: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message) as err:
        load_membrane(BALLOON, overrides)
    assert "\n" not in str(err.value)


@serial_only
def test_command_line_refuses_before_any_solve(tmp_path: Path) -> None:
    out = tmp_path / "out"
    result = subprocess.run([sys.executable, "-m", "model", "run", str(BALLOON), "--out", str(out), "--set",
                             "membrane.thickness=-0.01"], cwd=ROOT, env=environment(), capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 2
    assert result.stderr.strip() == "error: membrane.thickness: -0.01 is out of range, must be > 0"
    assert not out.exists()


def test_schema_file_and_examples() -> None:
    """docs/membrane.schema.json is the generated one; the membrane examples validate against it."""
    assert (ROOT / MEMBRANE_SCHEMA_FILE).read_text() == membrane_schema_text(), \
        f"{MEMBRANE_SCHEMA_FILE} is stale: run python -m model schema --membrane-out {MEMBRANE_SCHEMA_FILE}"
    validator = jsonschema.Draft202012Validator(json.loads((ROOT / MEMBRANE_SCHEMA_FILE).read_text()))
    assert BALLOON in MEMBRANE_EXAMPLES
    for path in MEMBRANE_EXAMPLES:
        assert list(validator.iter_errors(tomllib.loads(path.read_text()))) == [], path
        load_membrane(path)
    bad = tomllib.loads(BALLOON.read_text())
    bad["membrane"]["thicknes"] = 0.1
    assert list(validator.iter_errors(bad))


def _run_file(path: Path, out: Path, overrides: dict | None = None) -> dict:
    from model.experiments.membrane_run import run_membrane

    return run_membrane(load_membrane(path, overrides), out, MPI.COMM_WORLD)


def test_discs_example_action_reaction_and_the_rigid_plane(shared_tmp: Path) -> None:
    """Two discs (lower 0.2, upper 0.15, H = 0.8, k = 10) pressed together: per step the master's force is minus
    the slave's (to 1e-12), the contact starts at the second pressure; at the last the force lies between the
    rigid-plane forces (one disc against z = H/2 with penalty 2k, from a [membrane] disc config with an
    [[obstacle]] plane) of the two meshes, within 0.5 % of the slave mesh's (measured -3.8679e-3 against
    -3.8534e-3, +0.38 %), and the penetration is below 2 p / k. The augmented Lagrangian leaves no penetration."""
    summary = _run_file(DISCS, shared_tmp / "discs")
    assert summary["status"] == "completed"
    steps = summary["steps"]
    assert [s["pressure"] for s in steps] == pytest.approx([2e-3, 4e-3, 6e-3], rel=1e-12)
    for step in steps:
        (pair,) = step["pairs"]
        assert np.allclose(pair["master_force"], -np.asarray(pair["force"]), rtol=0, atol=1e-12)
        # the whole membrane's fraction counts both discs' area (equal areas): half the slave's
        assert step["contact_fraction"] == pytest.approx(0.5 * pair["contact_fraction"], rel=0.05, abs=1e-12)
    assert steps[0]["pairs"][0]["contact_fraction"] == 0.0 < steps[1]["pairs"][0]["contact_fraction"]
    last = steps[-1]["pairs"][0]
    assert summary["contacts"][0]["force"] == pytest.approx(last["force"], rel=1e-12)
    assert 0.0 < last["max_penetration"] < 2 * 6e-3 / 10.0
    planes = {}
    for size in (0.2, 0.15):
        plane = {"obstacle": "plane", "point": [0.0, 0.0, 0.4], "normal": [0.0, 0.0, -1.0], "penalty": 20.0}
        overrides = {"membrane": {"surface": "disc", "radius": 1.0, "size": size, "law": "stvk", "young": 1.0,
                                  "nu": 0.3, "thickness": 0.01, "bump": 0.3}, "contact": [], "obstacle": [plane]}
        planes[size] = _run_file(DISCS, shared_tmp / f"plane_{size}", overrides)["contacts"][0]
    coarse, fine = planes[0.2]["force"][2], planes[0.15]["force"][2]
    assert coarse > last["force"][2] > fine  # all negative: between the two meshes' rigid-plane forces
    assert abs(last["force"][2] / coarse - 1.0) < 5e-3
    assert abs(last["contact_fraction"] / planes[0.2]["contact_fraction"] - 1.0) < 0.12  # measured -10.6 %
    # augmented = true (Uzawa to 1e-9), straight to the last pressure: no penetration left, action = reaction, the
    # force between the rigid-plane forces too, 0.16 % from the penalty's (measured -3.8741e-3)
    pair = {"surface": "lower", "master": "upper", "penalty": 10.0, "augmented": True, "tolerance": 1e-9}
    augmented = _run_file(DISCS, shared_tmp / "discs_al", {"contact": [pair], "inflation.pressures": [6e-3],
                                                          "output.xdmf": False})
    assert augmented["pairs"] == [{"name": "lower-upper", "surface": "lower", "master": "upper",
                                   "penalty": 10.0, "augmented": True, "two_pass": False}]
    al = augmented["steps"][-1]["pairs"][0]
    assert al["max_penetration"] <= 1e-9
    assert np.allclose(al["master_force"], -np.asarray(al["force"]), rtol=0, atol=1e-12)
    assert coarse > al["force"][2] > fine
    assert abs(al["force"][2] / last["force"][2] - 1.0) < 5e-3


_PAIR = {"surface": "lower", "master": "upper", "penalty": 10.0}


def test_discs_two_pass_from_the_config(shared_tmp: Path) -> None:
    """two_pass = true: both passes recorded per step (lower-upper, then upper-lower), neither membrane's nodes
    penetrate the other's triangles by more than 2 p / k, each membrane's force (its pass as slave plus the other
    pass's reaction) balances the other's (tests/test_membrane_contact.py: the rigid-plane comparison)."""
    summary = _run_file(DISCS, shared_tmp / "discs_two_pass", {"contact": [{**_PAIR, "two_pass": True}],
                                                               "output.xdmf": False, "output.vtu": False})
    assert summary["status"] == "completed" and summary["pairs"][0]["two_pass"] is True
    first, second = summary["steps"][-1]["pairs"]
    assert (first["pair"], second["pair"]) == ("lower-upper", "upper-lower")
    assert [c["pair"] for c in summary["contacts"]] == ["lower-upper", "upper-lower"]
    for report in (first, second):
        assert 0.0 < report["max_penetration"] < 2 * 6e-3 / 10.0
    lower = np.asarray(first["force"]) + np.asarray(second["master_force"])
    upper = np.asarray(second["force"]) + np.asarray(first["master_force"])
    assert np.allclose(lower, -upper, rtol=0, atol=1e-12) and lower[2] < 0


@pytest.mark.parametrize(("overrides", "message"), [
    ({"contact": [{**_PAIR, "master": "lower"}]},
     r"^contact\[0\]\.master: the same region as surface \('lower'\): a contact pairs two membranes$"),
    ({"contact": [{**_PAIR, "surface": "lowr"}]},
     r"^contact\[0\]\.surface: facing_discs has no region 'lowr' \(regions: lower, upper\)$"),
    ({"contact": [{**_PAIR, "master": "uper"}]}, r"^contact\[0\]\.master: facing_discs has no region 'uper'"),
    ({"contact": [{**_PAIR, "penalty": -1.0}]}, r"^contact\[0\]\.penalty: -1\.0 is out of range, must be > 0$"),
    ({"contact": [{**_PAIR, "penalty": "stiff"}]}, r"^contact\[0\]\.penalty: "),
    ({"contact": [{**_PAIR, "tolerance": 1e-6}]}, r"^contact\[0\]\.tolerance: only applies with augmented"),
    ({"contact": [{**_PAIR, "slave": "lower"}]}, r"^contact\[0\]\.slave: unknown key"),
    ({"contact": [{**_PAIR, "two_pass": "yes"}]}, r"^contact\[0\]\.two_pass: "),
    ({"contact": [{**_PAIR, "two_pass": True, "augmented": True}]},
     r"^contact\[0\]\.two_pass: not with augmented = true"),
    ({"membrane.gap": None}, r"^membrane\.gap: missing"),
    ({"membrane.upper_size": 0.0}, r"^membrane\.upper_size: 0\.0 is out of range, must be > 0$"),
])
def test_bad_contact_names_the_key(overrides: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message) as err:
        load_membrane(DISCS, overrides)
    assert "\n" not in str(err.value)


def test_contact_needs_two_membranes() -> None:
    """[[contact]] on a surface of one membrane (the balloon), gap on the octant."""
    with pytest.raises(ConfigError, match=r"^contact\[0\]\.surface: sphere_octant has no region 'lower' \(no "
                                          r"regions: membrane-membrane contact needs surface = 'facing_discs' or "
                                          r"a \.msh file's named physical surfaces\)$"):
        load_membrane(BALLOON, {"contact": [_PAIR]})
    with pytest.raises(ConfigError, match=r"^membrane\.gap: only applies to surface = 'facing_discs' or "
                                          r"'closed_can', not "):
        load_membrane(BALLOON, {"membrane.gap": 0.5})


def test_a_failed_solve_is_recorded(shared_tmp: Path) -> None:
    """A neo-Hookean balloon cannot hold p above its limit point, max p = (2 mu h/R)(7^(-1/6) - 7^(-7/6)) = 1.21e-2:
    SolveFailed naming the pressure, summary.json written with status "failed"."""
    from model.errors import SolveFailed

    overrides = {"membrane": {"surface": "sphere_octant", "law": "neo_hookean", "mu": 1.0, "thickness": 0.01},
                 "inflation": {"pressures": [2e-2], "cutbacks": 0}, "output": {"xdmf": False, "vtu": False}}
    with pytest.raises(SolveFailed, match="pressure 0.02"):
        _run(shared_tmp, overrides, "failed")
    summary = json.loads((shared_tmp / "failed" / "summary.json").read_text())
    assert summary["status"] == "failed" and summary["steps"] == [] and "pressure 0.02" in summary["error"]


def test_inflation_to_a_target_volume(shared_tmp: Path) -> None:
    """target_volume = 0.8 (lambda = (0.8/V0)^(1/3) = 1.155): the last step at the volume to 1e-6, its pressure on
    the closed form to 5e-3, reached by growing p by the default dp = 0.05 w'(1.1) / R."""
    summary = _run(shared_tmp, {"inflation": {"target_volume": 0.8}}, "volume")
    last, V0 = summary["steps"][-1], summary["surface"]["rest_volume"]
    assert last["volume"] == pytest.approx(0.8, rel=1e-6)
    lam = (0.8 / V0) ** (1.0 / 3.0)
    assert abs(last["pressure"] / stvk_balloon_pressure(1.0, 0.3, 0.01, 1.0, np.array(lam)) - 1.0) < 5e-3
    dp = 0.05 * 0.01 / 0.7 * (1.1**2 - 1.0) * 1.1
    assert summary["steps"][0]["pressure"] == pytest.approx(dp, rel=1e-12)
    assert all(s["volume"] < 0.8 for s in summary["steps"][:-1] if s["pressure"] < last["pressure"])


def test_a_membrane_file_is_not_a_solid_run() -> None:
    """model.config.load (sweep, converge, model.load_config) names the [membrane] table instead of listing it as
    an unknown section."""
    from model.config import load

    with pytest.raises(ConfigError, match=r"^membrane: this file is a membrane run .*python -m model run FILE"):
        load(BALLOON)


class _StopAfter:
    """A stop flag (model.pipeline.StopFlag's check) that reports SIGTERM from its ``n``-th check on."""

    def __init__(self, n: int) -> None:
        self.n, self.calls = n, 0

    def check(self, comm: MPI.Comm) -> int:
        self.calls += 1
        return int(signal.SIGTERM) if self.calls >= self.n else 0


def test_an_interrupted_run_keeps_its_steps(shared_tmp: Path) -> None:
    """Stopped after its second pressure step (the check the SIGTERM handler answers): Interrupted with the signal,
    summary.json "interrupted" with those two steps, the XDMF series readable with both (meshio), the VTU files
    of both; the steps equal the uninterrupted run's first two."""
    from model.experiments.membrane_run import run_membrane
    from model.pipeline import Interrupted

    full = _run(shared_tmp, name="whole")
    out = shared_tmp / "interrupted"
    with pytest.raises(Interrupted, match="interrupted by SIGTERM after pressure step 2") as caught:
        run_membrane(load_membrane(BALLOON), out, MPI.COMM_WORLD, stop=_StopAfter(2))
    assert caught.value.signum == signal.SIGTERM
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and len(summary["steps"]) == 2
    for mine, whole in zip(summary["steps"], full["steps"][:2], strict=True):
        assert mine["volume"] == pytest.approx(whole["volume"], rel=1e-12)
    if MPI.COMM_WORLD.rank == 0:
        with meshio.xdmf.TimeSeriesReader(out / "surface.xdmf") as reader:
            reader.read_points_cells()
            assert reader.num_steps == 2
            times = [reader.read_data(k)[0] for k in range(reader.num_steps)]
        assert times == pytest.approx([s["pressure"] for s in summary["steps"]], rel=1e-12)
        assert sorted(p.name for p in out.glob("surface_*.vtu")) == ["surface_0001.vtu", "surface_0002.vtu"]


def test_an_interrupted_growth_keeps_its_steps(shared_tmp: Path) -> None:
    """A contact-fraction growth (the balloon into the cavity) stopped after its third equilibrium: Interrupted,
    summary.json "interrupted" with those three steps (the same as the uninterrupted run's first three), the
    surface of the third written."""
    from model.experiments.membrane_run import run_membrane
    from model.pipeline import Interrupted

    cavity = {"obstacle": "sphere", "centre": [0.0, 0.0, 0.0], "radius": 1.1, "penalty": 1.0, "inside": True}
    overrides = {"obstacle": [cavity], "inflation": {"contact_fraction": 0.5}, "output.vtu": False}
    full = _run(shared_tmp, overrides, name="growth")
    out = shared_tmp / "growth_interrupted"
    with pytest.raises(Interrupted, match="interrupted by SIGTERM after pressure step 3") as caught:
        run_membrane(load_membrane(BALLOON, overrides), out, MPI.COMM_WORLD, stop=_StopAfter(3))
    assert caught.value.signum == signal.SIGTERM
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and len(summary["steps"]) == 3
    assert len(full["steps"]) > 3
    for mine, whole in zip(summary["steps"], full["steps"][:3], strict=True):
        assert mine["pressure"] == pytest.approx(whole["pressure"], rel=1e-12)
        assert mine["volume"] == pytest.approx(whole["volume"], rel=1e-12)
    if MPI.COMM_WORLD.rank == 0:
        with meshio.xdmf.TimeSeriesReader(out / "surface.xdmf") as reader:
            reader.read_points_cells()
            assert reader.num_steps == 1
            assert reader.read_data(0)[0] == pytest.approx(summary["steps"][-1]["pressure"], rel=1e-12)


@serial_only
def test_sigterm_ends_a_membrane_run_cleanly(tmp_path: Path) -> None:
    """``python -m model run`` of a membrane file, SIGTERM once summary.json shows two steps: exit 143, status
    "interrupted", every finished step in summary.json and in the XDMF series."""
    config = tmp_path / "long.toml"
    raw = tomllib.loads(BALLOON.read_text())
    raw["inflation"] = {"pressure": 6.0e-3, "steps": 3000}  # long enough to be stopped (about 0.03 s a step)
    raw["output"] = {"xdmf": True, "vtu": False}
    write_toml(raw, config)
    for attempt in range(2):
        out = tmp_path / f"out{attempt}"
        logs = [open(tmp_path / f"{name}{attempt}.txt", "w+") for name in ("stdout", "stderr")]
        env = {**environment(), "PYTHONUNBUFFERED": "1"}
        process = subprocess.Popen([sys.executable, "-m", "model", "run", str(config), "--out", str(out)],
                                   env=env, text=True, stdout=logs[0], stderr=logs[1])
        deadline = time.monotonic() + 300
        while not (out / "summary.json").exists() or len(json.loads((out / "summary.json").read_text())["steps"]) < 2:
            if process.poll() is not None:
                break
            assert time.monotonic() < deadline
            time.sleep(0.02)
        if process.poll() is None:
            break
        for log in logs:
            log.close()
        stdout, stderr = ((tmp_path / f"{name}{attempt}.txt").read_text() for name in ("stdout", "stderr"))
        # Twice in many runs of the whole suite under load the child ended at once with exit code 1 and printed
        # nothing (not even the first step's line, with unbuffered output) nor wrote summary.json: a start-up
        # failure of the process (not understood), retried once; any other early end fails here.
        started = stdout.strip() or stderr.strip() or out.exists()
        assert attempt == 0 and not started, (f"the run ended before the signal (exit code {process.returncode}): "
                                              f"stdout {stdout[-1000:]!r}, stderr {stderr[-2000:]!r}")
    process.send_signal(signal.SIGTERM)
    process.wait(timeout=300)
    stderr = (tmp_path / f"stderr{attempt}.txt").read_text()
    for log in logs:
        log.close()
    assert process.returncode == 128 + signal.SIGTERM, stderr[-2000:]
    assert "interrupted by SIGTERM" in stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and 2 <= len(summary["steps"]) < 3000
    with meshio.xdmf.TimeSeriesReader(out / "surface.xdmf") as reader:
        reader.read_points_cells()
        assert reader.num_steps == len(summary["steps"])
