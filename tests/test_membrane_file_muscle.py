"""[extrusion] and [muscle] on a user's patch from a file (surface = "file", docs/membranes.md "A patch from a file
into a muscle"; the thesis' ch. 3.3.3: the patch is drawn on a bone, generally not planar).

- the built-in disc written to OBJ and run as a file through examples/membrane_muscle_bone.toml ([extrusion],
  contact with the capsule, [muscle]; muscle.axis = [1, 0, 0]: a round patch has no principal axis) gives the disc
  run's numbers: the same points in the same order, so the same equilibria (measured: bit for bit); written to STL
  (a triangle soup: its points merged, in another order) through examples/membrane_muscle.toml: the pressures,
  volumes, tetrahedra and fibres to round-off;
- a patch on a bone shaft (a cylinder of radius 0.5 along x, the patch |x| <= 1 over 2 rad of it: not planar,
  its rim not in a plane) inflated to a target volume: the volume is the one between the patch and its rest shape
  (the closed surface's, the divergence theorem: the same with the file moved away from the origin, measured to
  1e-14 relative), the tetrahedra of muscle.msh enclose it (to round-off: measured 3e-15), every fibre is a unit
  vector, the fibres at the ends are the end faces' normals (mostly into the muscle at the origin and out of it
  at the insertion: the discrete maximum principle fails in a few flat tetrahedra along the rim), in the belly
  they run along the principal axis x (measured: mean a0 . e_x 0.9997, min 0.996), the muscle lies outside the
  faceted bone, and the written muscle.toml runs (2 steps, the ends' reactions balance, the origin pulled towards
  the insertion);
- laplace_fibres where phi is constant on a cell (its four vertices on one end) against numpy;
- the refusals: two boundary loops, two pieces, a closed surface, a handle, the rim not clamped (in the config,
  part of it, an edge inside), a round patch without an axis, a zero axis: one-line ConfigErrors naming the key;
- examples/membrane_file_muscle.toml (examples/data/shaft_patch.obj, made by ``shaft_patch``) runs.
"""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path

import meshio
import numpy as np
import pytest
from conftest import EXAMPLES
from mpi4py import MPI

from meshes.membrane import disc_surface, sphere_surface
from model.config.membrane import load_membrane, parse_membrane
from model.errors import ConfigError

COMM = MPI.COMM_WORLD
BONE_RADIUS = 0.5
OUTPUT = {"xdmf": False, "vtu": False}
LAW = {"law": "neo_hookean", "mu": 1.0, "thickness": 0.01}
MUSCLE = {"young": 9.0e6, "sigma_max": 3.0e5, "steps": 2, "tet_size": 0.15}


def shaft_patch(length: float = 2.0, radius: float = BONE_RADIUS, angle: float = 1.0, nx: int = 16, nt: int = 8,
                jitter: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    """The patch |x| <= length/2, |theta| <= angle on the cylinder y = r sin theta, z = r cos theta (a bone shaft
    along x): an nx x nt grid of (x, theta), each cell halved along alternating diagonals, oriented outward
    (right-handed: d/dx x d/dtheta is the radial direction). The grid's inner x lines are moved along x by up to
    jitter/2 of a cell, by a fixed integer pattern that differs from line to line of theta: a regular grid has
    cospherical points and a mirror symmetry, whose ties gmsh's tetrahedralisation breaks by the round-off of the
    inflated surface (measured: the 1- and 2-rank runs' tetrahedra then differ, one the other's mirror image);
    moved, the two are the same. (Moved in theta too, the base's quadrilaterals fold, and gmsh fills some folds
    with flat tetrahedra whose four vertices are on the base: slivers for the muscle run.)"""
    i, j = (k.ravel() for k in np.meshgrid(np.arange(nx + 1), np.arange(nt + 1), indexing="ij"))
    shift = (((7 * i + 13 * j) % 11) / 10.0 - 0.5) * ((i > 0) & (i < nx))
    x = -length / 2 + (i + jitter * shift) * length / nx
    theta = -angle + j * 2 * angle / nt
    points = np.column_stack([x, radius * np.sin(theta), radius * np.cos(theta)])
    index = np.arange(len(points)).reshape(nx + 1, nt + 1)
    cells = []
    for a_i in range(nx):
        for a_j in range(nt):
            a, b, c, d = index[a_i, a_j], index[a_i + 1, a_j], index[a_i + 1, a_j + 1], index[a_i, a_j + 1]
            cells += [[a, b, c], [a, c, d]] if (a_i + a_j) % 2 == 0 else [[a, b, d], [b, c, d]]
    return points, np.asarray(cells, dtype=np.int64)


def write_obj(path: Path, points: np.ndarray, cells: np.ndarray, header: str | None = None) -> None:
    """An OBJ file (the coordinates exactly: repr), on rank 0 only."""
    lines = [f"# {header}"] if header else []
    lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in points.tolist()]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in cells.tolist()]
    path.write_text("\n".join(lines) + "\n")


