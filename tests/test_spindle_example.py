"""A user's own gmsh script: examples/spindle.toml meshes examples/spindle.geo when it is read.

Checked: the script's physical groups become the regions and boundaries (their volume and areas against
the surface of revolution r(z) = r_end + (r_belly - r_end) sin(pi z / L)^2 of the script's parameters),
the isometric contraction bulges the belly and loads the clamped ends with equal and opposite forces of
the order of the active stress times the cross-section; `file` resolves against the configuration's
folder whatever the working directory; the .geo-only keys and a broken script give one-line errors.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import EXAMPLES, environment, example, run_raw, serial_only, write_toml
from mpi4py import MPI

from model.config import parse
from model.errors import ConfigError
from model.pipeline import build

COARSE = 0.008  # element size of the test runs [m]


def geo_constants() -> dict[str, float]:
    """The DefineConstant defaults of examples/spindle.geo (name = {value, ...})."""
    text = (EXAMPLES / "spindle.geo").read_text()
    return {name: float(value) for name, value in re.findall(r"(\w+)\s*=\s*\{\s*([-+.\deE]+)\s*,", text)}


def coarse(raw: dict[str, Any]) -> dict[str, Any]:
    raw["mesh"]["parameters"] = {"size": COARSE}
    raw["loading"]["steps"] = 2
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    return raw


@pytest.fixture(scope="module")
def summary(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    comm = MPI.COMM_WORLD
    out = Path(comm.bcast(str(tmp_path_factory.mktemp("spindle")) if comm.rank == 0 else None, root=0))
    return run_raw(coarse(example("spindle")), out)


def test_physical_groups_become_regions_and_boundaries(summary: dict[str, Any]) -> None:
    g = geo_constants()
    L, re_, rb = g["L"], g["r_end"], g["r_belly"]
    # int_0^L pi r(z)^2 dz with <sin^2> = 1/2, <sin^4> = 3/8 over a half period
    volume = np.pi * L * (re_**2 + re_ * (rb - re_) + 3.0 / 8.0 * (rb - re_) ** 2)
    assert set(summary["region_volumes"]) == {"all", "muscle"}
    assert set(summary["boundary_areas"]) == {"origin", "insertion", "side"}
    # the faceted mesh is inscribed in the surface of revolution: a few percent smaller
    assert 0.94 * volume < summary["region_volumes"]["muscle"] < volume
    for end in ("origin", "insertion"):
        assert 0.94 * np.pi * re_**2 < summary["boundary_areas"][end] < np.pi * re_**2


def test_isometric_contraction_pulls_on_both_ends(summary: dict[str, Any]) -> None:
    assert summary["status"] == "completed"
    last = summary["steps"][-1]
    origin, insertion = np.array(last["reactions"]["origin"]), np.array(last["reactions"]["insertion"])
    g = geo_constants()
    sigma_max = example("spindle")["material"][0]["sigma_max"]
    force = insertion[2]
    # the clamps hold the shortening muscle: equal and opposite axial forces, of the order of the active
    # stress times the cross-section (between the ends' and the belly's)
    assert np.linalg.norm(origin + insertion) < 1e-6 * force
    assert 0.5 * sigma_max * np.pi * g["r_end"] ** 2 < force < sigma_max * np.pi * g["r_belly"] ** 2
    assert origin[2] < 0
    bulge = np.array(last["probes"]["belly_surface"])
    assert bulge[1] > 1e-6  # radially outwards (the probe is at +y)
    assert summary["probe_points"]["belly_centre"] == [0.0, 0.0, g["L"] / 2]
    # a probe snapped onto the faceted mesh moved less than the faceting error of the belly's circle
    point = np.array(summary["probe_points"]["belly_surface"])
    assert np.linalg.norm(point - [0.0, g["r_belly"], g["L"] / 2]) < 0.05 * g["r_belly"]
    for name, distance in summary.get("snapped_probes", {}).items():
        assert name == "belly_surface" and 0 < distance < 0.05 * g["r_belly"]


def test_geo_parameters_are_checked() -> None:
    raw = coarse(example("spindle"))
    raw["mesh"]["parameters"] = {"sise": 0.01}
    with pytest.raises(ConfigError, match=r"^mesh\.parameters\.sise: spindle\.geo declares no parameter 'sise' "
                                          r"\(its DefineConstant parameters: L, r_belly, r_end, sections, size\)$"):
        parse(raw, EXAMPLES)
    raw["mesh"] = {"file": "spindle.geo", "regions": {"muscle": 1}}
    with pytest.raises(ConfigError, match=r"^mesh\.regions: a gmsh \.geo file names its physical groups itself"):
        parse(raw, EXAMPLES)
    raw["mesh"] = {"generator": "box", "parameters": {"size": 1.0}}
    with pytest.raises(ConfigError, match=r"^mesh\.parameters: "):
        parse(raw, EXAMPLES)


def test_broken_script_is_reported_and_leaves_gmsh_usable(shared_tmp: Path) -> None:
    comm = MPI.COMM_WORLD
    bad = shared_tmp / "broken.geo"
    if comm.rank == 0:
        bad.write_text('SetFactory("OpenCASCADE");\nBox(1) = {0, 0, 0, 1, 1, 1}\nPhysical Volume("v") = {1};\n')
    comm.barrier()
    raw = coarse(example("spindle"))
    raw["mesh"] = {"file": str(bad)}
    with pytest.raises(ConfigError) as caught:
        build(parse(raw, EXAMPLES), comm)
    message = str(caught.value)
    assert message.startswith(f"mesh.file: cannot mesh {bad}: gmsh: ") and "line 3" in message, message
    assert "\n" not in message
    # gmsh 4.8 keeps the rest of a script with a syntax error; meshed in a child process, the next is fine
    good = coarse(example("spindle"))
    domain = build(parse(good, EXAMPLES), comm).domain
    assert set(domain.boundaries) == {"origin", "insertion", "side"}


@serial_only
def test_file_resolves_against_the_configuration_folder(tmp_path: Path) -> None:
    """`python -m model run ../user/spindle.toml` from another working directory finds spindle.geo."""
    user, elsewhere = tmp_path / "user", tmp_path / "elsewhere"
    user.mkdir()
    elsewhere.mkdir()
    shutil.copy(EXAMPLES / "spindle.geo", user / "spindle.geo")
    raw = coarse(example("spindle"))
    raw["loading"]["steps"] = 1
    write_toml(raw, user / "spindle.toml")
    proc = subprocess.run([sys.executable, "-m", "model", "run", "../user/spindle.toml", "--out", "results"],
                          cwd=elsewhere, env=environment(), capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert (elsewhere / "results" / "summary.json").is_file()
    assert not (elsewhere / "spindle.geo").exists()
