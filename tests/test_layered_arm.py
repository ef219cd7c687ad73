"""The layered arm against the conforming arm segment (issue 14 item 3; model.experiments.layered_arm).

The mesh: meshes.layered_arm cuts the arm segment open along the muscle-fat interfaces, so the three bodies share
no node, and every interface node has a twin at the same place in the other body; volumes and skin are the
conforming mesh's. The run (coarse: size 15 mm, 8 elements per turn, one load step; muscle a activated to 1, b to
0.3): the fat stays on the muscles (sliding gap within the penalty's p/k, far below the bulge), the muscles do not
enter each other, the fat slips on the muscles (zero by construction when glued) and more on muscle a, the more
activated one; the skin bulges less than when glued, within a stated band (docs/layers.md has the numbers, the
same on 1 and 2 ranks).
"""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

from meshes import ParameterError, generate
from meshes.arm_segment import arm_segment
from meshes.layered_arm import LAYERED_ARM_FACES, LAYERED_ARM_REGIONS, TOUCHING_FACES, layered_arm_meshes
from model.experiments.layered_arm import ArmResult, body_balance, compare_arms, run_arm, skin_difference

MESH = {"size": 0.015, "turn_elements": 8}


def _nodes(data, name: str) -> np.ndarray:  # noqa: ANN001 - MeshData
    return np.unique(data.facets[data.facet_tags == data.boundary_names[name]])


def test_the_layered_mesh_is_the_conforming_one_cut_open() -> None:
    conforming, layered = layered_arm_meshes(**MESH)
    assert set(layered.region_names) == set(LAYERED_ARM_REGIONS)
    assert set(layered.boundary_names) == set(LAYERED_ARM_FACES)
    assert layered.num_cells == conforming.num_cells
    assert layered.volume() == pytest.approx(conforming.volume(), rel=1e-12)
    # the conforming mesh is arm_segment's with the same parameters
    assert np.array_equal(arm_segment(**MESH).points, conforming.points)
    body_of = np.zeros(layered.num_points, dtype=int)
    for i, body in enumerate(("a", "b", "fat")):
        tags = [t for name, t in layered.region_names.items() if name.split("_")[0] == body]
        body_of[np.unique(layered.cells[np.isin(layered.cell_tags, tags)])] = i
    for muscle in ("a", "b"):
        lateral, cavity = _nodes(layered, f"{muscle}_lateral"), _nodes(layered, f"fat_cavity_{muscle}")
        assert not set(lateral) & set(cavity)  # no shared node
        assert np.all(body_of[lateral] == "ab".index(muscle)) and np.all(body_of[cavity] == 2)
        # ... but a twin at the same place: the cavity is the muscle's lateral surface
        order = np.lexsort(layered.points[lateral].T)
        twins = np.lexsort(layered.points[cavity].T)
        assert np.array_equal(layered.points[lateral][order], layered.points[cavity][twins])
    extra = layered.num_points - conforming.num_points
    assert extra == len(_nodes(layered, "fat_cavity_a")) + len(_nodes(layered, "fat_cavity_b"))
    skin = layered.points[_nodes(layered, "fat_skin")]
    assert np.allclose(np.hypot(skin[:, 0], skin[:, 1]), 0.03, rtol=1e-6)


def test_bad_parameters() -> None:
    with pytest.raises(ParameterError, match=r"layered_arm: turn_elements must be an integer in \[6, 10000\], got 4"):
        generate("layered_arm", turn_elements=4)
    with pytest.raises(ParameterError, match="spacing must be > 2 \\* muscle_radius"):
        generate("layered_arm", spacing=0.02)


@pytest.fixture(scope="module")
def runs() -> tuple[ArmResult, ArmResult]:
    return compare_arms(steps=1, **MESH)