def _written(path: Path, points: np.ndarray, cells: np.ndarray, lines: np.ndarray | None = None) -> Path:
    """The surface written on rank 0 (.obj exactly; .msh with ``lines`` as the physical line "edge"), seen by all."""
    if COMM.rank == 0:
        if path.suffix == ".obj":
            write_obj(path, points, cells)
        elif path.suffix == ".msh":
            mesh = meshio.Mesh(points, [("line", lines), ("triangle", cells)],
                               cell_data={"gmsh:physical": [np.full(len(lines), 2), np.full(len(cells), 1)],
                                          "gmsh:geometrical": [np.full(len(lines), 2), np.full(len(cells), 1)]},
                               field_data={"membrane": np.array([1, 2]), "edge": np.array([2, 1])})
            mesh.write(path, file_format="gmsh22", binary=False)
        else:
            meshio.Mesh(points, [("triangle", cells)]).write(path)
    COMM.barrier()
    return path


def _as_file(raw: dict, path: Path) -> dict:
    """A disc example's document on the file ``path``: radius 1 (the default dp's length, as the disc's) and
    muscle.axis = [1, 0, 0] (the disc's default: a round patch has no principal axis)."""
    raw = copy.deepcopy(raw)
    raw["membrane"] = {k: v for k, v in raw["membrane"].items() if k not in ("surface", "size")}
    raw["membrane"].update({"surface": "file", "file": str(path), "radius": 1.0, "centre": [0.0, 0.0, 0.0]})
    raw["muscle"]["axis"] = [1.0, 0.0, 0.0]
    raw["output"] = OUTPUT
    return raw


def _run(raw: dict, out: Path) -> dict:
    from model.experiments.membrane_run import run_membrane

    return run_membrane(parse_membrane(raw), out, COMM)


