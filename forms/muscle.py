"""Fibre-activated muscle and tendon (Teran et al. 2003 / Blemker et al. 2005 form, as in the thesis seed).

    psi = F1 + U(J) + F2(lbar, alpha)
    F1  = c1 (Ibar1 - 3) + c2 (Ibar2 - 3)          (isotropic = "mooney_rivlin", Teran)
        | mu E:E + (lmbda/2)(tr E)^2               (isotropic = "stvk", as the thesis used)
    U   = K (ln J)^2
    lbar = sqrt(a0 . Cbar a0),  Cbar = J^(-2/3) C  (isochoric fibre stretch)

F2 is defined by its derivative with F2(1) = 0 (energies.md), s = lbar / l_ofl:

    muscle: dF2/dlbar = (sigma_max / l_ofl) (f_passive(s) + alpha f_active(s))
      f_active(s)  = 9 (s - 0.4)^2        0.4 < s <= 0.6
                   = 1 - 4 (1 - s)^2      0.6 < s < 1.4
                   = 9 (s - 1.6)^2        1.4 <= s < 1.6,   0 outside (0.4, 1.6)
      f_passive(s) = 0 (s <= 1);  P1 (exp(P2 (s - 1)) - 1) (1 < s < s*);  P3 s + P4 (s >= s*),
                     s* = l_star / l_ofl, P3 = P1 P2 exp(P2 (s* - 1)), P4 = P1 (exp(P2 (s* - 1)) - 1) - P3 s*  (C1)
    tendon: dF2/dlbar = sigma_tendon(lbar) = 0 (lbar <= 1); L1 (exp(L2 (lbar - 1)) - 1) (1 < lbar < l*_t);
                        L3 lbar + L4 (lbar >= l*_t), C1 at l*_t.

The energy uses the closed-form antiderivatives (below), so that UFL derives P and A exactly:
F2 = sigma_max [Fp(s) - Fp(1/l_ofl) + alpha (Fa(s) - Fa(1/l_ofl))] with Fa(s) = int_0.4^s f_active,
Fp(s) = int_1^s f_passive (muscle), and F2 = Ft(lbar) = int_1^lbar sigma_tendon (tendon).
Mixed split (forms.law): g = ln J, kappa = 2K (K = inf: incompressible, mixed only).

How the forms are written, for the cost of compiling and assembling them (the same functions):
- a piecewise curve is sum_i chi_i(s) piece_i(s) with chi_i = 0/1 scalar conditionals of constant
  branches (_indicators), not nested conditionals: UFL's derivative of chi_i is zero, so no
  derivative of F (or of a test or trial function) ever lands inside a conditional;
- W is a function of the scalar invariants J, I1, I2 (or C:C) and I4 = |F a0|^2
  (energy_of_invariants), with lbar = J^(-1/3) sqrt(I4), and the stress is sum_k dW/dI_k dI_k/dF
  (reduced_stress), each factor UFL's derivative; UFL derives the tangent from it. The P1 Jacobian
  kernel has 6.0k operations (muscle) and 5.2k (tendon) instead of 14.5k and 11.2k (one quadrature
  point; neo_hookean: 3.6k); residual and Jacobian compile in about 5 s instead of 17-35 s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import ufl

from forms.isotropic import _lame_from
from forms.kinematics import green_lagrange, isochoric_invariants, right_cauchy_green
from forms.law import Expr, Law, ParameterError, check_keys, require, require_bulk, require_finite

ISOTROPIC = ("mooney_rivlin", "stvk")
#: relative tolerance of tangent_undefined: |x - b| <= TOL |b| is on the breakpoint b
TOL = 1e-8


def isochoric_fibre_invariant(F: np.ndarray, a: np.ndarray, b: np.ndarray | None = None) -> np.ndarray:
    """numpy: J^(-2/3) (F a).(F b) per sample (F (N,3,3), a and b (N,3)); b = a gives Ibar4 = lbar^2."""
    F = np.reshape(F, (-1, 3, 3))
    Fa = np.einsum("nij,nj->ni", F, a)
    Fb = Fa if b is None else np.einsum("nij,nj->ni", F, b)
    return np.cbrt(np.linalg.det(F)) ** -2.0 * np.einsum("ni,ni->n", Fa, Fb)


def _field(fields: dict[str, np.ndarray], name: str, law: str, n: int, shape: tuple[int, ...]) -> np.ndarray:
    if fields.get(name) is None:
        raise ValueError(f"{law}: the field {name} is required")
    return np.broadcast_to(np.asarray(fields[name], dtype=np.float64), (n, *shape))


def near(x: np.ndarray, breakpoint: float) -> np.ndarray:
    """|x - b| <= 1e-8 |b| (elementwise): x on the breakpoint b, within tangent_undefined's tolerance."""
    return np.abs(np.asarray(x) - breakpoint) <= TOL * abs(breakpoint)


