"""Fibre-reinforced laws of the biomechanics literature and of FEBio: myocardium, ligament, muscle.

All three are "uncoupled" (FEBio's term): an isochoric part written with the invariants of
Cbar = J^(-2/3) C, plus the volumetric term U(J) = (kappa/2)(ln J)^2 (FEBio's default U(J),
FEBioMech/FEUncoupledMaterial.h, npmodel 0), so g(F) = ln J in the mixed split of forms.law.
Invariants (a0 the fibre, s0 the sheet direction, unit vectors in the reference configuration):

    I1 = tr C,  I2 = ((tr C)^2 - C:C)/2,  I4 = a0.C a0,  I5 = a0.C^2 a0,  I4s = s0.C s0,  I8 = a0.C s0,
    Ibar1 = J^(-2/3) I1, Ibar2 = J^(-4/3) I2, Ibar4 = J^(-2/3) I4, Ibar5 = J^(-4/3) I5, ...,
    lbar = sqrt(Ibar4) = J^(-1/3) |F a0|  (isochoric fibre stretch)

holzapfel_ogden (Holzapfel & Ogden 2009, Phil. Trans. R. Soc. A 367:3445, eq. 5.38, in the modified
(isochoric) invariants, with its -1 on the first term so that psi(I) = 0):

    W = a/(2b) (exp(b (Ibar1 - 3)) - 1) + sum_{i=f,s} H(Ibar4i - 1) a_i/(2 b_i) (exp(b_i (Ibar4i - 1)^2) - 1)
        + a_fs/(2 b_fs) (exp(b_fs Ibar8^2) - 1),     H the unit step: fibres and sheets act in tension only

trans_iso_mooney_rivlin (Weiss, Maker & Govindjee 1996; FEBio's "trans iso Mooney-Rivlin",
FETransIsoMooneyRivlin.cpp with FEUncoupledFiberExpLinear.cpp and the active contraction of
FEUncoupledActiveFiberContraction.cpp):

    W = c1 (Ibar1 - 3) + c2 (Ibar2 - 3) + F2(lbar) + alpha Fa(lbar),   F2(1) = 0, Fa(l_a) = 0
    lbar dF2/dlbar = 0 (lbar < 1); c3 (exp(c4 (lbar - 1)) - 1) (1 <= lbar < lam_max); c5 lbar + c6 (lbar >= lam_max),
                     c6 = c3 (exp(c4 (lam_max - 1)) - 1) - c5 lam_max (continuity);
                     c3 = 0 given: c3 = c5/c4 exp(-c4 (lam_max - 1)) (FEBio's rule: then C1 at lam_max)
    lbar dFa/dlbar = T(lbar) = Tmax (E - 1)/(E - 1 + (camax/ca0)^2), E = exp(beta (refl lbar - l0)), for
                     refl lbar >= l0 (lbar >= l_a = l0/refl), else 0.

  An energy W(lbar) has the deviatoric Cauchy stress dev(lbar W'(lbar) a x a)/J (a = F a0/|F a0|), so
  alpha Fa gives FEBio's active stress dev(alpha T a x a)/J exactly (ascl = alpha). F2 and Fa have no
  elementary antiderivative (F2 needs the exponential integral Ei, as FEBio's strain energy does; Fa a
  non-elementary integral): psi integrates them with 32-point Gauss-Legendre quadrature, and the stress
  (reduced_stress) uses the exact derivative W'(lbar) written in closed form, so P and A are exact and
  psi is accurate to the quadrature (~1e-14 relative for the curves' usual parameters).

blemker (Blemker, Pinsky & Delp 2005; FEBio's "muscle material", FEMuscleMaterial.cpp):

    W = g1 B1^2 + g2 B2^2 + (9/16) g3 (ln Ibar4)^2 + F2(lbar, alpha),
    B1^2 = Ibar5 / Ibar4^2 - 1,  B2 = arccosh(w),
    w = (Ibar1 Ibar4 - Ibar5) / (2 sqrt(Ibar4)) = (I1 I4 - I5) / (2 J sqrt(I4))
    dF2/dlbar = (smax / Lofl) (f_passive(s) + alpha f_active(s)), s = lbar / Lofl (the muscle law's curves,
                forms.muscle, with l_ofl = Lofl, l_star = lam_max, P1 = p1, P2 = p2, sigma_max = smax)

  (no factor 1/2 on g1, g2: FEBio's F1D5 = g1/I4^2, F2D5 = -g2 beta/lbar are the derivatives of g1 B1^2
  and g2 B2^2, as Blemker et al. write W1 = G1 B1^2, W2 = G2 B2^2; the g3 term is FEBio's F3D4 =
  (9/8) g3 ln(I4)/I4). B1^2 is written directly (B1 = sqrt(.) has an infinite derivative at 0), and
  arccosh(w)^2 through its Taylor series in y = w - 1 for y <= 0.1 (arccosh(1 + y)^2 = sum_k a_k y^k,
  a_1 = 2, a_(m+1) = -m^2 a_m / ((m + 1)(2m + 1)), 16 terms: below 1e-17 relative), so that P and A are
  finite and exact at the rest state and at pure fibre stretch (w = 1).

Each W is a function of scalar invariants (as forms.muscle writes its laws, for the cost of the
forms): the stress is sum_k dW/dI_k dI_k/dF with both factors derived by UFL.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import ufl

from forms.law import Expr, Law, check_keys
from forms.metadata import Parameter
from forms.muscle import (
    TOL,
    _field,
    _indicators,
    _muscle_breakpoints,
    active_antiderivative,
    exponential_linear_antiderivative,
    isochoric_fibre_invariant,
    near,
)

PA = "Pa (stress)"
ONE = "dimensionless"
#: Gauss-Legendre points of the fibre integrals of trans_iso_mooney_rivlin's psi
GAUSS_POINTS = 32


def _bulk(name: str, default: float) -> Parameter:
    return Parameter(name, f"bulk modulus of the volumetric term ({name}/2)(ln J)^2", PA, default=default, lower=0.0,
                     infinite=True)


def _gauss(f: Any, lo: Any, hi: Any, n: int = GAUSS_POINTS) -> Expr:
    """int_lo^hi f(l) dl by n-point Gauss-Legendre quadrature (lo, hi UFL expressions or numbers)."""
    nodes, weights = np.polynomial.legendre.leggauss(n)
    half, mid = 0.5 * (hi - lo), 0.5 * (hi + lo)
    total = weights[0] * f(mid + half * nodes[0])
    for x, w in zip(nodes[1:], weights[1:]):
        total = total + w * f(mid + half * x)
    return half * total


def arccosh_squared(w: Expr, switch: float = 0.1, terms: int = 16) -> Expr:
    """arccosh(w)^2, smooth at w = 1: the Taylor series sum_k a_k (w - 1)^k for w - 1 <= switch
    (a_1 = 2, a_(m+1) = -m^2 a_m / ((m + 1)(2m + 1))), ln(w + sqrt(w^2 - 1))^2 beyond."""
    y = w - 1.0
    coefficients = [2.0]
    for m in range(1, terms):
        coefficients.append(-m * m * coefficients[-1] / ((m + 1) * (2 * m + 1)))
    series = coefficients[-1]
    for c in reversed(coefficients[:-1]):
        series = c + y * series
    series = y * series
    far = ufl.max_value(w, 1.0 + 0.5 * switch)  # the branch not taken stays finite
    exact = ufl.ln(far + ufl.sqrt(far**2 - 1.0)) ** 2
    return ufl.conditional(ufl.le(y, switch), series, exact)


@dataclass(frozen=True)
class _UncoupledFibreLaw(Law):
    """W(I) of scalar invariants I_k of F and the fields, plus (kappa/2)(ln J)^2; validated from PARAMETERS."""

    a0: Any = None  # UFL vector: unit fibre direction in the reference configuration
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = ()
    FIELDS: ClassVar[tuple[str, ...]] = ("a0",)

    def __post_init__(self) -> None:
        for p in self.PARAMETERS:
            p.check(self.name, getattr(self, p.name))
        self._check_constraints()

    def _check_constraints(self) -> None:
        """Bounds that depend on several parameters (ParameterError naming one)."""

    @classmethod
    def from_parameters(cls, **params: Any) -> _UncoupledFibreLaw:
        check_keys(cls.name, params, (*(p.name for p in cls.PARAMETERS), *cls.FIELDS))
        return cls(**params)

    @property
    def bulk_penalty(self) -> float:
        return float(getattr(self, self.bulk_parameter))

    def volume_constraint(self, F: Expr) -> Expr:
        return ufl.ln(ufl.det(F))

    def _required(self, name: str) -> Expr:
        value = getattr(self, name)
        if value is None:
            raise ValueError(f"{self.name}: the field {name} is required")
        return value

    def _activation(self) -> Any:
        return 0.0 if getattr(self, "alpha", None) is None else self.alpha

    def invariants(self, F: Expr) -> dict[str, Expr]:
        raise NotImplementedError

    def energy_of_invariants(self, inv: dict[str, Expr]) -> Expr:
        raise NotImplementedError

    def reduced_energy(self, F: Expr, R: Expr | None = None) -> Expr:
        return self.energy_of_invariants(self.invariants(F))

    def reduced_stress(self, F: Expr, R: Expr | None = None) -> Expr:
        """dW/dF = sum_k (dW/dI_k) dI_k/dF, both factors derived by UFL (as forms.muscle)."""
        Fv = ufl.variable(F)
        inv = self.invariants(Fv)
        variables = {k: ufl.variable(e) for k, e in inv.items()}
        W = self.energy_of_invariants(variables)
        return sum((ufl.diff(W, variables[k]) * ufl.diff(inv[k], Fv) for k in inv), start=ufl.zero(3, 3))

    def parameters(self) -> dict[str, Any]:
        return {p.name: getattr(self, p.name) for p in self.PARAMETERS}


HOLZAPFEL_OGDEN_PARAMETERS = (
    Parameter("a", "stiffness of the isotropic (matrix) term", PA, default=59.0, lower=0.0),
    Parameter("b", "exponent of the isotropic term", ONE, default=8.023, lower=0.0),
    Parameter("a_f", "stiffness of the fibre term (tension only)", PA, default=18472.0, lower=0.0, lower_open=False),
    Parameter("b_f", "exponent of the fibre term", ONE, default=16.026, lower=0.0),
    Parameter("a_s", "stiffness of the sheet term (tension only)", PA, default=2481.0, lower=0.0, lower_open=False),
    Parameter("b_s", "exponent of the sheet term", ONE, default=11.12, lower=0.0),
    Parameter("a_fs", "stiffness of the fibre-sheet coupling term", PA, default=216.0, lower=0.0, lower_open=False),
    Parameter("b_fs", "exponent of the fibre-sheet coupling term", ONE, default=11.436, lower=0.0),
    _bulk("kappa", 1.0e6),
)


@dataclass(frozen=True)
class HolzapfelOgden(_UncoupledFibreLaw):
    """Holzapfel & Ogden 2009 myocardium, isochoric invariants, + (kappa/2)(ln J)^2 (module docstring)."""

    name: ClassVar[str] = "holzapfel_ogden"
    bulk_parameter: ClassVar[str] = "kappa"
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = HOLZAPFEL_OGDEN_PARAMETERS
    FIELDS: ClassVar[tuple[str, ...]] = ("a0", "s0")
    a: float = 59.0
    b: float = 8.023
    a_f: float = 18472.0
    b_f: float = 16.026
    a_s: float = 2481.0
    b_s: float = 11.12
    a_fs: float = 216.0
    b_fs: float = 11.436
    kappa: float = 1.0e6
    s0: Any = None  # UFL vector: unit sheet direction, orthogonal to a0

    def invariants(self, F: Expr) -> dict[str, Expr]:
        """J, I1 = F:F, I4f = |F a0|^2, I4s = |F s0|^2, I8 = (F a0).(F s0)."""
        Ff, Fs = F * self._required("a0"), F * self._required("s0")
        return {"J": ufl.det(F), "I1": ufl.inner(F, F), "I4f": ufl.inner(Ff, Ff), "I4s": ufl.inner(Fs, Fs),
                "I8": ufl.inner(Ff, Fs)}

    def energy_of_invariants(self, inv: dict[str, Expr]) -> Expr:
        Jm23 = inv["J"] ** (-2.0 / 3.0)
        W = self.a / (2.0 * self.b) * (ufl.exp(self.b * (Jm23 * inv["I1"] - 3.0)) - 1.0)
        for a, b, key in ((self.a_f, self.b_f, "I4f"), (self.a_s, self.b_s, "I4s")):
            if a != 0.0:
                I4 = Jm23 * inv[key]
                tension = _indicators(I4, [1.0])[1]
                W = W + tension * a / (2.0 * b) * (ufl.exp(b * (I4 - 1.0) ** 2) - 1.0)
        if self.a_fs != 0.0:
            W = W + self.a_fs / (2.0 * self.b_fs) * (ufl.exp(self.b_fs * (Jm23 * inv["I8"]) ** 2) - 1.0)
        return W

    def tangent_undefined(self, F: np.ndarray, **fields: np.ndarray) -> np.ndarray:
        """Where A jumps: Ibar4f = 1 (a_f > 0) or Ibar4s = 1 (a_s > 0), the switch of the tension-only terms
        (W's second derivative in Ibar4 jumps from 0 to a_i there)."""
        F = np.reshape(F, (-1, 3, 3))
        out = np.zeros(len(F), dtype=bool)
        for a, key in ((self.a_f, "a0"), (self.a_s, "s0")):
            if a > 0:
                out |= near(isochoric_fibre_invariant(F, _field(fields, key, self.name, len(F), (3,))), 1.0)
        return out


TRANS_ISO_MOONEY_RIVLIN_PARAMETERS = (
    Parameter("c1", "Mooney-Rivlin coefficient of (Ibar1 - 3)", PA, default=13.85e6, lower=0.0),
    Parameter("c2", "Mooney-Rivlin coefficient of (Ibar2 - 3)", PA, default=0.0, lower=0.0, lower_open=False),
    Parameter("c3", "scale of the exponential fibre stress (0: c5/c4 exp(-c4 (lam_max - 1)), FEBio's rule)", PA,
              default=2.07e6, lower=0.0, lower_open=False),
    Parameter("c4", "rate of the exponential fibre stress", ONE, default=61.44, lower=0.0),
    Parameter("c5", "modulus of the linear fibre stress beyond lam_max", PA, default=640.7e6, lower=0.0,
              lower_open=False),
    Parameter("lam_max", "fibre stretch where the fibre stress turns linear", ONE, default=1.03, lower=1.0,
              lower_open=False),
    _bulk("k", 100.0e6),
    Parameter("Tmax", "active fibre stress at full activation and calcium (alpha = 1, camax)", PA, default=1.0e5,
              lower=0.0, lower_open=False),
    Parameter("ca0", "intracellular calcium concentration (its unit cancels in camax/ca0)", ONE, default=4.35,
              lower=0.0),
    Parameter("camax", "peak intracellular calcium concentration (as ca0)", ONE, default=4.35, lower=0.0),
    Parameter("beta", "tension-sarcomere length constant (the inverse of refl's length unit, 1/um in FEBio's "
              "example)", ONE, default=4.75, lower=0.0),
    Parameter("l0", "sarcomere length without tension (refl's unit, um in FEBio's example)", ONE, default=1.58,
              lower=0.0),
    Parameter("refl", "unloaded sarcomere length (um in FEBio's example)", ONE, default=2.04, lower=0.0),
)


@dataclass(frozen=True)
class TransIsoMooneyRivlin(_UncoupledFibreLaw):
    """Weiss et al. 1996 / FEBio's trans iso Mooney-Rivlin with its active contraction (module docstring)."""

    name: ClassVar[str] = "trans_iso_mooney_rivlin"
    bulk_parameter: ClassVar[str] = "k"
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = TRANS_ISO_MOONEY_RIVLIN_PARAMETERS
    FIELDS: ClassVar[tuple[str, ...]] = ("a0", "alpha")
    c1: float = 13.85e6
    c2: float = 0.0
    c3: float = 2.07e6
    c4: float = 61.44
    c5: float = 640.7e6
    lam_max: float = 1.03
    k: float = 100.0e6
    Tmax: float = 1.0e5
    ca0: float = 4.35
    camax: float = 4.35
    beta: float = 4.75
    l0: float = 1.58
    refl: float = 2.04
    alpha: Any = None  # UFL scalar in [0, 1]: the activation (FEBio's ascl)

    @property
    def c3_used(self) -> float:
        """c3, or FEBio's c5/c4 exp(-c4 (lam_max - 1)) when c3 = 0 (the fibre stress is then C1 at lam_max)."""
        return self.c3 if self.c3 != 0.0 else self.c5 / self.c4 * math.exp(-self.c4 * (self.lam_max - 1.0))

    @property
    def c6(self) -> float:
        """c3 (exp(c4 (lam_max - 1)) - 1) - c5 lam_max: the linear piece continues the exponential one."""
        return self.c3_used * (math.exp(self.c4 * (self.lam_max - 1.0)) - 1.0) - self.c5 * self.lam_max

    @property
    def l_active(self) -> float:
        """l0 / refl: the fibre stretch below which the active stress is zero."""
        return self.l0 / self.refl

    def active_tension(self, lbar: Any, mod: Any = ufl) -> Any:
        """T(lbar) = Tmax (E - 1)/(E - 1 + (camax/ca0)^2), E = exp(beta (refl lbar - l0)) (lbar >= l0/refl)."""
        E = mod.exp(self.beta * (self.refl * lbar - self.l0))
        return self.Tmax * (E - 1.0) / (E - 1.0 + (self.camax / self.ca0) ** 2)

    def invariants(self, F: Expr) -> dict[str, Expr]:
        """J, I1 = F:F, I2 = ((tr C)^2 - C:C)/2, I4 = |F a0|^2."""
        C = F.T * F
        Fa0 = F * self._required("a0")
        I1 = ufl.inner(F, F)
        return {"J": ufl.det(F), "I1": I1, "I2": 0.5 * (I1**2 - ufl.inner(C, C)), "I4": ufl.inner(Fa0, Fa0)}

    def _isotropic(self, inv: dict[str, Expr]) -> Expr:
        J = inv["J"]
        return self.c1 * (J ** (-2.0 / 3.0) * inv["I1"] - 3.0) + self.c2 * (J ** (-4.0 / 3.0) * inv["I2"] - 3.0)

    @staticmethod
    def _stretch(inv: dict[str, Expr]) -> Expr:
        return inv["J"] ** (-1.0 / 3.0) * ufl.sqrt(inv["I4"])

    def fibre_energy(self, lbar: Expr) -> Expr:
        """F2(lbar) + alpha Fa(lbar): Gauss-Legendre quadrature of lbar W'(lbar) / lbar (module docstring)."""
        c3, c4 = self.c3_used, self.c4
        below, middle, beyond = _indicators(lbar, [1.0, self.lam_max])
        top = below * 1.0 + middle * lbar + beyond * self.lam_max  # lbar clipped to [1, lam_max]
        W = _gauss(lambda x: c3 * (ufl.exp(c4 * (x - 1.0)) - 1.0) / x, 1.0, top)
        W = W + beyond * (self.c5 * (lbar - self.lam_max) + self.c6 * ufl.ln(lbar / self.lam_max))
        alpha = self._activation()
        if self.Tmax != 0.0 and not (isinstance(alpha, float) and alpha == 0.0):
            off, on = _indicators(lbar, [self.l_active])
            la = off * self.l_active + on * lbar  # max(lbar, l0/refl)
            W = W + alpha * _gauss(lambda x: self.active_tension(x) / x, self.l_active, la)
        return W

    def fibre_energy_derivative(self, lbar: Expr) -> Expr:
        """dW/dlbar of fibre_energy, in closed form: (lbar dF2/dlbar + alpha T(lbar)) / lbar."""
        below, middle, beyond = _indicators(lbar, [1.0, self.lam_max])
        top = below * 1.0 + middle * lbar + beyond * self.lam_max
        sn = middle * self.c3_used * (ufl.exp(self.c4 * (top - 1.0)) - 1.0) + beyond * (self.c5 * lbar + self.c6)
        alpha = self._activation()
        if self.Tmax != 0.0 and not (isinstance(alpha, float) and alpha == 0.0):
            off, on = _indicators(lbar, [self.l_active])
            la = off * self.l_active + on * lbar
            sn = sn + alpha * on * self.active_tension(la)
        return sn / lbar

    def energy_of_invariants(self, inv: dict[str, Expr]) -> Expr:
        return self._isotropic(inv) + self.fibre_energy(self._stretch(inv))

    def reduced_stress(self, F: Expr, R: Expr | None = None) -> Expr:
        """dW/dF: the isotropic part by the chain rule through J, I1, I2 (UFL's factors), the fibre part
        W'(lbar) dlbar/dF with W' in closed form (fibre_energy_derivative) and dlbar/dF by UFL."""
        Fv = ufl.variable(F)
        inv = self.invariants(Fv)
        variables = {k: ufl.variable(inv[k]) for k in ("J", "I1", "I2")}
        W = self._isotropic(variables)
        P = sum((ufl.diff(W, variables[k]) * ufl.diff(inv[k], Fv) for k in variables), start=ufl.zero(3, 3))
        lbar = self._stretch(inv)
        return P + self.fibre_energy_derivative(lbar) * ufl.diff(lbar, Fv)

    def tangent_undefined(self, F: np.ndarray, **fields: np.ndarray) -> np.ndarray:
        """Where A jumps: lbar = 1 (the exponential fibre stress starts with slope c3 c4 > 0), lbar = lam_max
        unless the stress is C1 there (c5 = c3 c4 exp(c4 (lam_max - 1)), e.g. FEBio's c3 = 0 rule), and
        lbar = l0/refl where alpha != 0 and Tmax > 0 (the active stress starts with a non-zero slope)."""
        F = np.reshape(F, (-1, 3, 3))
        lbar = np.sqrt(isochoric_fibre_invariant(F, _field(fields, "a0", self.name, len(F), (3,))))
        out = np.zeros(len(F), dtype=bool)
        if self.c3_used * self.c4 > 0 and self.lam_max > 1.0:
            out |= near(lbar, 1.0)
        slope = self.c3_used * self.c4 * math.exp(self.c4 * (self.lam_max - 1.0))
        if abs(slope - self.c5) > TOL * max(abs(slope), abs(self.c5)):
            out |= near(lbar, self.lam_max)
        if self.Tmax > 0:
            alpha = fields.get("alpha")
            active = np.ones(len(F), dtype=bool) if alpha is None else np.broadcast_to(alpha, len(F)) != 0
            out |= active & near(lbar, self.l_active)
        return out


BLEMKER_PARAMETERS = (
    Parameter("g1", "along-fibre shear modulus, coefficient of B1^2", PA, default=500.0, lower=0.0,
              lower_open=False),
    Parameter("g2", "cross-fibre shear modulus, coefficient of B2^2", PA, default=500.0, lower=0.0,
              lower_open=False),
    Parameter("g3", "coefficient of FEBio's term (9/16) g3 (ln Ibar4)^2", PA, default=0.0, lower=0.0,
              lower_open=False),
    Parameter("p1", "scale of the passive fibre curve (times smax)", ONE, default=0.05, lower=0.0, lower_open=False),
    Parameter("p2", "exponent of the passive fibre curve", ONE, default=6.6, lower=0.0),
    Parameter("Lofl", "optimal fibre stretch (the active curve peaks at lbar = Lofl)", ONE, default=1.07, lower=0.0),
    Parameter("lam_max", "fibre stretch where the passive curve turns linear (lambda*)", ONE, default=1.4,
              constraint="> Lofl"),
    Parameter("smax", "maximum isometric fibre stress", PA, default=3.0e5, lower=0.0, lower_open=False),
    _bulk("k", 1.0e6),
)


@dataclass(frozen=True)
class Blemker(_UncoupledFibreLaw):
    """Blemker et al. 2005 / FEBio's muscle material: Criscione's B1, B2 and the muscle curves (module docstring)."""

    name: ClassVar[str] = "blemker"
    bulk_parameter: ClassVar[str] = "k"
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = BLEMKER_PARAMETERS
    FIELDS: ClassVar[tuple[str, ...]] = ("a0", "alpha")
    g1: float = 500.0
    g2: float = 500.0
    g3: float = 0.0
    p1: float = 0.05
    p2: float = 6.6
    Lofl: float = 1.07
    lam_max: float = 1.4
    smax: float = 3.0e5
    k: float = 1.0e6
    alpha: Any = None  # UFL scalar in [0, 1]: the activation

    def _check_constraints(self) -> None:
        from forms.law import require

        require(self.lam_max > self.Lofl, self.name, "lam_max", self.lam_max, "> Lofl")

    def invariants(self, F: Expr) -> dict[str, Expr]:
        """J, I1 = F:F, I4 = |F a0|^2, I5 = |C a0|^2."""
        a0 = self._required("a0")
        Fa0 = F * a0
        Ca0 = F.T * Fa0
        return {"J": ufl.det(F), "I1": ufl.inner(F, F), "I4": ufl.inner(Fa0, Fa0), "I5": ufl.inner(Ca0, Ca0)}

    def energy_of_invariants(self, inv: dict[str, Expr]) -> Expr:
        J, I1, I4, I5 = inv["J"], inv["I1"], inv["I4"], inv["I5"]
        W = ufl.as_ufl(0.0)
        if self.g1 != 0.0:
            W = W + self.g1 * (I5 / I4**2 - 1.0)
        if self.g2 != 0.0:
            W = W + self.g2 * arccosh_squared((I1 * I4 - I5) / (2.0 * J * ufl.sqrt(I4)))
        Ibar4 = J ** (-2.0 / 3.0) * I4
        if self.g3 != 0.0:
            W = W + 9.0 / 16.0 * self.g3 * ufl.ln(Ibar4) ** 2
        return W + self.fibre_energy(ufl.sqrt(Ibar4))

    def fibre_energy(self, lbar: Expr) -> Expr:
        """F2 = smax [Fp(s) - Fp(1/Lofl) + alpha (Fa(s) - Fa(1/Lofl))], s = lbar/Lofl (forms.muscle's curves)."""
        s, s1, star = lbar / self.Lofl, 1.0 / self.Lofl, self.lam_max / self.Lofl

        def passive(x: Any, mod: Any) -> Any:
            return exponential_linear_antiderivative(x, 1.0, star, self.p1, self.p2, mod)

        Fp = passive(s, ufl) - passive(s1, math)
        Fa = active_antiderivative(s, ufl) - active_antiderivative(s1, math)
        return self.smax * (Fp + self._activation() * Fa)

    def tangent_undefined(self, F: np.ndarray, **fields: np.ndarray) -> np.ndarray:
        """Where A jumps: s = lbar/Lofl = 1 (p1 p2 smax > 0: the passive curve starts with slope p1 p2), and
        s = 0.6 or 1.4 where alpha != 0 (f_active's slope jumps from 3.6 to 3.2 and from -3.2 to -3.6).
        s = 0.4, 1.6 and lam_max/Lofl are C1 points of the curves: A is continuous there."""
        return _muscle_breakpoints(F, fields, self.name, self.Lofl, self.smax * self.p1 * self.p2 > 0,
                                   self.smax > 0)


__all__ = ["Blemker", "HolzapfelOgden", "TransIsoMooneyRivlin", "arccosh_squared"]