@pytest.mark.parametrize(("example", "suffix"), [("membrane_muscle_bone", ".obj"), ("membrane_muscle", ".stl")])
def test_the_disc_from_a_file_gives_the_disc_run(shared_tmp: Path, example: str, suffix: str) -> None:
    """The disc example and the same disc from a file: the same pressure steps (pressures and volumes to 1e-12),
    the same first phase and smoothing ([extrusion]), rest and base volume 0, the same tetrahedra (number,
    volume) and fibre ends, and the same fibres (cells matched by their centroids; to 1e-10)."""
    from scipy.spatial import cKDTree

    from meshes.data import read_msh

    raw = tomllib.loads((EXAMPLES / f"{example}.toml").read_text())
    raw["output"] = OUTPUT
    size = raw["membrane"]["size"]
    disc = disc_surface(raw["membrane"]["radius"], size)
    # the file's fibre ends come from its nodes' extent along x, the disc's from c = 0, a = radius: the same when
    # the rim has nodes at x = +-radius (32 rim nodes at size 0.2, Debian 12 and 13's gmsh)
    assert disc.points[:, 0].min() == -disc.points[:, 0].max() == -raw["membrane"]["radius"]
    path = _written(shared_tmp / f"disc{suffix}", disc.points, disc.cells)
    builtin = _run(copy.deepcopy(raw), shared_tmp / "disc")
    mine = _run(_as_file(raw, path), shared_tmp / "file")
    assert builtin["status"] == mine["status"] == "completed"
    assert mine["surface"]["base_volume"] == builtin["surface"]["base_volume"] == 0.0
    assert abs(mine["surface"]["rest_volume"] - builtin["surface"]["rest_volume"]) <= 1e-14
    for key in ("steps", *(("extrusion",) if "extrusion" in raw else ())):
        ours = mine[key]["first_steps"] if key == "extrusion" else mine[key]
        theirs = builtin[key]["first_steps"] if key == "extrusion" else builtin[key]
        assert len(ours) == len(theirs) > 1
        for a, b in zip(ours, theirs, strict=True):
            assert a["pressure"] == pytest.approx(b["pressure"], rel=1e-12)
            assert a["volume"] == pytest.approx(b["volume"], rel=1e-12)
    if "extrusion" in raw:
        assert mine["extrusion"]["smoothed_volume"] == pytest.approx(builtin["extrusion"]["smoothed_volume"],
                                                                     rel=1e-12)
    ours, theirs = mine["muscle"], builtin["muscle"]
    for key in ("tetrahedra", "points", "origin_triangles", "insertion_triangles", "axis", "half_length"):
        assert ours[key] == theirs[key], key
    for key in ("volume", "enclosed_volume"):
        assert ours[key] == pytest.approx(theirs[key], rel=1e-12)
    assert ours["axis_centre"] == theirs["axis_centre"] == 0.0
    if COMM.rank == 0:
        meshes = [read_msh(shared_tmp / name / "muscle.msh") for name in ("disc", "file")]
        a0 = [np.load(shared_tmp / name / "fibres.npy") for name in ("disc", "file")]
        centroids = [m.points[m.cells].mean(axis=1) for m in meshes]
        distance, index = cKDTree(centroids[1]).query(centroids[0])
        assert distance.max() < 1e-12
        assert np.abs(a0[1][index] - a0[0]).max() < 1e-10


def _shaft_raw(path: Path, target: float) -> dict:
    return {"membrane": {"surface": "file", "file": str(path), **LAW}, "inflation": {"target_volume": target},
            "muscle": dict(MUSCLE), "output": OUTPUT}


