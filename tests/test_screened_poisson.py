"""The screened Poisson problem -lap u + alpha u = f (zero flux), standard and mixed (KKT), 2D and 3D
(model.problem.screened_poisson, forms.poisson; issue 13 item 1).

Manufactured solution u = cos(pi x) cos(pi y) [cos(pi z)] on the unit square [cube]: its normal derivative
vanishes on the boundary (the natural condition) and f = (d pi^2 + alpha) u.
"""

from __future__ import annotations

import numpy as np
import pytest
import ufl
from conftest import ROOT, environment, serial_only
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from model.problem.screened_poisson import l2_h1_errors, solve_screened_poisson

ALPHA = 2.0


def exact(x, dim: int):
    u = ufl.cos(ufl.pi * x[0]) * ufl.cos(ufl.pi * x[1])
    return u * ufl.cos(ufl.pi * x[2]) if dim == 3 else u


def unit(dim: int, n: int):
    comm = MPI.COMM_WORLD
    return dmesh.create_unit_square(comm, n, n) if dim == 2 else dmesh.create_unit_cube(comm, n, n, n)


def source(dim: int):
    return lambda x: (dim * ufl.pi**2 + ALPHA) * exact(x, dim)


def l2(expr, msh) -> float:
    value = fem.assemble_scalar(fem.form(expr * expr * ufl.dx(domain=msh, metadata={"quadrature_degree": 6})))
    return float(np.sqrt(msh.comm.allreduce(value, op=MPI.SUM)))


@pytest.mark.parametrize(("dim", "degree", "n"), [(2, 1, 12), (2, 2, 6), (3, 1, 4), (3, 2, 2)])
def test_mixed_and_standard_give_the_same_u(dim: int, degree: int, n: int) -> None:
    msh = unit(dim, n)
    standard = solve_screened_poisson(msh, ALPHA, source(dim), degree, "standard")
    mixed = solve_screened_poisson(msh, ALPHA, source(dim), degree, "mixed")
    assert mixed.dofs > standard.dofs  # g and lambda are unknowns of their own
    assert l2(standard.u - mixed.u, msh) < 1e-10 * l2(standard.u, msh)
    # the mixed form's g is grad u, and its multiplier lambda equals g (dL/dg = g - lambda = 0)
    assert l2(ufl.sqrt(ufl.inner(mixed.g - ufl.grad(mixed.u), mixed.g - ufl.grad(mixed.u))), msh) < 1e-10
    assert l2(ufl.sqrt(ufl.inner(mixed.g - mixed.multiplier, mixed.g - mixed.multiplier)), msh) < 1e-10
    assert standard.residual < 1e-12 and mixed.residual < 1e-12


@pytest.mark.parametrize(("dim", "degree", "sizes"), [(2, 1, (16, 32)), (2, 2, (8, 16)), (3, 1, (8, 16)),
                                                      (3, 2, (6, 12))])
def test_manufactured_solution_converges_at_the_expected_rates(dim: int, degree: int, sizes: tuple[int, int]) -> None:
    errors = [l2_h1_errors(solve_screened_poisson(unit(dim, n), ALPHA, source(dim), degree).u,
                           lambda x: exact(x, dim)) for n in sizes]
    (l2_c, h1_c), (l2_f, h1_f) = errors
    rates = np.log2(l2_c / l2_f), np.log2(h1_c / h1_f)
    assert abs(rates[0] - (degree + 1)) < 0.1, (errors, rates)
    assert abs(rates[1] - degree) < 0.1, (errors, rates)


def test_mixed_converges_too() -> None:
    """The mixed solve's u at the P1 rates in 2D (it is the standard u; checked on its own)."""
    errors = [l2_h1_errors(solve_screened_poisson(unit(2, n), ALPHA, source(2), 1, "mixed").u,
                           lambda x: exact(x, 2)) for n in (16, 32)]
    assert abs(np.log2(errors[0][0] / errors[1][0]) - 2.0) < 0.1
    assert abs(np.log2(errors[0][1] / errors[1][1]) - 1.0) < 0.1


def test_bad_input() -> None:
    msh = unit(2, 2)
    with pytest.raises(ValueError, match="formulation: 'kkt'"):
        solve_screened_poisson(msh, ALPHA, 1.0, 1, "kkt")
    with pytest.raises(ValueError, match="alpha: 0.0 must be > 0"):
        solve_screened_poisson(msh, 0.0, 1.0)
    with pytest.raises(ValueError, match="degree: 0"):
        solve_screened_poisson(msh, ALPHA, 1.0, 0)


def test_constant_source_gives_the_constant_solution() -> None:
    """f constant: u = f / alpha exactly (zero flux), both forms, 2D and 3D."""
    for dim in (2, 3):
        for formulation in ("standard", "mixed"):
            u = solve_screened_poisson(unit(dim, 3), ALPHA, 3.0, 1, formulation).u
            assert np.allclose(u.x.array, 1.5, atol=1e-12, rtol=0)


@serial_only
def test_example_script() -> None:
    """examples/screened_poisson.py: both forms in 2D and 3D, the same u, the printed errors."""
    import re
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "examples/screened_poisson.py", "--cells", "8", "--degree", "2"], cwd=ROOT,
                          env=environment(), capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = [line for line in proc.stdout.splitlines() if "unknowns" in line]
    assert [line[:6] for line in lines] == ["2D, P2", "3D, P2"]
    for line in lines:
        difference = float(re.search(r"u_mixed\|\|_L2 = (\S+);", line).group(1))
        assert difference < 1e-10, line