def test_the_fat_stays_on_the_muscles_and_slides(runs: tuple[ArmResult, ArmResult]) -> None:
    conforming, layered = runs
    assert conforming.completed and layered.completed
    bulge = layered.bulge_max
    for name in ("fat_on_a", "fat_on_b"):
        pair = layered.pairs[name]
        # the sliding springs hold the fat on the muscle: |g| = |p| / k, well below the bulge
        assert max(pair["max_gap"], pair["max_penetration"]) < 0.1 * bulge, pair
        assert pair["active_points"] > 0
    # the muscles slip under the fat (the glued mesh cannot: its interface nodes are shared), by more than the
    # springs' give and more under the more activated muscle a
    gap = max(layered.pairs[n][k] for n in ("fat_on_a", "fat_on_b") for k in ("max_gap", "max_penetration"))
    assert layered.slip["a"]["max"] > 20.0 * gap
    assert layered.slip["a"]["max"] > 2.0 * layered.slip["b"]["max"]


def test_the_muscles_do_not_enter_each_other(runs: tuple[ArmResult, ArmResult]) -> None:
    _, layered = runs
    contact = layered.pairs["a_on_b"]
    assert contact["kind"] == "contact"
    assert contact["max_penetration"] <= 1e-6 * 0.13  # the augmented Lagrangian's tolerance x the arm's size
    assert layered.muscle_gap > 0.0  # the fat between them (2 mm at rest) is squeezed, not pierced


def test_the_skin_bulges_less_than_when_glued(runs: tuple[ArmResult, ArmResult]) -> None:
    """Glued, the muscles' shortening drags the fat along and the skin bulges by more; sliding frees it: the
    layered bulge is 30-90 % of the conforming one (measured 59 %, mean 52 %), and the skin moves by less than
    the conforming skin's largest displacement."""
    conforming, layered = runs
    assert conforming.bulge_max > 0.0 and layered.bulge_max > 0.0
    assert 0.3 * conforming.bulge_max < layered.bulge_max < 0.9 * conforming.bulge_max
    assert 0.3 * conforming.bulge_mean < layered.bulge_mean < 0.9 * conforming.bulge_mean
    difference = skin_difference(conforming, layered)
    assert 0.0 < difference["max"] < difference["max_conforming"]
    assert MPI.COMM_WORLD.allreduce(layered.bulge_max, op=MPI.MAX) == layered.bulge_max  # the same on every rank


# --- touching muscles (layered_arm's touching = true; examples/layered_arm_touching.toml) ---------------------------

TOUCHING = {"size": 0.015, "turn_elements": 8, "spacing": 0.019}
def test_touching_muscles_share_a_flat_face_cut_open() -> None:
    """touching = true: the bellies overlap and are cut at x = 0; the flat face is in both muscles' lateral
    surfaces, every node of a_flat has a twin in b_flat, and the fat has no part of it (no fat between)."""
    conforming, layered = layered_arm_meshes(**TOUCHING, touching=True)
    assert set(layered.boundary_names) == set(LAYERED_ARM_FACES) | set(TOUCHING_FACES)
    assert layered.num_cells == conforming.num_cells
    assert layered.volume() == pytest.approx(conforming.volume(), rel=1e-12)
    flat_a, flat_b = _nodes(layered, "a_flat"), _nodes(layered, "b_flat")
    assert len(flat_a) > 10 and not set(flat_a) & set(flat_b)
    assert np.allclose(layered.points[flat_a, 0], 0.0, atol=1e-9) and np.allclose(layered.points[flat_b, 0], 0.0,
                                                                                   atol=1e-9)
    order, twins = np.lexsort(layered.points[flat_a].T), np.lexsort(layered.points[flat_b].T)
    assert np.array_equal(layered.points[flat_a][order], layered.points[flat_b][twins])
    for m in "ab":  # lateral = flat + round; the fat's cavity is the round part
        lateral, flat, rnd = (set(_nodes(layered, f"{m}_{n}")) for n in ("lateral", "flat", "round"))
        assert lateral == flat | rnd
        triangles = {n: (layered.facet_tags == layered.boundary_names[f"{m}_{n}"]).sum()
                     for n in ("lateral", "flat", "round")}
        assert triangles["lateral"] == triangles["flat"] + triangles["round"]
        assert triangles["round"] == (layered.facet_tags == layered.boundary_names[f"fat_cavity_{m}"]).sum()
    # the nodes of the flat face's interior have three copies no more (a, b; the rim also the fat's)
    extra = layered.num_points - conforming.num_points
    rim = set(flat_a) & set(_nodes(layered, "a_round"))
    assert extra == len(_nodes(layered, "fat_cavity_a")) + len(_nodes(layered, "fat_cavity_b")) + len(flat_a) - \
        len(rim)