def test_a_patch_on_a_bone_shaft_to_muscle(shared_tmp: Path) -> None:
    """The shaft patch (153 nodes, 256 triangles) inflated to V = 0.3 over its rest shape, closed, meshed, fibres,
    and muscle.toml run (module docstring)."""
    from meshes.data import read_msh
    from meshes.membrane import enclosed_volume
    from model import pipeline
    from model.config.document import load

    points, cells = shaft_patch()
    target = 0.3
    out = shared_tmp / "shaft"
    summary = _run(_shaft_raw(_written(shared_tmp / "shaft.obj", points, cells), target), out)
    assert summary["status"] == "completed"
    surface, last, muscle = summary["surface"], summary["steps"][-1], summary["muscle"]
    # the volumes are measured from the rest patch: V_b its cone volume about the origin, the rest volume 0
    assert surface["base_volume"] == pytest.approx(enclosed_volume(points, cells), rel=1e-15)
    assert surface["base_volume"] > 0.3 and abs(surface["rest_volume"]) < 1e-13
    assert abs(last["volume"] - target) <= 1e-6 * target
    assert muscle["volume"] == pytest.approx(muscle["enclosed_volume"], rel=1e-12)
    assert muscle["enclosed_volume"] == last["volume"]
    # the principal axis: along the shaft (the moved nodes turn it by 4e-5), the patch's middle and half-length
    assert muscle["axis"] == pytest.approx([1.0, 0.0, 0.0], abs=1e-3)
    assert muscle["axis_centre"] == pytest.approx(0.0, abs=1e-3) and muscle["half_length"] == pytest.approx(1.0, 1e-3)
    assert muscle["origin_triangles"] == muscle["insertion_triangles"] == 48  # |x| > 0.6 of the 16 x 8 grid
    # the same patch away from the origin: the same volumes (the closed surface's: independent of the origin)
    shift = np.array([0.3, -0.2, 0.5])
    moved = _run(_shaft_raw(_written(shared_tmp / "moved.obj", points + shift, cells), target), shared_tmp / "moved")
    assert moved["surface"]["base_volume"] != pytest.approx(surface["base_volume"], rel=0.01)
    assert moved["muscle"]["volume"] == pytest.approx(muscle["volume"], rel=1e-9)
    assert len(moved["steps"]) == len(summary["steps"])
    assert moved["steps"][-1]["pressure"] == pytest.approx(last["pressure"], rel=1e-6)
    if COMM.rank == 0:
        mesh = read_msh(out / "muscle.msh")
        assert mesh.volume() == pytest.approx(muscle["volume"], rel=1e-12)
        a0 = np.load(out / "fibres.npy")
        assert np.abs(np.linalg.norm(a0, axis=1) - 1.0).max() < 1e-12
        # a tetrahedron with a face on an end: a0 is that face's normal (phi is constant on it), into the muscle at
        # the origin (phi = 0 there, > 0 inside) and out of it at the insertion, but where the discrete maximum
        # principle fails: in the flat tetrahedra of the wedge along the rim, where the patch leaves the base, a
        # patch node next to the insertion may have phi > 1 (measured: 5 of the 48 at the insertion, none at the
        # origin; a0's sign does not matter to the muscle, whose active stress has a0 a0^T)
        for name, sign in (("origin", 1.0), ("insertion", -1.0)):
            faces = {tuple(f) for f in np.sort(mesh.boundary_facets(name), axis=1)}
            along = []
            for k, tet in enumerate(mesh.cells):
                for opposite in range(4):
                    face = np.delete(tet, opposite)
                    if tuple(np.sort(face)) in faces:
                        p = mesh.points[face]
                        n = np.cross(p[1] - p[0], p[2] - p[0])
                        n /= np.linalg.norm(n)
                        n *= np.sign(n @ (mesh.points[tet[opposite]] - p[0]))  # towards the inside
                        along.append(sign * a0[k] @ n)
            along = np.asarray(along)
            assert len(along) >= 20 and np.abs(np.abs(along) - 1.0).max() < 1e-10, name
            assert np.count_nonzero(along > 0) >= 0.75 * len(along), name  # measured 48 of 48, 43 of 48
        along = a0 @ np.array([1.0, 0.0, 0.0])
        x = mesh.points[mesh.cells].mean(axis=1)[:, 0]
        belly = np.abs(x) < 0.2
        assert belly.sum() > 50 and along[belly].min() > 0.98 and along[belly].mean() > 0.99
        assert along.mean() > 0.7
        # the muscle lies on the bone: outside the faceted cylinder (a triangle of angular span w is at least
        # r cos(w/2) from the axis)
        theta = np.arctan2(points[:, 1], points[:, 2])[cells]
        span = (theta.max(axis=1) - theta.min(axis=1)).max()
        r = np.hypot(mesh.points[:, 1], mesh.points[:, 2])
        assert r.min() >= BONE_RADIUS * np.cos(span / 2) - 1e-12
    # muscle.toml runs as it is: both ends clamped, the fibres contract, the ends' reactions balance
    result = pipeline.run(load(out / "muscle.toml"), out / "contraction", COMM)
    assert result["status"] == "completed"
    assert len(result["steps"]) == MUSCLE["steps"] and all(s["converged"] for s in result["steps"])
    origin, insertion = (np.asarray(result["steps"][-1]["reactions"][k]) for k in ("origin", "insertion"))
    assert np.linalg.norm(origin + insertion) < 1e-8 * np.linalg.norm(origin)
    assert origin[0] < 0.0 < insertion[0]


