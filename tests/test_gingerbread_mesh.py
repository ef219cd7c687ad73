"""The gingerbread-man triangle mesh (meshes.gingerbread): positive areas, non-empty handle regions, the same
area distributed over any number of ranks."""

from __future__ import annotations

import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI

from meshes._validate import ParameterError
from meshes.gingerbread import GINGERBREAD_HANDLES, GINGERBREAD_REGIONS, gingerbread, triangle_areas
from model.domain.distribute import build_domain


def _assemble(form: ufl.Form, comm: MPI.Comm) -> float:
    return comm.allreduce(fem.assemble_scalar(fem.form(form)), op=MPI.SUM)


def test_gingerbread_areas_and_regions() -> None:
    data = gingerbread(size=0.1)
    body = data.region_cells("body")
    areas = triangle_areas(data.points, body)
    assert areas.min() > 0.0
    assert 1.0 < areas.sum() < 2.5  # about 2 tall, 1.8 wide, with thin limbs
    ys, xs = data.points[:, 1], data.points[:, 0]
    assert ys.min() == pytest.approx(0.0, abs=0.02) and ys.max() == pytest.approx(2.0, abs=0.02)  # chords of discs
    assert xs.min() == pytest.approx(-1.07, abs=0.02) and xs.max() == pytest.approx(1.07, abs=0.02)
    body_keys = {tuple(sorted(c)) for c in body.tolist()}
    total = 0.0
    for name, (x0, y0, x1, y1) in GINGERBREAD_HANDLES.items():
        cells = data.region_cells(name)
        assert len(cells) >= 3, name
        assert {tuple(sorted(c)) for c in cells.tolist()} <= body_keys, name
        centres = data.points[cells].mean(axis=1)
        assert np.all((centres[:, 0] > x0) & (centres[:, 0] < x1) & (centres[:, 1] > y0) & (centres[:, 1] < y1))
        total += data.area(name)
    assert total < 0.25 * data.area()
    assert len(data.facets) > 0 and set(data.facets.ravel()) <= set(body.ravel())
    with pytest.raises(ParameterError, match="size"):
        gingerbread(size=0.0)


def test_gingerbread_distributed_area_is_the_same_on_any_ranks() -> None:
    comm = MPI.COMM_WORLD
    data = gingerbread(size=0.1) if comm.rank == 0 else None
    expected = comm.bcast({n: data.area(n) for n in GINGERBREAD_REGIONS} if data is not None else None, root=0)
    length = comm.bcast(float(np.linalg.norm(np.diff(data.points[data.facets], axis=1), axis=2).sum())
                        if data is not None else None, root=0)
    domain = build_domain(comm, data)
    assert domain.mesh.geometry.dim == 2 and domain.mesh.topology.dim == 2
    dx = ufl.Measure("dx", domain=domain.mesh, subdomain_data=domain.cell_tags, metadata={"quadrature_degree": 0})
    ds = ufl.Measure("ds", domain=domain.mesh, subdomain_data=domain.facet_tags, metadata={"quadrature_degree": 0})
    one = fem.Constant(domain.mesh, 1.0)
    for name in GINGERBREAD_REGIONS:
        area = _assemble(one * dx(domain.regions[name]), comm)
        assert area == pytest.approx(expected[name], rel=1e-12), name
    assert _assemble(one * dx, comm) == pytest.approx(expected["body"], rel=1e-12)
    assert _assemble(one * ds(domain.boundaries["outline"]), comm) == pytest.approx(length, rel=1e-12)
    assert _assemble(one * ds, comm) == pytest.approx(length, rel=1e-12)
