"""Membrane energies for triangle surfaces embedded in 3D (a dolfinx mesh with tdim 2, gdim 3).

Kinematics (thesis 3.3.3.1, after Wang et al. 2011). Each rest triangle carries an orthonormal tangent frame
(t1, t2) and a unit normal N = t1 x t2 (``tangent_frame``: t1 along the first edge of the cell's Jacobian,
N given so that the orientation is a choice of the caller, not of dolfinx's cell numbering). With the deformed
position x = X + u the surface deformation gradient is the 3x2 matrix

    F = [dx/dt1  dx/dt2] = [(I + grad u) t1   (I + grad u) t2],

grad the manifold (tangential) gradient UFL takes on a surface mesh, so F equals the thesis' discrete
[x2 - x1, x3 - x1] Dm^-1 on linear triangles (the seed rows thesis-sec3.3.3.1-F compare the two). The surface
metric is C = F^T F (2x2), the membrane Green strain E = (C - I2) / 2.

Energies per unit reference area (thickness h, integrate over the reference surface dA):

| law                          | w(F)                                                                   |
|------------------------------|------------------------------------------------------------------------|
| ``MembraneStVK``             | h (mu E:E + (lambda'/2)(tr E)^2),  lambda' = 2 mu lambda/(lambda + 2mu) |
| ``MembraneNeoHookean``       | (mu h / 2)(tr C + 1/det C - 3)                                          |

``MembraneStVK`` is the thesis' 1/2 G:B:G h with B the plane-stress Hooke matrix [[1, nu, 0], [nu, 1, 0],
[0, 0, (1 - nu)/2]] E/(1 - nu^2) in Voigt form (engineering shear 2 G12): mu = E/(2(1 + nu)),
lambda' = E nu/(1 - nu^2). ``MembraneNeoHookean`` is the incompressible neo-Hookean solid
W = (mu/2)(lambda1^2 + lambda2^2 + lambda3^2 - 3) under plane stress, the thickness stretch eliminated by
incompressibility, lambda3^2 = 1/det C (Adkins & Rivlin, Large elastic deformations of isotropic materials IX.
The deformation of thin shells, Phil. Trans. R. Soc. A 244 (1952) 505-531; also Holzapfel, Nonlinear Solid
Mechanics (2000), the incompressible membrane). Both reduce to the same small-strain plane-stress law for
the neo-Hookean with nu = 1/2 (E = 3 mu).

Pressure p on the deformed surface (normal n, area da, n da = F t1 x F t2 dA = dx/dt1 x dx/dt2 dA):

* follower virtual work  delta W_p = int p n . v da = int p (F t1 x F t2) . v dA (``pressure_virtual_work``),
  a residual whose ufl.derivative is the (non-symmetric in general) load stiffness;
* for a closed surface (or one closed by fixed plane pieces through the origin, where x . n = 0, e.g. a
  clamped disc on the plane z = 0 or a symmetry octant of a sphere) the load has the potential -p V(x),
  V = (1/3) int x . n da (divergence theorem, ``enclosed_volume``), whose first derivative is the follower
  work above and whose second derivative is symmetric. The problems here use the volume potential, so the
  Newton Jacobian is the (symmetric) Hessian of Pi(x) = int w dA - p V(x). On such surfaces the follower
  form's tangent is the same matrix (tests/test_membrane.py checks both on a closed sphere); on a surface with
  free (unsupported) edges the follower load has no potential and its tangent is not symmetric.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar

import ufl

from forms.law import Expr, ParameterError, check_keys, require, require_finite

__all__ = ["MEMBRANE_LAWS", "MembraneLaw", "MembraneNeoHookean", "MembraneStVK", "enclosed_volume",
           "equibiaxial_energy", "membrane_deformation_gradient", "membrane_law", "pressure_virtual_work",
           "surface_metric", "tangent_frame"]


def tangent_frame(mesh: Any, normal: Expr) -> tuple[Expr, Expr]:
    """(t1, t2): t1 = J[:, 0] / |J[:, 0]| (the cell Jacobian's first column), t2 = N x t1, N the given unit normal
    (e.g. a DG0 field oriented outward), so (t1, t2, N) is right-handed."""
    J = ufl.Jacobian(mesh)
    j0 = ufl.as_vector([J[i, 0] for i in range(3)])
    t1 = j0 / ufl.sqrt(ufl.dot(j0, j0))
    return t1, ufl.cross(normal, t1)


def membrane_deformation_gradient(u: Expr, frame: tuple[Expr, Expr]) -> Expr:
    """F = [(I + grad u) t1, (I + grad u) t2] (3x2), grad the manifold gradient of the surface mesh."""
    G = ufl.Identity(3) + ufl.grad(u)
    columns = [G * t for t in frame]
    return ufl.as_matrix([[columns[k][i] for k in range(2)] for i in range(3)])


def surface_metric(F: Expr) -> Expr:
    """C = F^T F, the 2x2 metric of the deformed surface in the rest frame."""
    return F.T * F


@dataclass(frozen=True)
class MembraneLaw(ABC):
    """A membrane energy w(F) per unit reference area (thickness h included); F the 3x2 surface gradient."""

    name: ClassVar[str]

    @abstractmethod
    def energy(self, F: Expr) -> Expr:
        """w(F), the UFL energy density per unit reference area."""

    @abstractmethod
    def equibiaxial(self, stretch: float) -> tuple[float, float]:
        """(w(lambda), dw/dlambda) for the equibiaxial stretch C = lambda^2 I2 (closed form)."""


def _positive(law: str, **values: float) -> None:
    require_finite(law, **values)
    for key, value in values.items():
        require(value > 0, law, key, value, "> 0")


@dataclass(frozen=True)
class MembraneStVK(MembraneLaw):
    """Plane-stress St Venant-Kirchhoff membrane (thesis 3.3.3.1): w = h (mu E:E + (lambda'/2)(tr E)^2),
    E = (F^T F - I2)/2, mu = E/(2(1 + nu)), lambda' = E nu/(1 - nu^2). Equibiaxial stretch lambda:
    w = h E/(1 - nu) e^2 with e = (lambda^2 - 1)/2, so dw/dlambda = h E/(1 - nu) (lambda^2 - 1) lambda."""

    young: float
    nu: float
    thickness: float
    name: ClassVar[str] = "membrane_stvk"

    def __post_init__(self) -> None:
        _positive(self.name, young=self.young, thickness=self.thickness)
        require_finite(self.name, nu=self.nu)
        require(-1.0 < self.nu < 0.5, self.name, "nu", self.nu, "in (-1, 0.5)")

    @property
    def mu(self) -> float:
        return self.young / (2.0 * (1.0 + self.nu))

    @property
    def lmbda_plane(self) -> float:
        """lambda' = E nu / (1 - nu^2), the plane-stress Lame constant."""
        return self.young * self.nu / (1.0 - self.nu**2)

    def energy(self, F: Expr) -> Expr:
        E = 0.5 * (surface_metric(F) - ufl.Identity(2))
        return self.thickness * (self.mu * ufl.inner(E, E) + 0.5 * self.lmbda_plane * ufl.tr(E) ** 2)

    def equibiaxial(self, stretch: float) -> tuple[float, float]:
        k = self.thickness * self.young / (1.0 - self.nu)
        e = 0.5 * (stretch**2 - 1.0)
        return k * e**2, k * (stretch**2 - 1.0) * stretch


@dataclass(frozen=True)
class MembraneNeoHookean(MembraneLaw):
    """Incompressible neo-Hookean membrane: w = (mu h/2)(tr C + 1/det C - 3), C = F^T F (2x2), the thickness
    stretch lambda3 = 1/sqrt(det C) (Adkins & Rivlin 1952). Equibiaxial stretch lambda:
    w = (mu h/2)(2 lambda^2 + lambda^-4 - 3), dw/dlambda = 2 mu h (lambda - lambda^-5)."""

    mu: float
    thickness: float
    name: ClassVar[str] = "membrane_neo_hookean"

    def __post_init__(self) -> None:
        _positive(self.name, mu=self.mu, thickness=self.thickness)

    def energy(self, F: Expr) -> Expr:
        C = surface_metric(F)
        return 0.5 * self.mu * self.thickness * (ufl.tr(C) + 1.0 / ufl.det(C) - 3.0)

    def equibiaxial(self, stretch: float) -> tuple[float, float]:
        c = 0.5 * self.mu * self.thickness
        return c * (2.0 * stretch**2 + stretch**-4 - 3.0), 4.0 * c * (stretch - stretch**-5)


MEMBRANE_LAWS: dict[str, type[MembraneLaw]] = {"stvk": MembraneStVK, "neo_hookean": MembraneNeoHookean}


def membrane_law(name: str, **params: Any) -> MembraneLaw:
    """Build a membrane law by name: ``stvk`` (young, nu, thickness) or ``neo_hookean`` (mu, thickness)."""
    if name not in MEMBRANE_LAWS:
        raise ParameterError(f"membrane law {name!r} unknown (known: {', '.join(MEMBRANE_LAWS)})")
    cls = MEMBRANE_LAWS[name]
    keys = ("young", "nu", "thickness") if cls is MembraneStVK else ("mu", "thickness")
    check_keys(cls.name, params, keys, keys)
    return cls(**params)


def equibiaxial_energy(law: MembraneLaw, stretch: float) -> tuple[float, float]:
    """(w, dw/dlambda) of ``law`` at the equibiaxial stretch ``stretch`` (> 0)."""
    require(stretch > 0, law.name, "stretch", stretch, "> 0")
    return law.equibiaxial(stretch)


def pressure_virtual_work(u: Expr, v: Expr, frame: tuple[Expr, Expr], pressure: Expr) -> Expr:
    """p (F t1 x F t2) . v = p n . v da/dA, the follower pressure's virtual work density per reference area
    (a residual term; no potential in general, see ``enclosed_volume``)."""
    F = membrane_deformation_gradient(u, frame)
    return pressure * ufl.dot(ufl.cross(F[:, 0], F[:, 1]), v)


def enclosed_volume(u: Expr, frame: tuple[Expr, Expr], x_ref: Expr) -> Expr:
    """(1/3) x . (F t1 x F t2), x = X + u: integrated over a closed reference surface (normal outward) it is the
    enclosed volume V(x); its derivative in direction v is the follower work int n . v da (module docstring)."""
    F = membrane_deformation_gradient(u, frame)
    return ufl.dot(x_ref + u, ufl.cross(F[:, 0], F[:, 1])) / 3.0