def _annulus(inner: float = 0.4, outer: float = 1.0, nr: int = 3, nt: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """A flat ring: two boundary loops."""
    r = np.linspace(inner, outer, nr + 1)
    t = np.linspace(0.0, 2 * np.pi, nt, endpoint=False)
    R, T = np.meshgrid(r, t, indexing="ij")
    points = np.column_stack([(R * np.cos(T)).ravel(), (R * np.sin(T)).ravel(), np.zeros(R.size)])
    index = np.arange(len(points)).reshape(nr + 1, nt)
    cells = []
    for i in range(nr):
        for j in range(nt):
            a, b, c, d = index[i, j], index[i + 1, j], index[i + 1, (j + 1) % nt], index[i, (j + 1) % nt]
            cells += [[a, b, c], [a, c, d]]
    return points, np.asarray(cells)


def _punctured_torus(n: int = 12, m: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """A torus with one grid cell removed: one boundary loop, V - E + F = -1 (a handle)."""
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, n, endpoint=False), np.linspace(0, 2 * np.pi, m, endpoint=False),
                       indexing="ij")
    points = np.column_stack([((1 + 0.4 * np.cos(v)) * np.cos(u)).ravel(), ((1 + 0.4 * np.cos(v)) * np.sin(u)).ravel(),
                              (0.4 * np.sin(v)).ravel()])
    index = np.arange(n * m).reshape(n, m)
    cells = []
    for i in range(n):
        for j in range(m):
            if (i, j) == (0, 0):
                continue
            a, b, c, d = index[i, j], index[(i + 1) % n, j], index[(i + 1) % n, (j + 1) % m], index[i, (j + 1) % m]
            cells += [[a, b, c], [a, c, d]]
    return points, np.asarray(cells)


def _two_pieces() -> tuple[np.ndarray, np.ndarray]:
    points, cells = shaft_patch(nx=2, nt=2)
    return np.vstack([points, points + [3.0, 0.0, 0.0]]), np.vstack([cells, cells + len(points)])


@pytest.mark.parametrize(("surface", "phase", "message"), [
    (_annulus, "muscle", r"has 2 boundary loops; \[muscle\] needs one patch with one rim$"),
    (_two_pieces, "extrusion", r"has 2 separate pieces; \[extrusion\] needs one patch with one rim$"),
    (lambda: (sphere_surface(1.0, 0.8).points, sphere_surface(1.0, 0.8).cells), "both",
     r"is a closed surface \(no boundary loop\); \[extrusion\] and \[muscle\] need one patch with one rim$"),
    (_punctured_torus, "muscle", r"has one boundary loop but Euler characteristic V - E \+ F = -1 \(a disc's is 1: "
                                 r"the patch has handles\); \[muscle\] needs one patch with one rim$"),
])
def test_a_patch_that_is_not_a_disc_is_refused(shared_tmp: Path, surface, phase: str, message: str) -> None:  # noqa: ANN001
    points, cells = surface()
    path = _written(shared_tmp / "patch.obj", points, cells)
    raw = _shaft_raw(path, 0.3)  # every surface here consistently oriented by its vertex order
    if phase in ("extrusion", "both"):
        raw["extrusion"] = {"offset": 0.02, "first_volume": 0.4, "rest_volume": 0.2}
    if phase == "extrusion":
        del raw["muscle"]
    out = shared_tmp / "out"
    with pytest.raises(ConfigError, match=r"^membrane\.file: .*patch\.obj " + message) as err:
        _run(raw, out)
    assert "\n" not in str(err.value)
    COMM.barrier()
    assert not out.exists()  # refused when the file is read, before the output folder is made


