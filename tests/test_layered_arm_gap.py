"""Muscles that start apart and close a gap (issue 14 item 3; examples/layered_arm_gap.toml,
model.experiments.layered_arm.run_gap).

The mesh: layered_arm(touching = true, gap = g) cuts the overlapping bellies at x = -g/2 (a) and x = +g/2 (b) and
leaves the slab between them empty: the flat faces a_flat and b_flat are parallel planes g apart, the fat's surface
on the void (fat_void) lies in the slab, and the rest is the touching arm's (lateral = flat + round, the fat's cavity
= round). The run (coarse mesh, both muscles activated to 1 in two steps, a_flat against b_flat in frictionless
penalty contact): at rest and at half the activation the faces are apart (no contact force, no active node); at full
activation they touch, the contact pushes a along -x with a penetration of the penalty's p/k (far below the gap),
and every body is in equilibrium with its clamps' reactions and the pairs' forces (action = reaction between the
muscles). docs/layers.md ("Muscles that close a gap") has the numbers, the same on 1 and 2 ranks.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import EXAMPLES
from mpi4py import MPI

from meshes import ParameterError, generate
from meshes.layered_arm import GAP_BOUNDARY, GAP_FACES, LAYERED_ARM_FACES, TOUCHING_FACES, layered_arm_meshes
from model.config import load, parse
from model.domain.readers import load_mesh_data
from model.errors import ConfigError
from model.experiments.layered_arm import GAP_MESH, ArmResult, body_balance, gap_raw, run_gap

#: The flat faces' distance at rest: the muscles' approach under full activation is about 0.21 mm on the coarse mesh
#: (measured with g = 0.3 mm: the contact never active), 0.10 mm at half of it.
GAP = 0.00015
STEPS = 2


def _nodes(data, name: str) -> np.ndarray:  # noqa: ANN001 - MeshData
    return np.unique(data.facets[data.facet_tags == data.boundary_names[name]])


def _count(data, name: str) -> int:  # noqa: ANN001 - MeshData
    return int((data.facet_tags == data.boundary_names[name]).sum())


def test_the_example_is_the_experiments_run() -> None:
    """examples/layered_arm_gap.toml is the run of these tests, gap_raw(GAP, STEPS)."""
    shipped = load(EXAMPLES / "layered_arm_gap.toml")
    built = parse(gap_raw(GAP, STEPS))
    for key in ("mesh", "discretization", "materials", "boundaries", "contacts", "loading", "petsc_options"):
        assert getattr(shipped, key) == getattr(built, key), key


def test_the_flat_faces_face_each_other_across_a_void() -> None:
    """a_flat on x = -g/2, b_flat on x = +g/2, the same lens (area to 1 %); the fat's void surface within the slab;
    the fat's whole boundary named (ends, skin, cavities, void); the fat touches the flat faces on their rims
    only (no fat between them); the layered mesh is the conforming one cut open."""
    conforming, layered = layered_arm_meshes(**GAP_MESH, touching=True, gap=GAP)
    assert set(layered.boundary_names) == set(LAYERED_ARM_FACES) | set(TOUCHING_FACES) | {GAP_BOUNDARY}
    assert set(GAP_FACES) <= set(conforming.boundary_names)
    assert layered.num_cells == conforming.num_cells
    assert layered.volume() == pytest.approx(conforming.volume(), rel=1e-12)
    P = layered.points
    flat_a, flat_b, void = _nodes(layered, "a_flat"), _nodes(layered, "b_flat"), _nodes(layered, "fat_void")
    assert len(flat_a) > 10 and len(flat_b) > 10 and len(void) > 10
    assert np.allclose(P[flat_a, 0], -0.5 * GAP, rtol=0.0, atol=1e-12)
    assert np.allclose(P[flat_b, 0], 0.5 * GAP, rtol=0.0, atol=1e-12)
    assert np.all(np.abs(P[void, 0]) <= 0.5 * GAP + 1e-12)

    def area(name: str) -> float:
        t = P[layered.facets[layered.facet_tags == layered.boundary_names[name]]]
        return float(0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum())

    assert area("a_flat") == pytest.approx(area("b_flat"), rel=0.01)
    assert area("a_flat") > 1e-4  # m^2: 25 mm x 11 mm lens
    fat_faces = ("proximal", "distal", "skin", "cavity_a", "cavity_b", "void")
    assert _count(layered, "fat_surface") == sum(_count(layered, f"fat_{n}") for n in fat_faces)
    for m in "ab":  # lateral = flat + round; the fat's cavity is the round part
        assert _count(layered, f"{m}_lateral") == _count(layered, f"{m}_flat") + _count(layered, f"{m}_round")
        assert _count(layered, f"{m}_round") == _count(layered, f"fat_cavity_{m}")
    # the fat's nodes on the planes x = -+g/2 are the flat faces' rims (twins of a_round's / b_round's nodes)
    fat = np.unique(layered.facets[layered.facet_tags == layered.boundary_names["fat_surface"]])
    for m, sign in (("a", -1.0), ("b", 1.0)):
        on_plane = fat[np.abs(P[fat, 0] - sign * 0.5 * GAP) < 1e-12]
        rim = np.intersect1d(_nodes(layered, f"{m}_flat"), _nodes(layered, f"{m}_round"))
        keys = {tuple(np.round(p / GAP, 6)) for p in P[rim]}
        assert len(on_plane) > 0 and {tuple(np.round(p / GAP, 6)) for p in P[on_plane]} <= keys


def test_bad_gap() -> None:
    with pytest.raises(ParameterError, match="layered_arm: gap must be a finite number >= 0, got -0.001"):
        generate("layered_arm", touching=True, spacing=0.019, gap=-0.001)
    with pytest.raises(ParameterError, match="layered_arm: gap must be a finite number >= 0, got True"):
        generate("layered_arm", touching=True, spacing=0.019, gap=True)
    with pytest.raises(ParameterError, match="layered_arm: gap .* needs touching = true"):
        generate("layered_arm", gap=0.001)
    with pytest.raises(ParameterError, match=r"layered_arm: gap must be < spacing - 2 \* tendon_radius"):
        generate("layered_arm", touching=True, spacing=0.019, gap=0.012)
    raw = gap_raw(0.012)
    with pytest.raises(ConfigError, match=r"^mesh.gap: layered_arm: gap must be < spacing - 2 \* tendon_radius"):
        load_mesh_data(parse(raw).mesh)


@pytest.fixture(scope="module")
def run() -> ArmResult:
    return run_gap(GAP, STEPS)


def test_the_gap_closes(run: ArmResult) -> None:
    """At rest the faces are g apart (the smallest gap is g: parallel planes); at half the activation still open
    (measured 40 um: no force, no active node); at full activation closed: the contact carries force (measured
    2.22 N on 40 nodes) along -x (b pushes a along the faces' normal) with a penetration of the penalty's p/k
    (0.49 um at k = 1e11, below 1 % of the gap). Newton 14 + 16 iterations (the lagged sliding pairs)."""
    assert run.completed and len(run.newton_iterations) == STEPS and max(run.newton_iterations) <= 30
    rest, half, full = run.history
    assert [h["load_factor"] for h in run.history] == pytest.approx([0.0, 0.5, 1.0])
    assert rest["min_gap"] == pytest.approx(GAP, rel=1e-9)
    for h in (rest, half):
        assert h["active_points"] == 0 and h["max_penetration"] == 0.0
        assert h["normal_force"] == 0.0 and np.linalg.norm(h["force"]) == 0.0
    assert 0.1 * GAP < half["min_gap"] < 0.9 * GAP
    contact = run.pairs["a_on_b"]
    assert contact["pair"] == "a_flat-b_flat" and full["normal_force"] == contact["normal_force"]
    assert contact["active_points"] >= 3
    assert contact["normal_force"] > 0.5  # N
    force = np.asarray(contact["force"])
    assert force[0] < 0.0 and abs(force[0]) > 0.99 * np.linalg.norm(force)
    assert abs(force[0]) == pytest.approx(contact["normal_force"], rel=1e-2)
    assert 0.0 < contact["max_penetration"] < 0.01 * GAP
    assert run.muscle_gap == pytest.approx(-contact["max_penetration"], rel=1e-12)
    assert contact["max_gap"] < half["max_gap"] < rest["max_gap"]  # the faces approach everywhere
    for m in "ab":  # the fat slides on both muscles as in the touching arm
        pair = run.pairs[f"fat_on_{m}"]
        assert max(pair["max_gap"], pair["max_penetration"]) < 0.1 * run.bulge_max
        assert run.slip[m]["max"] > 20.0 * max(pair["max_gap"], pair["max_penetration"])
    assert MPI.COMM_WORLD.allreduce(contact["normal_force"], op=MPI.MAX) == contact["normal_force"]


def test_action_equals_reaction(run: ArmResult) -> None:
    """Each body is in equilibrium under its clamps' reactions and its pairs' forces, with the force on b from a
    taken as minus the reported force on a from b (and the force on a muscle from the fat as minus the force on the
    fat): the residual is below 0.1 % of the contact force (measured 4.4e-4 N of 2.2 N)."""
    scale = run.pairs["a_on_b"]["normal_force"]
    for body, residual in body_balance(run).items():
        assert np.linalg.norm(residual) < 1e-3 * scale, (body, residual)


@pytest.mark.slow
def test_the_penetration_shrinks_as_one_over_k(run: ArmResult) -> None:
    """Ten times the penalty (k = 1e12): the same contact force (measured 2.2293 N against 2.2228 N: the penalty's
    give no longer counts against a 0.15 mm gap) on the same nodes, and a tenth of the penetration (0.0521 um
    against 0.4856 um, ratio 9.3: p / k). About 40 s more."""
    stiff = run_gap(GAP, STEPS, k_contact=1e12)
    soft, hard = run.pairs["a_on_b"], stiff.pairs["a_on_b"]
    assert stiff.completed and abs(hard["active_points"] - soft["active_points"]) <= 2  # measured: the same 40
    assert hard["normal_force"] == pytest.approx(soft["normal_force"], rel=0.02)
    assert soft["max_penetration"] / hard["max_penetration"] == pytest.approx(10.0, rel=0.15)