def _muscle_breakpoints(F: np.ndarray, fields: dict[str, np.ndarray], law: str, l_ofl: float, passive: bool,
                        active: bool) -> np.ndarray:
    """The muscle curves' points where A jumps, in s = lbar / l_ofl: 1 (``passive``: the passive curve starts
    with a non-zero slope), 0.6 and 1.4 (``active``, where alpha != 0, or everywhere without an alpha field:
    f_active's slope jumps there). s = 0.4, 1.6 and l_star / l_ofl are C1 points: A is continuous there."""
    F = np.reshape(F, (-1, 3, 3))
    s = np.sqrt(isochoric_fibre_invariant(F, _field(fields, "a0", law, len(F), (3,)))) / l_ofl
    out = near(s, 1.0) if passive else np.zeros(len(F), dtype=bool)
    if active:
        alpha = fields.get("alpha")
        on = np.ones(len(F), dtype=bool) if alpha is None else np.broadcast_to(alpha, len(F)) != 0
        out |= on & (near(s, 0.6) | near(s, 1.4))
    return out


def _indicators(x: Expr, breaks: list[float]) -> list[Expr]:
    """chi_i(x), the indicators (0.0 or 1.0) of x <= breaks[0], breaks[i-1] < x <= breaks[i], x > breaks[-1].

    chi_i = H(b_i - x) - H(b_(i-1) - x), H(b - x) = conditional(x <= b, 1, 0): scalar conditionals whose
    branches are constants, so UFL's derivative of chi_i is zero and a derivative never moves F's (or
    an argument's) derivatives inside a conditional.
    """
    steps: list[Any] = [0.0, *(ufl.conditional(ufl.le(x, b), 1.0, 0.0) for b in breaks), 1.0]
    return [steps[i + 1] - steps[i] for i in range(len(breaks) + 1)]


def _piecewise(chi: list[Expr], pieces: list[Expr]) -> Expr:
    """sum_i chi_i pieces[i]: pieces[i] where chi_i = 1 (every piece is finite for every x, so 0 * piece = 0).

    Equal to the nested conditional "pieces[0] if x <= b_0 else pieces[1] if x <= b_1 ..." to the last
    bit (the other terms are exact zeros), but its derivatives are sum_i chi_i dpieces[i]: UFL
    differentiates polynomials of one scalar, and F's derivatives (ds/dF, d2s/dF2) appear once each.
    """
    out = chi[0] * pieces[0]
    for c, piece in zip(chi[1:], pieces[1:]):
        out = out + c * piece
    return out


def active_antiderivative(s: Expr | float, mod: Any = ufl) -> Expr:
    """Fa(s) = int_0.4^s f_active (closed form; mod = ufl or math for numbers).

    Fa = 0 (s <= 0.4); 3 (s - 0.4)^3 (0.4 < s <= 0.6); Fa(0.6) + m(s) - m(0.6), m(x) = x + (4/3)(1 - x)^3
    (0.6 < s <= 1.4); Fa(1.4) + 3 ((s - 1.6)^3 + 0.2^3) (1.4 < s <= 1.6); Fa(1.6) (s > 1.6).
    """
    a06 = 3 * 0.2**3
    mid = lambda x: x + (4.0 / 3.0) * (1 - x) ** 3  # noqa: E731 - antiderivative of 1 - 4(1 - x)^2
    a14 = a06 + mid(1.4) - mid(0.6)
    a16 = a14 + 3 * (0.0 - (-0.2) ** 3)
    if mod is math:
        pieces = [0.0, 3 * (s - 0.4) ** 3, a06 + mid(s) - mid(0.6), a14 + 3 * ((s - 1.6) ** 3 + 0.2**3), a16]
        for b, piece in zip([0.4, 0.6, 1.4, 1.6], pieces):
            if s <= b:
                return piece
        return pieces[-1]
    chi = _indicators(s, [0.4, 0.6, 1.4, 1.6])
    pieces = [ufl.as_ufl(0.0), 3 * (s - 0.4) ** 3, a06 + mid(s) - mid(0.6), a14 + 3 * ((s - 1.6) ** 3 + 0.2**3),
              ufl.as_ufl(a16)]
    return _piecewise(chi, pieces)