@pytest.mark.parametrize(("change", "message"), [
    ({"membrane": {"fixed": {"boundary": [2]}}},
     r"^muscle: needs the rim clamped \(membrane\.fixed = \{ boundary = \[0, 1, 2\] \}, the patch's open boundary "
     r"held in x, y, z\): the base is closed on it$"),
    ({"membrane": {"fixed": {"boundary": [0, 1]}}, "extrusion": {"offset": 0.02, "first_volume": 0.4,
                                                                 "rest_volume": 0.2}},
     r"^extrusion: needs the rim clamped "),
    ({"muscle": {"axis": [0.0, 0.0, 0.0]}}, r"^muscle\.axis: must not be zero"),
    ({"membrane": {"surface": "sphere_octant"}}, r"^muscle: needs surface = 'disc' or 'file' "),
])
def test_bad_patch_keys_in_the_config(shared_tmp: Path, change: dict, message: str) -> None:
    raw = _shaft_raw(shared_tmp / "none.obj", 0.3)
    raw["membrane"]["file"] = __file__
    for section, values in change.items():
        raw.setdefault(section, {}).update(values)
    if raw["membrane"]["surface"] == "sphere_octant":
        raw["membrane"] = {**LAW, "surface": "sphere_octant"}
    with pytest.raises(ConfigError, match=message) as err:
        parse_membrane(raw)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize(("which", "message"), [
    ("half", r"^membrane\.fixed: .*rim\.msh: 16 of the rim's 48 edges are not held, e\.g\. the edge of points "),
    ("inside", r"^membrane\.fixed: .*rim\.msh: 16 held edges are inside the patch, not on its rim, e\.g\. "),
])
def test_the_rim_must_be_the_border(shared_tmp: Path, which: str, message: str) -> None:
    """A .msh file's named line as the border (fixed = { edge = [0, 1, 2] }): a part of the rim, or the rim and a
    line across the patch, refused when the file is read."""
    points, cells = shaft_patch(jitter=0.0)  # the line theta = 0 at y = 0
    directed = np.concatenate([cells[:, [0, 1]], cells[:, [1, 2]], cells[:, [2, 0]]])
    edges, counts = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
    rim = edges[counts == 1]
    if which == "half":  # the two long sides only (theta = +-1): the short ends (x = +-1) free
        lines = rim[np.abs(np.abs(points[rim].mean(axis=1)[:, 0]) - 1.0) > 1e-9]
    else:  # the rim and the line theta = 0 across the patch
        middle = np.all(np.abs(points[edges][:, :, 1]) < 1e-12, axis=1)
        lines = np.vstack([rim, edges[middle]])
    path = _written(shared_tmp / "rim.msh", points, cells, lines)
    raw = _shaft_raw(path, 0.3)
    raw["membrane"]["fixed"] = {"edge": [0, 1, 2]}
    with pytest.raises(ConfigError, match=message + r".*; \[muscle\] needs the whole rim clamped and nothing else "
                                                    r"\(the base is closed on it\)$") as err:
        _run(raw, shared_tmp / "out")
    assert "\n" not in str(err.value)


def test_a_round_patch_needs_an_axis(shared_tmp: Path) -> None:
    disc = disc_surface(1.0, 0.3)
    raw = _shaft_raw(_written(shared_tmp / "round.obj", disc.points, disc.cells), 0.3)
    with pytest.raises(ConfigError, match=r"^muscle\.axis: .*round\.obj: the patch has no principal axis: its two "
                                          r"largest second moments .* are within 5% \(a round patch\): give axis$"):
        _run(raw, shared_tmp / "out")


def test_the_example(shared_tmp: Path) -> None:
    """examples/membrane_file_muscle.toml: examples/data/shaft_patch.obj is shaft_patch's; [extrusion], the
    inflation to the target and [muscle] complete, the tetrahedra enclose the target volume; every fibre is a unit
    vector; summary.json counts the tetrahedra with their four vertices on an end (grad phi = 0 there; none here,
    measured; one of 725 with the patch's nodes moved in theta too) as the mesh has them."""
    from meshes.data import read_msh

    example = EXAMPLES / "membrane_file_muscle.toml"
    raw = tomllib.loads(example.read_text())
    data = meshio.read(EXAMPLES / raw["membrane"]["file"])
    points, cells = shaft_patch()
    assert np.allclose(data.points, points, rtol=0, atol=1e-14) and np.array_equal(data.cells_dict["triangle"], cells)
    from model.experiments.membrane_run import run_membrane

    summary = run_membrane(load_membrane(example, {"output.xdmf": False, "output.vtu": False}), shared_tmp / "ex",
                           COMM)
    assert summary["status"] == "completed"
    target = raw["inflation"]["target_volume"]
    assert summary["extrusion"]["first_steps"][-1]["volume"] == pytest.approx(raw["extrusion"]["first_volume"],
                                                                             rel=1e-6)
    assert summary["extrusion"]["smoothed_volume"] <= raw["extrusion"]["rest_volume"]
    assert summary["surface"]["rest_volume"] == pytest.approx(summary["extrusion"]["smoothed_volume"], rel=1e-10)
    assert abs(summary["steps"][-1]["volume"] - target) <= 1e-6 * target
    muscle = summary["muscle"]
    assert muscle["volume"] == pytest.approx(target, rel=1e-6)
    if COMM.rank == 0:
        mesh = read_msh(shared_tmp / "ex" / "muscle.msh")
        a0 = np.load(shared_tmp / "ex" / "fibres.npy")
        assert np.abs(np.linalg.norm(a0, axis=1) - 1.0).max() < 1e-12
        flat = np.zeros(len(mesh.cells), dtype=bool)
        for name in ("origin", "insertion"):
            on_end = np.zeros(mesh.num_points, dtype=bool)
            on_end[np.unique(mesh.boundary_facets(name))] = True
            flat |= on_end[mesh.cells].all(axis=1)
        assert int(flat.sum()) == muscle["flat_end_tetrahedra"]  # 0 here (test_laplace_fibres_where_phi_is_constant
        # checks the fibres of such cells)