def test_touching_bad_spacing() -> None:
    with pytest.raises(ParameterError, match="layered_arm: with touching = true spacing must be between"):
        generate("layered_arm", touching=True)  # the default spacing 24 mm > 2 x 11 mm: apart
    with pytest.raises(ParameterError, match="layered_arm: touching must be true or false, got 1"):
        generate("layered_arm", touching=1)


@pytest.fixture(scope="module")
def touching() -> ArmResult:
    return run_arm(True, steps=2, activations=(1.0, 1.0), touching=TOUCHING["spacing"], k_contact=1e11,
                   augmented=False, size=TOUCHING["size"], turn_elements=TOUCHING["turn_elements"])


def test_touching_muscles_press_on_each_other(touching: ArmResult) -> None:
    """Both muscles fully active bulge into each other: the flat-face contact carries force (measured 10.2 N on
    33 nodes), the penetration is the penalty's p / k (3.1 um at k = 1e11, below 5 % of the skin bulge), and the
    fat still slides on both muscles (|g| within its springs' give, slip far larger). Newton 13 + 17 iterations
    on Debian 12's mesh, 15 + 12 on Debian 13's (full steps: model.problem.body_contact, potential_reason)."""
    assert touching.completed and touching.newton_iterations and max(touching.newton_iterations) <= 20
    contact = touching.pairs["a_on_b"]
    assert contact["pair"] == "a_flat-b_flat" and contact["kind"] == "contact"
    assert contact["active_points"] > 10
    assert contact["normal_force"] > 5.0  # N
    force = np.asarray(contact["force"])
    assert force[0] < 0.0 and abs(force[0]) > 0.99 * np.linalg.norm(force)  # b pushes a along -x, the face normal
    assert abs(force[0]) == pytest.approx(contact["normal_force"], rel=1e-3)
    assert 0.0 < contact["max_penetration"] < 0.05 * touching.bulge_max
    assert touching.muscle_gap == pytest.approx(-contact["max_penetration"], rel=1e-12)
    for m in "ab":
        pair = touching.pairs[f"fat_on_{m}"]
        assert pair["master"] == f"{m}_round" and pair["active_points"] > 0
        assert max(pair["max_gap"], pair["max_penetration"]) < 0.1 * touching.bulge_max
        assert touching.slip[m]["max"] > 20.0 * max(pair["max_gap"], pair["max_penetration"])


def test_touching_action_equals_reaction(touching: ArmResult) -> None:
    """Each body is in equilibrium under its clamps' reactions and its pairs' forces, with the force on b from a
    taken as minus the reported force on a from b (and the force on a muscle from the fat as minus the force on
    the fat): the residual is below 0.1 % of the contact force (measured 4e-4 N of 10.2 N; 0.7 % when the fat's
    nodes on the flat face's rim were tied to both muscles); the clamps' reactions sum to zero (all internal)."""
    scale = touching.pairs["a_on_b"]["normal_force"]
    for body, residual in body_balance(touching).items():
        assert np.linalg.norm(residual) < 1e-3 * scale, (body, residual)
    assert MPI.COMM_WORLD.allreduce(scale, op=MPI.MAX) == scale  # the same on every rank
