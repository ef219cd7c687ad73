"""Fibre fields: constant, Laplace-computed (a straight cylinder gives its axis), per-cell arrays."""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

import meshes
from model import compat
from model.domain import build_domain
from model.fields.fibres import FibreField, unit_vectors


def domain_of(data):
    comm = MPI.COMM_WORLD
    return build_domain(comm, data if comm.rank == 0 else None)


def owned_values(field: FibreField) -> np.ndarray:
    dofs = compat.cell_dofs(field.function.function_space.dofmap).reshape(-1)
    return field.function.x.array.reshape(-1, 3)[dofs[field.cells]]


def test_laplace_fibres_of_a_straight_cylinder_are_its_axis() -> None:
    domain = domain_of(meshes.cylinder(radius=0.3, length=2.0, size=0.3))
    field = FibreField(domain).laplace("bottom", "top")
    np.testing.assert_allclose(owned_values(field), np.tile([0.0, 0.0, 1.0], (len(field.cells), 1)), atol=1e-10)


def test_laplace_on_a_region_of_the_fusiform_muscle() -> None:
    domain = domain_of(meshes.fusiform(size=0.006))
    field = FibreField(domain, "tendon_origin").laplace("origin", "insertion", region="all")
    a0 = owned_values(field)
    assert np.all(a0[:, 2] > 0.95)  # along the muscle's axis in the straight tendon
    np.testing.assert_allclose(np.linalg.norm(a0, axis=1), 1.0, atol=1e-12)


def test_constant_and_per_cell_fibres() -> None:
    data = meshes.box(cells=(2, 2, 2))
    domain = domain_of(data)
    field = FibreField(domain).constant([0, 0, 0], [1.0, 2.0, 2.0])
    np.testing.assert_allclose(owned_values(field), np.tile([1 / 3, 2 / 3, 2 / 3], (len(field.cells), 1)))
    centroids = data.points[data.cells].mean(axis=1)
    FibreField(domain).from_cell_array(centroids + 1.0)  # any non-zero per-cell directions
    per_cell = FibreField(domain).from_cell_array(centroids + 1.0)
    from dolfinx import mesh as dmesh

    mid = dmesh.compute_midpoints(domain.mesh, 3, per_cell.cells)
    np.testing.assert_allclose(owned_values(per_cell), unit_vectors(mid + 1.0), atol=1e-12)
    with pytest.raises(ValueError, match="zero"):
        FibreField(domain).constant([0, 0, 0], [0, 0, 0])


@pytest.fixture(scope="module")
def arm_domain():
    return domain_of(meshes.arm_segment(size=0.008))


@pytest.mark.parametrize("regions", [("belly_a", "tendon_a"), ("belly_b", "tendon_b"), ("fat",)])
def test_region_dofs_include_the_nodes_a_region_touches_on_other_ranks(arm_domain, regions: tuple[str, ...]) -> None:
    """A node on the border between ranks may touch cells of the region on the other rank only; it is still
    a node of the region (else the Laplace solve pins it to 0 and bends the fibres around it: on 2 ranks the
    two-muscle arm segment's muscle a thickened half as much in some partitions). Reference: the global
    numbers of every rank's region-cell nodes, gathered."""
    from model.fields.fibres import region_dofs

    domain = arm_domain
    V = compat.function_space(domain.mesh, "Lagrange", 1)
    imap = V.dofmap.index_map
    cells = np.concatenate([domain.region_cells(n) for n in regions])
    mine = imap.local_to_global(np.unique(compat.cell_dofs(V.dofmap)[cells]).astype(np.int32))
    touched = np.unique(np.concatenate(MPI.COMM_WORLD.allgather(mine)))
    local = np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32)
    expected = local[np.isin(imap.local_to_global(local), touched)]
    np.testing.assert_array_equal(region_dofs(V, domain, regions), expected)
