"""From a patch to a muscle from a configuration: examples/membrane_muscle.toml's [muscle] phase (docs/membranes.md,
"The inflation workflow"; the thesis' ch. 3.3.3).

- the clamped neo-Hookean disc is inflated to V = 0.5 (to 1e-6 V), closed with its flat base and filled with
  tetrahedra: the tetrahedra of the written muscle.msh (read back with its physical groups) enclose the target
  volume (the surface mesh is kept, so to round-off: measured 8.0e-10 = 1.6e-9 V from the target, the secant
  stop's own tolerance, and 6.7e-16 V from the membrane's enclosed volume);
- fibres.npy holds unit vectors; a cell with a face on the origin (phi = 0 on it, phi >= 0 inside: the maximum
  principle) has a0 = +e_z (the P1 phi is constant on the face: grad phi is its normal), one on the insertion
  -e_z; in the middle of the belly (|x| < 0.2) the fibres run from the origin's end to the insertion's, a0 . e_x
  > 0.9 (measured >= 0.98, mean 0.997); the main model's reader puts fibres.npy on the cells of muscle.msh as
  the Laplace field solved afresh on the read mesh (to 1e-10: the file's cell order is the mesh file's);
- muscle.toml runs as it is through model.pipeline.run: every step converges, the two clamped ends' reactions
  balance (no other load; to 1e-8 of their size), the origin is pulled towards the insertion (its reaction
  points to -x) and the y-reaction is small (the mirror y -> -y: measured 0.9 % of the x-reaction on the
  unsymmetric mesh);
- bad input: one-line ConfigError naming the key, before any mesh or solve.
"""

from __future__ import annotations

import gc
import tomllib
from pathlib import Path

import numpy as np
import pytest
from conftest import EXAMPLES, ROOT, environment, serial_only
from mpi4py import MPI

from model.config.membrane import load_membrane
from model.errors import ConfigError

EXAMPLE = EXAMPLES / "membrane_muscle.toml"
COMM = MPI.COMM_WORLD


def _cells_on(mesh: object, name: str) -> np.ndarray:
    """The tetrahedra with a face in the boundary ``name`` of a MeshData."""
    faces = {tuple(f) for f in np.sort(mesh.boundary_facets(name), axis=1)}
    cells = np.sort(mesh.cells, axis=1)
    return np.array([any(tuple(c[list(k)]) in faces for k in ((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)))
                     for c in cells])


