"""The muscle and tendon forms as now written (forms.muscle) against the earlier forms.

The fibre energies used to be nested UFL conditionals of s = lbar / l_ofl with lbar = sqrt(a0 . Cbar a0).
They are now sums chi_i(s) piece_i(s) of 0/1 indicators of the scalar invariants (lbar = J^(-1/3) |F a0|),
with the stress through the invariants: cheaper to compile and to assemble, the same function. ``Old*``
below is a frozen copy of the earlier expressions, written here (not a stored number file); psi, P and A
of both, evaluated by dolfinx at the same F, agree to 1e-12. The samples put the fibre stretch in every
piece of the curves (and on break points) and add the verify tool's deformation samples.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI

import forms
from forms.kinematics import right_cauchy_green
from forms.muscle import Muscle, Tendon
from model import compat
from model.verify import deformation_samples

# --- the earlier expressions, frozen -------------------------------------------------------------------------------

def _old_piecewise(x: Any, breaks: list[float], pieces: list[Any]) -> Any:
    out = pieces[-1]
    for b, piece in zip(reversed(breaks), reversed(pieces[:-1])):
        out = ufl.conditional(ufl.le(x, b), piece, out)
    return out


def _old_active(s: Any) -> Any:
    a06 = 3 * 0.2**3
    mid = lambda x: x + (4.0 / 3.0) * (1 - x) ** 3  # noqa: E731
    a14 = a06 + mid(1.4) - mid(0.6)
    a16 = a14 + 3 * (0.0 - (-0.2) ** 3)
    pieces = [0.0 * s, 3 * (s - 0.4) ** 3, a06 + mid(s) - mid(0.6), a14 + 3 * ((s - 1.6) ** 3 + 0.2**3), a16 + 0.0 * s]
    return _old_piecewise(s, [0.4, 0.6, 1.4, 1.6], pieces)


def _old_exponential_linear(x: Any, start: float, star: float, P1: float, P2: float) -> Any:
    P3 = P1 * P2 * math.exp(P2 * (star - start))
    P4 = P1 * (math.exp(P2 * (star - start)) - 1) - P3 * star
    at_star = P1 * ((math.exp(P2 * (star - start)) - 1) / P2 - (star - start))
    pieces = [0.0 * x, P1 * ((ufl.exp(P2 * (x - start)) - 1) / P2 - (x - start)),
              at_star + 0.5 * P3 * (x**2 - star**2) + P4 * (x - star)]
    return _old_piecewise(x, [start, star], pieces)


def _old_fibre_stretch(F: Any, a0: Any) -> Any:
    Cbar = ufl.det(F) ** (-2.0 / 3.0) * right_cauchy_green(F)
    return ufl.sqrt(ufl.inner(a0, Cbar * a0))


class OldMuscle(Muscle):
    def reduced_energy(self, F: Any, R: Any = None) -> Any:
        s = _old_fibre_stretch(F, self.fibre_direction()) / self.l_ofl
        s0 = 1.0 / self.l_ofl
        star = self.l_star / self.l_ofl
        Fp = (_old_exponential_linear(s, 1.0, star, self.P1, self.P2)
              - forms.muscle.exponential_linear_antiderivative(s0, 1.0, star, self.P1, self.P2, math))
        Fa = _old_active(s) - forms.muscle.active_antiderivative(s0, math)
        return self.isotropic_energy(F) + self.sigma_max * (Fp + self.alpha * Fa)


class OldTendon(Tendon):
    def reduced_energy(self, F: Any, R: Any = None) -> Any:
        lbar = _old_fibre_stretch(F, self.fibre_direction())
        return self.isotropic_energy(F) + _old_exponential_linear(lbar, 1.0, self.l_star_t, self.L1, self.L2)


# --- evaluation ----------------------------------------------------------------------------------------------------

def fibre_samples(stretches: list[float], n_random: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(F, a0, alpha): isochoric stretches lbar along random fibres, then the verify tool's samples."""
    rng = np.random.default_rng(seed)
    F, a0 = [], []
    for lbar in stretches:
        Q = np.linalg.qr(rng.standard_normal((3, 3)))[0]
        stretch = np.diag([lbar, lbar**-0.5, lbar**-0.5])
        F.append(Q @ stretch @ Q.T * rng.uniform(0.9, 1.1))  # a volume change too: lbar is isochoric
        a0.append(Q[:, 0])
    G, _ = deformation_samples(n_random, seed, inverted=False)
    directions = rng.standard_normal((n_random, 3))
    F_all = np.concatenate([np.array(F), G])
    a0_all = np.concatenate([np.array(a0), directions / np.linalg.norm(directions, axis=1)[:, None]])
    alpha = rng.uniform(0.0, 1.0, len(F_all))
    alpha[0::3] = 1.0
    return F_all, a0_all, alpha


