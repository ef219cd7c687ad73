"""A form compiled with a cold JIT cache must not change the test functions made afterwards (compat.create_mesh).

FFCx 0.5 sets the equispaced variant on a mesh's coordinate element, in place, when it compiles a form of the mesh
that is not in its cache; that changed the repr (the hash) of every Argument made after it, and a form with test
functions made before and after such a compile failed with "Found different Arguments with same number and part"
(seen in CI with a cold cache: contact, membranes, the contact notebook). Collective: serially and on 2 ranks."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from model import compat


def test_a_cold_compile_leaves_later_test_functions_equal(tmp_path: Path) -> None:
    comm = MPI.COMM_WORLD
    cells = np.array([[0, 1, 2, 3]], dtype=np.int64) if comm.rank == 0 else np.empty((0, 4), dtype=np.int64)
    points = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]) if comm.rank == 0 \
        else np.empty((0, 3))
    msh = compat.create_mesh(comm, cells, points)
    space = compat.function_space(msh, compat.element("Lagrange", compat.cell_name(msh), 1, (3,)))
    before = ufl.TestFunction(space)
    cache = Path(comm.bcast(str(tmp_path) if comm.rank == 0 else None)) / "jit"  # cold: FFCx analyses the form
    options = {"jit_params" if compat.LEGACY else "jit_options": {"cache_dir": str(cache)}}
    fem.form(ufl.inner(before, ufl.as_vector([1.0, 2.0, 3.0])) * ufl.dx(domain=msh), **options)
    after = ufl.TestFunction(space)
    assert before == after and hash(before) == hash(after)
    both = ufl.inner(before, ufl.as_vector([1.0, 0.0, 0.0])) * ufl.dx(domain=msh) \
        + ufl.inner(after, ufl.as_vector([0.0, 1.0, 0.0])) * ufl.ds(domain=msh)
    fem.form(both, **options)  # raised the UFL error before the fix