def test_patch_to_muscle_and_its_contraction(shared_tmp: Path) -> None:
    from dolfinx import fem

    from meshes.data import read_msh
    from model import pipeline
    from model.config.document import load
    from model.experiments.membrane_run import run_membrane
    from model.fields.fibres import FibreField

    out = shared_tmp / "patch"
    target = tomllib.loads(EXAMPLE.read_text())["inflation"]["target_volume"]
    summary = run_membrane(load_membrane(EXAMPLE), out, COMM)
    assert summary["status"] == "completed"
    assert abs(summary["steps"][-1]["volume"] - target) <= 1e-6 * target
    muscle = summary["muscle"]
    assert muscle["volume"] == pytest.approx(muscle["enclosed_volume"], rel=1e-12)
    assert abs(muscle["volume"] - target) <= 1e-6 * target
    for name in ("mesh", "fibres", "config", "vtu"):
        assert muscle[name] in summary["files"] and (out / muscle[name]).is_file()
    gc.collect()  # on every rank, not inside rank 0's reading below (a PETSc destroy there would be rank 0's alone)
    if COMM.rank == 0:
        mesh = read_msh(out / "muscle.msh")
        assert mesh.region_names == {"muscle": 1}
        assert set(mesh.boundary_names) == {"patch", "base", "origin", "insertion"}
        assert mesh.volume() == pytest.approx(muscle["volume"], rel=1e-12)
        assert mesh.num_cells == muscle["tetrahedra"]
        a0 = np.load(out / "fibres.npy")
        assert a0.shape == (mesh.num_cells, 3)
        assert np.allclose(np.linalg.norm(a0, axis=1), 1.0, rtol=0, atol=1e-12)
        for name, direction in (("origin", [0, 0, 1]), ("insertion", [0, 0, -1])):
            ends = _cells_on(mesh, name)
            assert ends.sum() >= 10
            assert np.allclose(a0[ends], direction, rtol=0, atol=1e-10), name
        centroid_x = mesh.points[mesh.cells].mean(axis=1)[:, 0]
        belly = np.abs(centroid_x) < 0.2
        assert belly.sum() >= 20 and a0[belly, 0].min() > 0.9
    # the main model reads the mesh and the fibres: the field of fibres.npy is the Laplace field of the read mesh
    config = load(out / "muscle.toml")
    setup = pipeline.build(config, COMM)
    fresh = FibreField(setup.domain).laplace("origin", "insertion").function
    owned = setup.domain.mesh.topology.index_map(3).size_local * 3
    gap = np.abs(setup.fibres.x.array[:owned] - fresh.x.array[:owned]).max(initial=0.0)
    assert COMM.allreduce(gap, op=MPI.MAX) < 1e-10
    assert isinstance(setup.fibres, fem.Function)
    # ... and runs it as written
    result = pipeline.run(config, out / "contraction", COMM)
    assert result["status"] == "completed"
    steps = result["steps"]
    assert len(steps) == tomllib.loads(EXAMPLE.read_text())["muscle"]["steps"]
    assert all(s["converged"] for s in steps)
    origin, insertion = (np.asarray(steps[-1]["reactions"][k]) for k in ("origin", "insertion"))
    assert np.linalg.norm(origin + insertion) < 1e-8 * np.linalg.norm(origin)
    assert origin[0] < 0.0 < insertion[0]  # the contracting fibres pull the two ends towards each other
    assert abs(origin[1]) < 0.05 * abs(origin[0])


DELETE = object()


@pytest.mark.parametrize(("where", "value", "message"), [
    ("muscle.end", 1.0, r"^muscle\.end: 1\.0 is out of range, must be in \(0\.0, 1\.0\)$"),
    ("muscle.fixed", ["orign"],
     r"^muscle\.fixed\[0\]: 'orign' is not one of patch, base, origin, insertion \(did you mean 'origin'\?\)$"),
    ("muscle.sigma_max", -1.0, r"^muscle\.sigma_max: -1\.0 is out of range, must be > 0$"),
    ("muscle.young", DELETE, r"^muscle\.young: missing"),
    ("muscle.tet_siz", 0.1, r"^muscle\.tet_siz: unknown key"),
    ("membrane.fixed", {"rim": [2]}, r"^muscle: needs the rim clamped"),
])
def test_bad_muscle_input_names_the_key(where: str, value: object, message: str) -> None:
    from model.config.membrane import parse_membrane

    raw = tomllib.loads(EXAMPLE.read_text())
    section, name = where.split(".")
    if value is DELETE:
        del raw[section][name]
    else:
        raw[section][name] = value
    with pytest.raises(ConfigError, match=message) as err:
        parse_membrane(raw, EXAMPLES)
    assert "\n" not in str(err.value)


def test_muscle_needs_a_disc() -> None:
    with pytest.raises(ConfigError, match=r"^muscle: needs surface = 'disc' .*not 'sphere_octant'$"):
        load_membrane(EXAMPLE, {"membrane.surface": "sphere_octant", "membrane.fixed": {"x0": [0]}})


def test_ends_without_triangles_refused_before_any_solve(shared_tmp: Path) -> None:
    """end = 0.95 at size 0.2: no base triangle's centroid beyond |x| = 0.95: refused before the inflation (nothing
    but the emptied output folder)."""
    from model.experiments.membrane_run import run_membrane

    out = shared_tmp / "ends"
    with pytest.raises(ConfigError, match=r"^muscle\.end: no base triangle .* beyond x = \+-0\.95 radius"):
        run_membrane(load_membrane(EXAMPLE, {"muscle.end": 0.95}), out, COMM)
    COMM.barrier()
    assert not (out / "summary.json").exists()


BONE = EXAMPLES / "membrane_muscle_bone.toml"


