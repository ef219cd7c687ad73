"""Biharmonic weights (model.fields.biharmonic; issue 13 item 5): the mixed two-field form, and the bounded
variant by TAO. Partition of unity to 1e-12, w_j(handle k) = delta_jk, bounded weights in [0, 1]; the mixed
solve is the minimiser of 1/2 w^T K M^-1 K w (checked against Q = K M^-1 K assembled on its own), and where
the bounds are inactive TAO finds the same weights."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ROOT, environment, serial_only
from dolfinx import mesh as dmesh
from mpi4py import MPI

from model import compat
from model.fields.biharmonic import (
    _locate,
    biharmonic_weights,
    bilaplacian,
    bounded_biharmonic_weights,
    handle_at_point,
)

POINTS = [(0.1, 0.1), (0.9, 0.2), (0.5, 0.9), (0.2, 0.7)]


def square(n: int = 16):
    return dmesh.create_unit_square(MPI.COMM_WORLD, n, n)


def faces(msh, *planes: tuple[int, float]):
    """Handles: the boundary facets on the planes x_axis = value."""
    fdim = msh.topology.dim - 1
    return [(fdim, dmesh.locate_entities_boundary(msh, fdim, lambda x, a=axis, v=value: np.isclose(x[a], v)))
            for axis, value in planes]


def check_weights(weights, handles, tol: float = 1e-12) -> None:
    total = sum(w.x.array for w in weights)
    assert np.max(np.abs(total - 1.0), initial=0.0) < tol  # partition of unity (owned and ghost nodes)
    V = weights[0].function_space
    for k, handle in enumerate(handles):
        dofs = _locate(V, handle)
        for j, w in enumerate(weights):
            assert np.all(w.x.array[dofs] == (1.0 if j == k else 0.0)), (j, k)


def test_point_handles_in_2d() -> None:
    msh = square()
    handles = [handle_at_point(msh, p) for p in POINTS]
    weights = biharmonic_weights(msh, handles)
    check_weights(weights, handles)
    # the unbounded weights of point handles overshoot: the reason for the bounded variant
    assert MPI.COMM_WORLD.allreduce(min(w.x.array.min() for w in weights), op=MPI.MIN) < -0.1


def test_the_mixed_form_minimises_the_bilaplacian_energy() -> None:
    """(Q w)_i = 0 at every node off the handles, Q = K M^-1 K assembled directly (not from the mixed form)."""
    msh = square(12)
    handles = [handle_at_point(msh, p) for p in POINTS]
    weights = biharmonic_weights(msh, handles)
    V = weights[0].function_space
    Q = bilaplacian(V)
    fixed = np.concatenate([_locate(V, h) for h in handles])
    owned = V.dofmap.index_map.size_local
    for w in weights:
        x = compat.petsc_vector(w)
        y = x.duplicate()
        Q.mult(x, y)
        free = np.setdiff1d(np.arange(owned), fixed)
        scale = Q.norm() * x.norm()
        worst = MPI.COMM_WORLD.allreduce(float(np.max(np.abs(y.array_r[free]), initial=0.0)), op=MPI.MAX)
        assert worst < 1e-12 * scale
        y.destroy()
    Q.destroy()


@pytest.mark.parametrize("n", [5, 6, 7])
def test_region_handles_in_3d(n: int) -> None:
    """Face handles whose dof lists end in ghost dofs on some rank (on 2 ranks, depending on the partition): the
    Dirichlet dofs must be handed to dolfinx sorted (before, a zero row in about half the two-rank runs)."""
    msh = dmesh.create_unit_cube(MPI.COMM_WORLD, n, n, n)
    handles = [*faces(msh, (0, 0.0), (0, 1.0)), handle_at_point(msh, (0.5, 0.5, 0.5))]
    check_weights(biharmonic_weights(msh, handles), handles)


def test_bounded_weights_stay_in_the_unit_interval() -> None:
    msh = square()
    handles = [handle_at_point(msh, p) for p in POINTS]
    weights, reports = bounded_biharmonic_weights(msh, handles)
    check_weights(weights, handles)
    low = MPI.COMM_WORLD.allreduce(min(w.x.array.min() for w in weights), op=MPI.MIN)
    high = MPI.COMM_WORLD.allreduce(max(w.x.array.max() for w in weights), op=MPI.MAX)
    assert low >= 0.0 and high <= 1.0
    assert all(r["reason"] > 0 for r in reports), reports


def test_bounded_equals_unbounded_where_the_bounds_are_inactive() -> None:
    """Two opposite faces of a square: the unbounded weights already lie in [0, 1]; TAO (TRON) finds them."""
    msh = square(10)
    handles = faces(msh, (0, 0.0), (0, 1.0))
    free = biharmonic_weights(msh, handles)
    assert all(w.x.array.min() >= -1e-12 and w.x.array.max() <= 1 + 1e-12 for w in free)
    bounded, _ = bounded_biharmonic_weights(msh, handles)
    for a, b in zip(free, bounded):
        assert np.max(np.abs(a.x.array - b.x.array)) < 1e-8


def test_bad_handles() -> None:
    msh = square(4)
    with pytest.raises(ValueError, match="at least two"):
        biharmonic_weights(msh, [handle_at_point(msh, (0, 0))])
    with pytest.raises(ValueError, match=r"handles\[1\] and handles\[0\] share nodes"):
        biharmonic_weights(msh, [handle_at_point(msh, (0, 0)), handle_at_point(msh, (0.01, 0.0))])
    with pytest.raises(ValueError, match=r"handles\[1\]: no node"):
        biharmonic_weights(msh, [handle_at_point(msh, (0, 0)), (0, np.empty(0, dtype=np.int32))])


@serial_only
def test_example_script() -> None:
    import re
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "examples/biharmonic_weights.py", "--cells", "12"], cwd=ROOT,
                          env=environment(), capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    ranges = re.findall(r"weights in \[(\S+), (\S+)\], \|sum - 1\| <= (\S+),", proc.stdout)
    assert len(ranges) == 2, proc.stdout
    (low_u, _, unity_u), (low_b, high_b, unity_b) = [tuple(map(float, r)) for r in ranges]
    assert low_u < 0 <= low_b and high_b <= 1 and max(unity_u, unity_b) < 1e-12