def test_laplace_fibres_where_phi_is_constant() -> None:
    """laplace_fibres on the structured box [0, 4] x [0, 1] x [0, 1] (4 hexahedra of 6 tetrahedra), origin its face
    x = 0 and the top face's first hexahedron (x <= 1), insertion x = 4: three tetrahedra of the first hexahedron
    have all four vertices on the origin (phi = 0 on them, grad phi = 0). Against phi solved here with numpy (P1
    stiffness): every other cell's a0 is grad phi / |grad phi|, those three the mean over their vertices of the
    nodal averages g_i = sum_T |T| grad_T phi / sum_T |T| (over the cells T around node i), normalised (to 1e-10)."""
    from meshes.box import box
    from meshes.data import MeshData
    from model.domain.distribute import build_domain
    from model.experiments.membrane import cell_values, laplace_fibres

    b = box((4.0, 1.0, 1.0), (4, 1, 1))
    x = b.points[b.facets][:, :, 0]
    origin = (b.facet_tags == b.boundary_names["xmin"]) | \
        ((b.facet_tags == b.boundary_names["zmax"]) & np.all(x <= 1.0, axis=1))
    insertion = b.facet_tags == b.boundary_names["xmax"]
    data = MeshData(b.points, b.cells, b.cell_tags, np.vstack([b.facets[origin], b.facets[insertion]]),
                    np.repeat(np.array([1, 2], np.int32), [int(origin.sum()), int(insertion.sum())]),
                    dict(b.region_names), {"origin": 1, "insertion": 2})
    a0 = cell_values(laplace_fibres(build_domain(COMM, data if COMM.rank == 0 else None)))
    if COMM.rank != 0:
        return
    # phi with numpy: P1 stiffness, phi = 0 / 1 on the ends' nodes
    n = len(b.points)
    ones = np.ones((len(b.cells), 4, 1))
    G = np.linalg.inv(np.concatenate([ones, b.points[b.cells]], axis=2))[:, 1:, :]  # grad of the barycentrics
    volume = np.abs(np.linalg.det(b.points[b.cells][:, 1:] - b.points[b.cells][:, :1])) / 6
    K = np.zeros((n, n))
    for T, cell in enumerate(b.cells):
        K[np.ix_(cell, cell)] += volume[T] * G[T].T @ G[T]
    phi = np.full(n, np.nan)
    phi[np.unique(b.facets[origin])] = 0.0
    phi[np.unique(b.facets[insertion])] = 1.0
    free = np.isnan(phi)
    known = ~free
    phi[free] = np.linalg.solve(K[np.ix_(free, free)], -K[np.ix_(free, known)] @ phi[known])
    grad = np.einsum("tdk,tk->td", G, phi[b.cells])
    flat = np.isin(b.cells, np.unique(b.facets[origin])).all(axis=1)
    assert flat.sum() == 3 and np.abs(grad[flat]).max() < 1e-12
    nodal = np.zeros((n, 3))
    weight = np.zeros(n)
    for T, cell in enumerate(b.cells):
        nodal[cell] += volume[T] * grad[T]
        weight[cell] += volume[T]
    expected = grad.copy()
    expected[flat] = (nodal / weight[:, None])[b.cells[flat]].mean(axis=1)
    expected /= np.linalg.norm(expected, axis=1)[:, None]
    assert np.abs(a0 - expected).max() < 1e-10
    assert np.all(a0[flat][:, 0] > 0.8)  # from the origin towards the insertion (measured 0.83 to 0.90)