def test_extruded_patch_against_a_bone_to_muscle(shared_tmp: Path) -> None:
    """examples/membrane_muscle_bone.toml, the thesis' two phases: the extrusion inflated to first_volume (to 1e-6,
    no contact), smoothed down to rest_volume (the last smoothing step crosses it; the membrane built on that rest
    shape encloses the same volume), inflated against the capsule until 5 % of the area touches it (the bone pushes
    down, the penetration below 0.02); the muscle's tetrahedra enclose the final volume to round-off and stay out
    of the bone up to the penetration (measured: 19 + 25 pressure steps, smoothed V = 0.3911 in 22 iterations,
    fraction 0.0528, penetration 2.9e-3, V = 0.9174, 648 tetrahedra)."""
    from meshes.data import read_msh
    from model.experiments.membrane_run import run_membrane

    raw = tomllib.loads(BONE.read_text())
    out = shared_tmp / "bone"
    summary = run_membrane(load_membrane(BONE), out, COMM)
    assert summary["status"] == "completed"
    extrusion = summary["extrusion"]
    first = extrusion["first_steps"]
    assert first[-1]["volume"] == pytest.approx(raw["extrusion"]["first_volume"], rel=1e-6)
    assert extrusion["smoothed_volume"] <= raw["extrusion"]["rest_volume"]
    assert summary["surface"]["rest_volume"] == pytest.approx(extrusion["smoothed_volume"], rel=1e-10)
    last, (bone,) = summary["steps"][-1], summary["contacts"]
    assert last["contact_fraction"] >= raw["inflation"]["contact_fraction"] and last["volume"] < 2.0
    assert bone["force"][2] < 0.0 and 0.0 < bone["max_penetration"] < 0.02
    muscle = summary["muscle"]
    assert muscle["volume"] == pytest.approx(last["volume"], rel=1e-12)
    if COMM.rank == 0:
        mesh = read_msh(out / "muscle.msh")
        capsule = raw["obstacle"][0]
        y, z = mesh.points[:, 1] - capsule["a"][1], mesh.points[:, 2] - capsule["a"][2]
        assert np.hypot(y, z).min() >= capsule["radius"] - bone["max_penetration"] - 1e-12


@pytest.mark.parametrize(("where", "value", "message"), [
    ("extrusion.rest_volume", 0.9, r"^extrusion\.rest_volume: 0\.9 must be below first_volume \(0\.8\)"),
    ("extrusion.offset", 0.0, r"^extrusion\.offset: 0\.0 is out of range, must be > 0$"),
    ("membrane.bump", 0.1, r"^membrane\.bump: not with \[extrusion\]"),
])
def test_bad_extrusion_input_names_the_key(where: str, value: object, message: str) -> None:
    from model.config.membrane import parse_membrane

    raw = tomllib.loads(BONE.read_text())
    section, name = where.split(".")
    raw[section][name] = value
    with pytest.raises(ConfigError, match=message) as err:
        parse_membrane(raw, EXAMPLES)
    assert "\n" not in str(err.value)


@serial_only
def test_command_line_patch_then_muscle(tmp_path: Path) -> None:
    """The two commands of the example's header: the membrane run names the written muscle.toml, which the command
    line then runs as it is (its [output] dir: the membrane run's folder's contraction/, an absolute path: the
    membrane run is given a relative --out, the muscle run starts in another working directory)."""
    import json
    import subprocess
    import sys

    out = tmp_path / "patch"
    first = subprocess.run([sys.executable, "-m", "model", "run", str(EXAMPLE), "--out", "patch"], cwd=tmp_path,
                           env=environment(), capture_output=True, text=True, timeout=300)
    assert first.returncode == 0, first.stderr[-2000:]
    assert f"run it with: python -m model run {Path('patch') / 'muscle.toml'}" in first.stdout, first.stdout
    second = subprocess.run([sys.executable, "-m", "model", "run", str(out / "muscle.toml")], cwd=ROOT,
                            env=environment(), capture_output=True, text=True, timeout=300)
    assert second.returncode == 0, second.stderr[-2000:]
    summary = json.loads((out / "contraction" / "summary.json").read_text())
    assert summary["status"] == "completed" and all(s["converged"] for s in summary["steps"])