def exponential_linear_antiderivative(x: Expr | float, start: float, star: float, P1: float, P2: float,
                                      mod: Any = ufl) -> Expr:
    """int_start^x f, f = 0 (x <= start); P1 (exp(P2 (x - start)) - 1) (start < x < star); C1 line beyond.

    The antiderivative: 0; P1 ((exp(P2 d) - 1) / P2 - d), d = x - start; at_star + (P3/2)(x^2 - star^2)
    + P4 (x - star). In UFL d = chi_1 (x - start), chi_1 the indicator of (start, star], so that
    exp(P2 d) stays finite where the piece is not used (0 * inf would be NaN).
    """
    exp = mod.exp
    P3 = P1 * P2 * math.exp(P2 * (star - start))
    P4 = P1 * (math.exp(P2 * (star - start)) - 1) - P3 * star
    at_star = P1 * ((math.exp(P2 * (star - start)) - 1) / P2 - (star - start))

    def middle(d: Any) -> Any:
        return P1 * ((exp(P2 * d) - 1) / P2 - d)

    def line(y: Any) -> Any:
        return at_star + 0.5 * P3 * (y**2 - star**2) + P4 * (y - star)

    if mod is math:
        return 0.0 if x <= start else middle(x - start) if x <= star else line(x)
    chi = _indicators(x, [start, star])
    return _piecewise(chi, [ufl.as_ufl(0.0), middle(chi[1] * (x - start)), line(x)])


def fibre_stretch(F: Expr, a0: Expr) -> Expr:
    """lbar = sqrt(a0 . Cbar a0), Cbar = J^(-2/3) F^T F.

    (J^(-1/3) |F a0| is the same number but rounds differently; at a rotation lbar = 1 +- 1e-16 sits on
    the curves' break point, where A jumps, so the rounding of lbar is kept as it was.)
    """
    Cbar = ufl.det(F) ** (-2.0 / 3.0) * right_cauchy_green(F)
    return ufl.sqrt(ufl.inner(a0, Cbar * a0))


