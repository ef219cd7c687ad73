"""Curved bellies in contact (issue 14 item 3; examples/twin_muscles.toml, model.experiments.twin_muscles).

Two fusiform muscles side by side, mirror images about x = 0 (meshes.twin_muscles), both activated to 1 with their
ends clamped: the bellies bulge and press on each other (two penalty pairs, a on b and b on a). The closed
reference is the mirror symmetry: the contact plane is x = 0, and each muscle against a rigid frictionless plane
at x = 0 with the wall penalty 4 k (model.experiments.twin_muscles.WALL_FACTOR: both pairs push a pressed node,
each by k times the gap 2 d to its twin) must give the same answer; the run is mirror-symmetric, the pairs' forces
are equal and opposite, the penetration is ~ p / k. At a low activation the gap stays open: no active pair and the
answer of the run without contact. docs/layers.md ("Curved bellies in contact") has the numbers.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import EXAMPLES

from meshes import ParameterError, generate
from meshes.twin_muscles import TWIN_MUSCLES_FACES, TWIN_MUSCLES_REGIONS, mesh_gap
from model.config import load, parse
from model.experiments.twin_muscles import MESH, WALL_FACTOR, mirror_pairs, plane_raw, run_twin, twin_raw

M = np.array([-1.0, 1.0, 1.0])
K = (1e10, 1e11)


def test_the_mesh_is_two_mirror_images() -> None:
    """a's nodes, cells and named triangles are b's mirrored (exactly); the bellies are at least gap apart (the
    exact surfaces gap apart, the facets inside them); names and volumes as documented."""
    data = generate("twin_muscles", **MESH)
    assert set(data.region_names) == set(TWIN_MUSCLES_REGIONS)
    assert set(data.boundary_names) == set(TWIN_MUSCLES_FACES)
    n = data.num_points // 2
    assert np.array_equal(data.points[:n] * M, data.points[n:])
    half = len(data.cells) // 2
    assert np.array_equal(np.sort(data.cells[:half], axis=1) + n, np.sort(data.cells[half:], axis=1))
    for face in ("origin", "insertion", "lateral"):
        a = data.facets[data.facet_tags == data.boundary_names[f"a_{face}"]]
        b = data.facets[data.facet_tags == data.boundary_names[f"b_{face}"]]
        assert np.array_equal(np.sort(a, axis=1) + n, np.sort(b, axis=1)), face
    assert np.all(data.points[:n, 0] < 0.0) and np.all(data.points[n:, 0] > 0.0)
    assert MESH["gap"] <= mesh_gap(data) < 3.0 * MESH["gap"]
    assert data.volume("a_belly") == pytest.approx(data.volume("b_belly"), rel=1e-12)
    assert data.volume("a_tendon") == pytest.approx(data.volume("b_tendon"), rel=1e-12)


@pytest.mark.parametrize(("key", "value"), [("gap", 0.0), ("gap", -1e-4), ("gap", 0.006), ("gap", "0.1"),
                                            ("tendon_radius", 0.007), ("turn_elements", 4), ("size", 0.0)])
def test_bad_parameters_are_refused(key: str, value: object) -> None:
    with pytest.raises(ParameterError, match=f"twin_muscles: {key}"):
        generate("twin_muscles", **{**MESH, key: value})


def test_the_example_is_the_experiments_run() -> None:
    """examples/twin_muscles.toml is twin_raw() (k = 1e10, 8 steps, activation 1)."""
    shipped = load(EXAMPLES / "twin_muscles.toml")
    built = parse(twin_raw())
    for key in ("mesh", "discretization", "materials", "boundaries", "contacts", "loading", "petsc_options"):
        assert getattr(shipped, key) == getattr(built, key), key


@pytest.fixture(scope="module")
def runs() -> dict[str, object]:
    """The walls first, then the pairs (a wall built after a pairs run failed once in UFL during development:
    docs/layers.md, Curved bellies in contact)."""
    out: dict[str, object] = {f"plane{k:g}": run_twin(plane_raw(WALL_FACTOR * k)) for k in K}
    out.update({f"twin{k:g}": run_twin(twin_raw(k)) for k in K})
    out["augmented"] = run_twin(twin_raw(K[0], augmented=True))
    out["low"] = run_twin(twin_raw(K[0], activation=0.03))
    out["low_free"] = run_twin(twin_raw(K[0], activation=0.03, contact=False))
    return out


def test_twin_muscles_against_each_other_as_each_against_a_wall(runs: dict) -> None:
    """Mirror symmetry (1e-10 of max |u|), the same displacement and contact force as the wall with 4 k (to
    1e-3 of max |u| and 2e-3 of the force), forces on a and b equal and opposite, penetration ~ 1/k."""
    penetration = []
    for k in K:
        twin, wall = runs[f"twin{k:g}"], runs[f"plane{k:g}"]
        assert twin.completed and wall.completed
        ia, ib = mirror_pairs(twin.X)
        scale = np.abs(wall.u).max()
        assert scale > 5e-4  # m: the bellies shorten and bulge (0.98 mm at most)
        assert np.abs(twin.u[ia] - twin.u[ib] * M).max() < 1e-10 * scale
        assert np.abs(wall.u[ia] - wall.u[ib] * M).max() < 1e-10 * scale
        assert np.abs(twin.u[ib] - wall.u[ib]).max() < 1e-3 * scale
        f_a, f_b = twin.body_force["a"], twin.body_force["b"]
        assert np.abs(f_a + f_b).max() < 1e-10 * np.abs(f_b).max()
        assert f_b[0] > 0.5  # N: b pushed along +x
        assert f_b[0] == pytest.approx(wall.reports[1]["force"][0], rel=2e-3)
        reports = twin.reports
        assert reports[0]["active_points"] == reports[1]["active_points"] >= 1
        assert reports[0]["max_penetration"] == pytest.approx(reports[1]["max_penetration"], rel=1e-8)
        penetration.append(reports[0]["max_penetration"])
    assert 8.0 < penetration[0] / penetration[1] < 12.0  # ~ 1/k


def test_a_low_activation_leaves_the_gap_open(runs: dict) -> None:
    """Activation 0.03: the bellies bulge less than the gap: no active point, the answer of the run without
    contact."""
    low, free = runs["low"], runs["low_free"]
    assert all(r["active_points"] == 0 and r["max_penetration"] == 0.0 for r in low.reports)
    assert np.abs(free.u).max() > 1e-5
    assert np.abs(low.u - free.u).max() < 1e-12


def test_augmented_pairs_reach_the_penalties_limit(runs: dict) -> None:
    """augmented = true (Uzawa updates of both pairs' pressures): mirror-symmetric, penetration below 1e-9 m, and
    the contact force is the two penalties' 1/k extrapolation to k -> infinity, f(1e11) + (f(1e11) - f(1e10)) / 9
    (to 1e-4)."""
    aug = runs["augmented"]
    assert aug.completed
    ia, ib = mirror_pairs(aug.X)
    assert np.abs(aug.u[ia] - aug.u[ib] * M).max() < 1e-10 * np.abs(aug.u).max()
    assert all(0.0 < r["max_penetration"] < 1e-9 for r in aug.reports)
    f10, f11 = (runs[f"twin{k:g}"].body_force["b"][0] for k in K)
    assert aug.body_force["b"][0] == pytest.approx(f11 + (f11 - f10) / 9.0, rel=1e-4)
    assert np.abs(aug.body_force["a"] + aug.body_force["b"]).max() < 1e-10 * aug.body_force["b"][0]


@pytest.mark.parametrize(("change", "message"), [
    ({"exact": True}, "smooth_normals: not with exact = true"),
    ({"master": None, "obstacle": "plane", "point": [0.0, 0.0, 0.0], "normal": [1.0, 0.0, 0.0]},
     "smooth_normals: only with master"),
    ({"master": None, "self_contact": True}, "smooth_normals: not with self_contact = true"),
    ({"smooth_normals": "yes"}, "smooth_normals: must be true or false")])
def test_smooth_normals_only_for_pairs_of_bodies(change: dict, message: str) -> None:
    """[[contact]] smooth_normals: a one-line ConfigError with an obstacle, with self-contact, with exact."""
    from model.config import ConfigError

    raw = twin_raw(smooth_normals=True)
    pair = {**raw["contact"][0], **change}
    raw["contact"][0] = {k: v for k, v in pair.items() if v is not None}
    with pytest.raises(ConfigError, match=message):
        parse(raw)
    assert parse(twin_raw(smooth_normals=True)).contacts[0].smooth_normals is True
    assert parse(twin_raw()).contacts[0].smooth_normals is None  # the default: T's own normal for contact


def test_smoothed_normals_keep_the_finer_mesh_symmetric() -> None:
    """12 elements per turn (size 4 mm, 5,514 dofs), k = 1e10: with T's own normals the pairs converge to an
    asymmetric state (docs/layers.md); with the masters' interpolated nodal normals (smooth_normals, l2 line
    search) the answer is mirror-symmetric (1e-8 of max |u|) and the wall's with 4 k (1e-3 of max |u|, the force on
    b to 2e-3), both pairs carrying the same load."""
    fine = {"turn_elements": 12, "size": 0.004}
    wall = run_twin(plane_raw(WALL_FACTOR * K[0], **fine))
    twin = run_twin(twin_raw(K[0], smooth_normals=True, **fine))
    assert twin.completed and wall.completed and twin.dofs > 5000  # 5,514 (Debian 12), 5,556 (Debian 13: its gmsh)
    ia, ib = mirror_pairs(twin.X)
    scale = np.abs(wall.u).max()
    assert np.abs(twin.u[ia] - twin.u[ib] * M).max() < 1e-8 * scale  # Newton's tolerance (faceted: 0.23)
    assert np.abs(twin.u[ib] - wall.u[ib]).max() < 1e-3 * scale
    assert twin.body_force["b"][0] == pytest.approx(wall.reports[1]["force"][0], rel=2e-3)
    first, second = twin.reports
    assert first["active_points"] == second["active_points"] >= 1
    assert first["normal_force"] == pytest.approx(second["normal_force"], rel=1e-6)
