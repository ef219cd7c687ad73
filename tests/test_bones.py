"""Bones (model.problem.bones, forms.motions): rigid motions against time, attachments, sliding on moving obstacles.

Rotations are checked against scipy.spatial.transform (an independent implementation of
Rodrigues' formula and of slerp); attachments and sliding against closed forms:
a body attached on its whole boundary moves rigidly with zero strain energy, a face held on
a moving plane follows it normally (uniaxial closed form, both signs) and ignores its
tangential motion, a cylinder held on a coaxial capsule translates with it and ignores its
rotation about, and its sliding along, its own axis.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from closed_form import principal_stress
from mpi4py import MPI
from scipy.optimize import brentq
from scipy.spatial.transform import Rotation, Slerp

import forms
import meshes
from forms.motions import Bone, HingeMotion, Stationary, TransformTable, axis_angle, rotation_log, rotation_matrix
from forms.obstacles import Capsule, Plane
from model.domain import build_domain
from model.problem import ElasticityProblem
from model.problem.bones import add_sliding, attach
from model.solvers.loadstepping import step_loads
from model.solvers.newton import NewtonSolver

LAW = {"E": 1.0e4, "nu": 0.3}


def box_problem(cells: int = 2, degree: int = 1) -> ElasticityProblem:
    comm = MPI.COMM_WORLD
    data = meshes.box((1.0, 1.0, 1.0), (cells, cells, cells)) if comm.rank == 0 else None
    law = forms.make_law("neo_hookean", **LAW)
    return ElasticityProblem(build_domain(comm, data), [("all", law)], degree, 2 * degree)


def nodal_displacements(problem: ElasticityProblem) -> tuple[np.ndarray, np.ndarray]:
    """(X, u) at the owned nodes of the displacement space (rows)."""
    owned = problem.space.dofmap.index_map.size_local
    X = problem.space.tabulate_dof_coordinates()[:owned]
    u = problem.solution.x.array.reshape(-1, 3)[:owned]
    return X, u


def max_all(value: float) -> float:
    return MPI.COMM_WORLD.allreduce(float(value), op=MPI.MAX)


# --- rotations and motions ------------------------------------------------------------------------

def test_rotation_matrix_and_log_agree_with_scipy() -> None:
    rng = np.random.default_rng(3)
    axes = rng.normal(size=(8, 3))
    axes /= np.linalg.norm(axes, axis=1)[:, None]
    for axis in axes:
        for theta in (0.0, 1e-9, 1e-4, 0.7, math.pi / 2, 2.5, math.pi - 1e-7, math.pi):
            w = theta * axis
            Q = rotation_matrix(w)
            np.testing.assert_allclose(Q, Rotation.from_rotvec(w).as_matrix(), atol=1e-14)
            back = rotation_log(Q)
            if theta < math.pi:
                np.testing.assert_allclose(back, w, atol=2e-9 if theta > math.pi - 1e-6 else 1e-12)
            else:  # at pi, w and -w are the same rotation
                np.testing.assert_allclose(rotation_matrix(back), Q, atol=1e-12)
    np.testing.assert_allclose(axis_angle((0, 0, 2), 90.0) @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)


def test_transform_table_slerps_like_scipy() -> None:
    rng = np.random.default_rng(5)
    keys = Rotation.random(3, random_state=7)
    times = [0.0, 0.4, 1.0]
    translations = rng.normal(size=(3, 3))
    as_matrices = TransformTable(times, list(keys.as_matrix()), translations.tolist())
    as_vectors = TransformTable(times, list(keys.as_rotvec()), translations.tolist())
    slerp = Slerp(times, keys)
    for t in (0.0, 0.1, 0.4, 0.55, 0.9, 1.0):
        for table in (as_matrices, as_vectors):
            Q, c = table(t)
            np.testing.assert_allclose(Q, slerp([t]).as_matrix()[0], atol=1e-12)
            np.testing.assert_allclose(c, [np.interp(t, times, translations[:, i]) for i in range(3)], atol=1e-14)
    for t, i in ((-1.0, 0), (2.0, 2)):  # held beyond the ends
        Q, c = as_matrices(t)
        np.testing.assert_allclose(Q, keys[i].as_matrix(), atol=1e-12)
        np.testing.assert_allclose(c, translations[i])
    with pytest.raises(ValueError, match=r"times\[1\]"):
        TransformTable([0.0, 0.0], [[0, 0, 0]] * 2, [[0, 0, 0]] * 2)
    with pytest.raises(ValueError, match=r"rotations\[1\]"):
        TransformTable([0.0, 1.0], [np.eye(3), 2 * np.eye(3)], [[0, 0, 0]] * 2)


def test_hinge_motion_is_piecewise_linear_about_a_fixed_axis() -> None:
    hinge = HingeMotion((0.0, 0.0, 1.0), (1.0, 2.0, 0.0), [(0.0, 0.0), (0.5, 30.0), (1.0, 90.0)])
    for t, degrees in ((-1.0, 0.0), (0.25, 15.0), (0.5, 30.0), (0.75, 60.0), (1.0, 90.0), (3.0, 90.0)):
        Q, c = hinge(t)
        np.testing.assert_allclose(Q, Rotation.from_euler("z", degrees, degrees=True).as_matrix(), atol=1e-14)
        np.testing.assert_allclose(Q @ [1.0, 2.0, 5.0] + c, [1.0, 2.0, 5.0], atol=1e-14)  # axis points stay
    Q, c = hinge(1.0)
    np.testing.assert_allclose(Q @ [2.0, 2.0, 0.0] + c, [1.0, 3.0, 0.0], atol=1e-14)
    with pytest.raises(ValueError, match="axis"):
        HingeMotion((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), [(0.0, 0.0)])
    bone = Bone("humerus", hinge)
    np.testing.assert_allclose(bone.transform(0.5)[0], hinge(0.5)[0])
    np.testing.assert_allclose(Stationary()(0.3)[0], np.eye(3))


# --- attachments ----------------------------------------------------------------------------------

MOTIONS = {
    "hinge_90": HingeMotion((1.0, 1.0, 0.0), (0.5, 0.0, 0.0), [(0.0, 0.0), (1.0, 90.0)]),
    "transform_table": TransformTable([0.0, 0.5, 1.0], [[0.0, 0.0, 0.0], [0.0, 0.8, 0.0], [1.2, 0.4, -0.6]],
                                      [[0.0, 0.0, 0.0], [0.3, -0.2, 0.5], [1.0, 0.5, -0.4]]),
}


@pytest.mark.parametrize("degree", [1, 2])
@pytest.mark.parametrize("name", sorted(MOTIONS))
def test_attached_body_moves_rigidly(name: str, degree: int) -> None:
    """All six faces attached to a moving bone: the interior follows, u = Q X + c - X, zero strain energy."""
    motion = MOTIONS[name]
    problem = box_problem(2, degree)
    for face in ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax"):
        attach(problem, face, Bone("bone", motion))
    solver = NewtonSolver(problem)
    checked = []

    def check(record) -> None:  # noqa: ANN001 - a StepRecord
        assert record.result.converged
        Q, c = motion(record.load_factor)
        X, u = nodal_displacements(problem)
        assert max_all(np.abs(u - (X @ Q.T + c - X)).max(initial=0.0)) < 1e-10
        assert abs(problem.total_energy()) < 1e-10
        checked.append(record.load_factor)

    assert step_loads(solver, 4, on_step=check)
    assert len(checked) == 4
    solver.destroy()


# --- sliding --------------------------------------------------------------------------------------

def uniaxial_stretches(l3: float) -> tuple[float, float]:
    """(lt, P33) of uniaxial stress at axial stretch l3 (lateral faces free)."""
    lt = brentq(lambda lt: principal_stress("neo_hookean", np.array([lt, lt, l3]), LAW)[0], 0.5, 2.0, xtol=1e-15)
    return lt, float(principal_stress("neo_hookean", np.array([lt, lt, l3]), LAW)[2])


@pytest.mark.parametrize("delta", [0.05, -0.05], ids=["pushed", "pulled"])
def test_face_slides_on_a_moving_plane(delta: float) -> None:
    """zmin held on the plane z = 0 by (k/2) g^2 (zmax at u_z = 0, sliders on xmin, ymin); the plane moves
    by delta along its normal, by (0.3, -0.2) along itself and turns 30 degrees about its normal.

    Closed form: uniaxial stress, -P33(l3) = k (delta - w), w = 1 - l3 the face's lift, on both sides
    (pushed and pulled); the lateral stretch is that of uniaxial stress whatever the tangential motion.
    """
    k = 1.0e6
    problem = box_problem(2, 1)
    problem.add_dirichlet("xmin", [0], [0.0])
    problem.add_dirichlet("ymin", [1], [0.0])
    problem.add_dirichlet("zmax", [2], [0.0])
    motion = TransformTable([0.0, 1.0], [[0.0, 0.0, 0.0], [0.0, 0.0, math.radians(30.0)]],
                            [[0.0, 0.0, 0.0], [0.3, -0.2, delta]])
    sliding = add_sliding(problem, "zmin", Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)), k, motion)
    solver = NewtonSolver(problem)
    assert step_loads(solver, 2)
    low, high = sorted((1.0 - delta, 1.0))
    l3 = brentq(lambda l3: -uniaxial_stretches(l3)[1] - k * (delta - 1.0 + l3), low, high, xtol=1e-15)
    lt, _ = uniaxial_stretches(l3)
    X, u = nodal_displacements(problem)
    expected = np.column_stack([(lt - 1.0) * X[:, 0], (lt - 1.0) * X[:, 1], (l3 - 1.0) * (X[:, 2] - 1.0)])
    assert max_all(np.abs(u - expected).max(initial=0.0)) < 1e-9
    force = sliding.force()
    np.testing.assert_allclose(force[2], k * (delta - 1.0 + l3), rtol=1e-7)
    np.testing.assert_allclose(force[:2], [0.0, 0.0], atol=1e-9 * abs(force[2]))
    np.testing.assert_allclose(sliding.max_gap(), abs(force[2]) / k, rtol=1e-6)
    solver.destroy()


def test_cylinder_slides_on_a_moving_capsule() -> None:
    """A cylinder's lateral surface held on a coaxial capsule (vertex quadrature, k = 1e6). The capsule
    moves by 0.2 across its axis, slides 0.5 along it and turns 60 degrees about it: the cylinder
    translates by (0.2, 0, 0) only, with zero strain energy. Its bottom slides along x (u_y = u_z = 0):
    that fixes the free axial translation and rotation and does not resist the expected motion, while
    a surface dragged along by the capsule's rotation or axial slide would strain the body."""
    comm = MPI.COMM_WORLD
    radius, length = 0.5, 1.0
    data = meshes.cylinder(radius=radius, length=length, size=0.25) if comm.rank == 0 else None
    law = forms.make_law("neo_hookean", **LAW)
    problem = ElasticityProblem(build_domain(comm, data), [("all", law)], 1, 2)
    problem.add_dirichlet("bottom", [1, 2], [0.0, 0.0])  # a slider along x: fixes the free modes, allows (0.2, 0, 0)
    capsule = Capsule((0.0, 0.0, -1.0), (0.0, 0.0, 2.0), radius)
    motion = TransformTable([0.0, 1.0], [[0.0, 0.0, 0.0], [0.0, 0.0, math.radians(60.0)]],
                            [[0.0, 0.0, 0.0], [0.2, 0.0, 0.5]])
    sliding = add_sliding(problem, "lateral", Bone("radius", motion, capsule), 1.0e6, quadrature_degree="vertex")
    assert sliding.max_gap() < 1e-12  # the mesh vertices lie on the capsule
    solver = NewtonSolver(problem)
    assert step_loads(solver, 2)
    X, u = nodal_displacements(problem)
    assert max_all(np.abs(u - [0.2, 0.0, 0.0]).max(initial=0.0)) < 1e-9
    assert abs(problem.total_energy()) < 1e-10
    # |R| <= snes_rtol |R_0| = 1e-10 * 2e4 lets the penalty (k = 1e6) hold a gap of ~1e-11
    assert sliding.max_gap() < 1e-11
    solver.destroy()


def test_errors_name_what_is_wrong() -> None:
    problem = box_problem(1, 1)
    with pytest.raises(ValueError, match="surface"):
        attach(problem, "floor", Stationary())
    with pytest.raises(ValueError, match="k"):
        add_sliding(problem, "zmin", Plane((0, 0, 0), (0, 0, 1)), 0.0)
    with pytest.raises(ValueError, match="vertex"):
        add_sliding(box_problem(1, 2), "zmin", Plane((0, 0, 0), (0, 0, 1)), 1.0, quadrature_degree="vertex")
    with pytest.raises(ValueError, match="no obstacle"):
        add_sliding(problem, "zmin", Bone("femur"), 1.0)