@dataclass(frozen=True)
class _FibreLaw(Law):
    """Isotropic part F1 + U(J) = K (ln J)^2, plus a fibre term F2(lbar) of the subclass."""

    isotropic: str = "mooney_rivlin"
    c1: float = 500.0
    c2: float = 0.0
    K: float = 1.0e7
    mu: float = 0.0
    lmbda: float = 0.0
    a0: Any = None  # UFL vector: unit fibre direction in the reference configuration
    bulk_parameter: ClassVar[str] = "K"

    def _check_isotropic(self) -> None:
        require(self.isotropic in ISOTROPIC, self.name, "isotropic", self.isotropic, f"one of {', '.join(ISOTROPIC)}")
        require_finite(self.name, c1=self.c1, c2=self.c2, mu=self.mu, lmbda=self.lmbda)
        require_bulk(self.name, K=self.K)
        require(self.K > 0, self.name, "K", self.K, "> 0")
        if self.isotropic == "mooney_rivlin":
            require(self.c1 >= 0 and self.c2 >= 0, self.name, "c1" if self.c1 < 0 else "c2",
                    self.c1 if self.c1 < 0 else self.c2, ">= 0")
        else:
            require(self.mu > 0, self.name, "mu", self.mu, "> 0 (isotropic = stvk)")

    @classmethod
    def _split(cls, params: dict[str, Any], own: tuple[str, ...]) -> dict[str, Any]:
        isotropic = params.get("isotropic", "mooney_rivlin")
        iso_keys = ("c1", "c2", "K") if isotropic == "mooney_rivlin" else ("E", "nu", "mu", "lmbda", "K")
        check_keys(cls.name, params, ("isotropic", "a0", *iso_keys, *own))
        out = dict(params)
        if isotropic == "stvk":
            lame = {k: out.pop(k) for k in ("E", "nu", "mu", "lmbda") if k in out}
            out.update(_lame_from(cls.name, lame))
        return out

    @property
    def bulk_penalty(self) -> float:
        return 2.0 * self.K

    def volume_constraint(self, F: Expr) -> Expr:
        return ufl.ln(ufl.det(F))

    def isotropic_energy(self, F: Expr) -> Expr:
        """F1(F), written as the earlier forms were (tensor Cbar, E): the reference the tests compare with."""
        if self.isotropic == "mooney_rivlin":
            Ibar1, Ibar2 = isochoric_invariants(F)
            return self.c1 * (Ibar1 - 3.0) + self.c2 * (Ibar2 - 3.0)
        E = green_lagrange(F)
        return self.mu * ufl.inner(E, E) + 0.5 * self.lmbda * ufl.tr(E) ** 2

    def invariants(self, F: Expr) -> dict[str, Expr]:
        """The scalar invariants W depends on: J = det F, I1 = F : F = tr C, I4 = |F a0|^2 = a0 . C a0, and
        I2 = ((tr C)^2 - C : C) / 2 (mooney_rivlin) or CC = C : C (stvk)."""
        C = right_cauchy_green(F)
        Fa0 = F * self.fibre_direction()
        I1 = ufl.inner(F, F)
        out = {"J": ufl.det(F), "I1": I1, "I4": ufl.inner(Fa0, Fa0)}
        if self.isotropic == "mooney_rivlin":
            out["I2"] = 0.5 * (I1**2 - ufl.inner(C, C))
        else:
            out["CC"] = ufl.inner(C, C)
        return out

    def energy_of_invariants(self, inv: dict[str, Expr]) -> Expr:
        """W = F1 + F2(lbar) as a function of the scalar invariants:

            mooney_rivlin  F1 = c1 (J^(-2/3) I1 - 3) + c2 (J^(-4/3) I2 - 3)      (Ibar1, Ibar2)
            stvk           F1 = (mu/4)(CC - 2 I1 + 3) + (lmbda/8)(I1 - 3)^2      (mu E:E + (lmbda/2)(tr E)^2)
            lbar = J^(-1/3) sqrt(I4)                                              (sqrt(a0 . Cbar a0))
        """
        J, I1 = inv["J"], inv["I1"]
        if self.isotropic == "mooney_rivlin":
            iso = self.c1 * (J ** (-2.0 / 3.0) * I1 - 3.0) + self.c2 * (J ** (-4.0 / 3.0) * inv["I2"] - 3.0)
        else:
            iso = 0.25 * self.mu * (inv["CC"] - 2.0 * I1 + 3.0) + 0.125 * self.lmbda * (I1 - 3.0) ** 2
        return iso + self.fibre_energy(J ** (-1.0 / 3.0) * ufl.sqrt(inv["I4"]))

    def reduced_energy(self, F: Expr, R: Expr | None = None) -> Expr:
        return self.energy_of_invariants(self.invariants(F))

    def reduced_stress(self, F: Expr, R: Expr | None = None) -> Expr:
        """dW/dF = sum_k (dW/dI_k) dI_k/dF over the scalar invariants I_k (J, I1, I2 or CC, I4).

        Both factors are UFL's derivatives (dW/dI_k of W(I) with each I_k a ufl.variable, dI_k/dF of
        I_k(F)); UFL also derives the tangent from this stress. The same P as UFL's dW/dF of W(F), but
        the derivatives of the piecewise fibre curve are scalars of lbar and F's enter through the four
        simple tensors dI_k/dF: the Jacobian kernel has a third fewer operations and compiles ~4x faster.
        """
        Fv = ufl.variable(F)
        inv = self.invariants(Fv)
        variables = {k: ufl.variable(e) for k, e in inv.items()}
        W = self.energy_of_invariants(variables)
        return sum((ufl.diff(W, variables[k]) * ufl.diff(inv[k], Fv) for k in inv), start=ufl.zero(3, 3))

    def fibre_direction(self) -> Expr:
        if self.a0 is None:
            raise ValueError(f"{self.name}: the fibre direction a0 is required")
        return self.a0

    #: the subclass's parameters of F2, reported by parameters()
    fibre_parameters: ClassVar[tuple[str, ...]] = ()

    def fibre_energy(self, lbar: Expr) -> Expr:  # F2(lbar)
        raise NotImplementedError

    def parameters(self) -> dict[str, Any]:
        """isotropic, K, the isotropic part's constants and the fibre curve's parameters."""
        iso = ("c1", "c2") if self.isotropic == "mooney_rivlin" else ("mu", "lmbda")
        return {k: getattr(self, k) for k in ("isotropic", "K", *iso, *self.fibre_parameters)}