def evaluate(make: Any, F: np.ndarray, a0: np.ndarray, alpha: np.ndarray) -> dict[str, np.ndarray]:
    """psi, P and A = dP/dF of the law make(a0=..., alpha=...) at each F (one tetrahedron per sample)."""
    n = len(F)
    tet = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    msh = compat.create_mesh(MPI.COMM_SELF, np.arange(4 * n, dtype=np.int64).reshape(n, 4), np.tile(tet, (n, 1)))
    order = np.asarray(msh.topology.original_cell_index, dtype=np.int64)
    functions = {}
    for name, values, shape in (("F", F, (3, 3)), ("a0", a0, (3,)), ("alpha", alpha, ())):
        functions[name] = fem.Function(compat.function_space(msh, "DG", 0, shape) if shape
                                       else compat.function_space(msh, "DG", 0))
        functions[name].x.array[:] = np.asarray(values).reshape(n, -1)[order].reshape(-1)
    law = make(a0=functions["a0"], alpha=functions["alpha"])
    Fv = ufl.variable(functions["F"])
    P = law.stress(Fv)
    points = compat.quadrature_points(msh, 1)
    cells = np.arange(n, dtype=np.int32)
    inverse = np.empty_like(order)
    inverse[order] = np.arange(n)
    out = {}
    for name, expr, shape in (("psi", law.energy(Fv), ()), ("P", P, (3, 3)), ("A", ufl.diff(P, Fv), (3, 3, 3, 3))):
        values = compat.evaluate(fem.Expression(expr, points), msh, cells)
        out[name] = values.reshape(n, *shape)[inverse]
    return out


MUSCLE = {"c1": 500.0, "c2": 120.0, "K": 1.0e6, "sigma_max": 3.0e5, "P1": 0.05, "P2": 6.6, "l_ofl": 0.95,
          "l_star": 1.4}
TENDON = {"c1": 500.0, "c2": 0.0, "K": 1.0e6, "L1": 2.7e6, "L2": 46.4, "l_star_t": 1.03}
#: fibre stretches in every piece: muscle s = lbar / 0.95 in (0, 0.4], (0.4, 0.6], (0.6, 1.4], (1.4, 1.6],
#: beyond, and passive (1, 1.4/0.95]; tendon (.., 1], (1, 1.03], beyond; 0.95 = l_ofl puts s on a break
STRETCHES = [0.3, 0.45, 0.5, 0.7, 0.95, 0.98, 1.01, 1.02, 1.2, 1.36, 1.45, 1.6, 1.9, 3.0]


@pytest.mark.parametrize(("new", "old", "params"), [(Muscle, OldMuscle, MUSCLE), (Tendon, OldTendon, TENDON)],
                         ids=["muscle", "tendon"])
@pytest.mark.parametrize("isotropic", ["mooney_rivlin", "stvk"])
def test_fibre_forms_unchanged(new: type, old: type, params: dict[str, float], isotropic: str) -> None:
    if isotropic == "stvk":
        params = {**{k: v for k, v in params.items() if k not in ("c1", "c2")}, "isotropic": "stvk", "E": 3e4,
                  "nu": 0.4}
    F, a0, alpha = fibre_samples(STRETCHES, 14, seed=3)
    got = evaluate(lambda **f: new.from_parameters(**params, **(f if new is Muscle else {"a0": f["a0"]})),
                   F, a0, alpha)
    want = evaluate(lambda **f: old.from_parameters(**params, **(f if old is OldMuscle else {"a0": f["a0"]})),
                    F, a0, alpha)
    # A jumps where the curve's slope does (s = 0.6, 1.4 and the passive curve's 1 and l_star / l_ofl; tendon
    # lbar = 1 and l_star_t): there the rounding of lbar (J^(-1/3) |F a0| now, sqrt(a0 . Cbar a0) before) picks
    # a side, so A is compared only away from them (psi and P are continuous there and compared everywhere)
    lbar = np.linalg.det(F) ** (-1.0 / 3.0) * np.linalg.norm(np.einsum("nij,nj->ni", F, a0), axis=1)
    if new is Muscle:
        s, breaks = lbar / params["l_ofl"], [0.4, 0.6, 1.4, 1.6, 1.0, params["l_star"] / params["l_ofl"]]
    else:
        s, breaks = lbar, [1.0, params["l_star_t"]]
    smooth = np.min(np.abs(s[:, None] - np.array(breaks)[None, :]), axis=1) > 1e-9
    assert smooth.sum() >= 0.7 * len(F) and not smooth.all()  # on a break: l_ofl, identity, rotations, isotropic
    for name in ("psi", "P", "A"):
        assert np.all(np.isfinite(want[name])), name
        scale = np.abs(want[name]).reshape(len(F), -1).max(axis=1)
        error = np.abs(got[name] - want[name]).reshape(len(F), -1).max(axis=1)
        ok = error <= 1e-12 * np.maximum(scale, 1e-6 * scale.max())
        assert np.all(ok | ~smooth) if name == "A" else np.all(ok), (name, error / scale)


def test_tendon_energy_finite_at_huge_stretch() -> None:
    """The exponential piece's argument is zeroed outside its interval: no 0 * inf = NaN at lbar = 40."""
    F = np.diag([40.0, 40.0**-0.5, 40.0**-0.5])[None]
    values = evaluate(lambda **f: Tendon.from_parameters(**TENDON, a0=f["a0"]), F, np.array([[1.0, 0, 0]]),
                      np.zeros(1))
    assert all(np.all(np.isfinite(v)) for v in values.values())
    assert values["psi"][0] > 0