@dataclass(frozen=True)
class Muscle(_FibreLaw):
    """psi = F1 + K (ln J)^2 + F2(lbar, alpha), the active fibre term of the module docstring."""

    name: ClassVar[str] = "muscle"
    sigma_max: float = 3.0e5
    P1: float = 0.05
    P2: float = 6.6
    l_ofl: float = 1.0
    l_star: float = 1.4
    alpha: Any = None  # UFL scalar in [0, 1]: the activation

    def __post_init__(self) -> None:
        self._check_isotropic()
        require_finite(self.name, sigma_max=self.sigma_max, P1=self.P1, P2=self.P2, l_ofl=self.l_ofl,
                       l_star=self.l_star)
        require(self.sigma_max >= 0, self.name, "sigma_max", self.sigma_max, ">= 0")
        require(self.P1 >= 0, self.name, "P1", self.P1, ">= 0")
        require(self.P2 > 0, self.name, "P2", self.P2, "> 0")
        require(self.l_ofl > 0, self.name, "l_ofl", self.l_ofl, "> 0")
        require(self.l_star > self.l_ofl, self.name, "l_star", self.l_star, "> l_ofl")

    @classmethod
    def from_parameters(cls, alpha: Any = None, **params: Any) -> Muscle:
        own = ("sigma_max", "P1", "P2", "l_ofl", "l_star", "alpha")
        return cls(alpha=alpha, **cls._split(params, own))

    def fibre_energy(self, lbar: Expr) -> Expr:
        s = lbar / self.l_ofl
        s0 = 1.0 / self.l_ofl
        alpha = 0.0 if self.alpha is None else self.alpha
        star = self.l_star / self.l_ofl

        def passive(x: Any, mod: Any) -> Any:
            return exponential_linear_antiderivative(x, 1.0, star, self.P1, self.P2, mod)

        Fp = passive(s, ufl) - passive(s0, math)
        Fa = active_antiderivative(s, ufl) - active_antiderivative(s0, math)
        return self.sigma_max * (Fp + alpha * Fa)

    def tangent_undefined(self, F: np.ndarray, **fields: np.ndarray) -> np.ndarray:
        """Where A jumps (numpy; fields a0 (N,3), alpha (N,)): s = lbar/l_ofl = 1 (sigma_max P1 P2 > 0), and
        s = 0.6, 1.4 where alpha != 0 (sigma_max > 0). l_star is a C1 point of the passive curve (no jump)."""
        return _muscle_breakpoints(F, fields, self.name, self.l_ofl, self.sigma_max * self.P1 * self.P2 > 0,
                                   self.sigma_max > 0)

    fibre_parameters: ClassVar[tuple[str, ...]] = ("sigma_max", "P1", "P2", "l_ofl", "l_star")


@dataclass(frozen=True)
class Tendon(_FibreLaw):
    """psi = F1 + K (ln J)^2 + F2(lbar), dF2/dlbar = sigma_tendon(lbar) of the module docstring (passive)."""

    name: ClassVar[str] = "tendon"
    L1: float = 2.7e6
    L2: float = 46.4
    l_star_t: float = 1.03

    def __post_init__(self) -> None:
        self._check_isotropic()
        require_finite(self.name, L1=self.L1, L2=self.L2, l_star_t=self.l_star_t)
        require(self.L1 >= 0, self.name, "L1", self.L1, ">= 0")
        require(self.L2 > 0, self.name, "L2", self.L2, "> 0")
        require(self.l_star_t > 1.0, self.name, "l_star_t", self.l_star_t, "> 1")

    @classmethod
    def from_parameters(cls, **params: Any) -> Tendon:
        return cls(**cls._split(params, ("L1", "L2", "l_star_t")))

    def fibre_energy(self, lbar: Expr) -> Expr:
        return exponential_linear_antiderivative(lbar, 1.0, self.l_star_t, self.L1, self.L2, ufl)

    def tangent_undefined(self, F: np.ndarray, **fields: np.ndarray) -> np.ndarray:
        """Where A jumps (numpy; field a0 (N,3)): lbar = 1 when L1 > 0 (sigma_tendon starts with slope L1 L2).
        l_star_t is a C1 point of sigma_tendon (no jump)."""
        return _muscle_breakpoints(F, fields, self.name, 1.0, self.L1 > 0, False)

    fibre_parameters: ClassVar[tuple[str, ...]] = ("L1", "L2", "l_star_t")


__all__ = ["Muscle", "ParameterError", "Tendon", "active_antiderivative", "exponential_linear_antiderivative",
           "fibre_stretch"]
