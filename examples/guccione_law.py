"""Transversely isotropic Guccione law, as in the cardiac mechanics benchmark of Land et al. 2015.

    W = (C/2) (exp(Q) - 1),
    Q = bf E11^2 + bt (E22^2 + E33^2 + 2 E23^2) + 2 bfs (E12^2 + E13^2),

E = (F^T F - I)/2 the Green-Lagrange strain in the frame (f, s, n) of the fibre direction f = a0.
Only f is needed: with E_ff = f.E f and |E f|^2 = E_ff^2 + E_fs^2 + E_fn^2,

    E12^2 + E13^2 = |E f|^2 - E_ff^2,
    E22^2 + E33^2 + 2 E23^2 = E:E - E_ff^2 - 2 (E12^2 + E13^2),

so Q does not depend on how the cross-fibre directions s, n are chosen.

Land et al. 2015 (Proc. R. Soc. A 471: 20150641): C = 2 kPa, bf = 8, bt = 2, bfs = 4, incompressible.
Use it as ``law = "guccione_law.py:psi"`` with ``kappa = inf`` and the mixed formulation for exact
incompressibility, or a finite ``kappa`` for the penalty (kappa/2)(J - 1)^2 (forms/user_law.py).
Any consistent units: C in Pa with lengths in m, or in kPa with lengths in mm and pressures in kPa.
"""

import ufl

PARAMETERS = {
    "C": {"meaning": "stiffness scale", "unit": "Pa (stress)", "bounds": (0, None), "exclusive": True},
    "bf": {"meaning": "fibre-direction exponent coefficient", "unit": "dimensionless", "bounds": (0, None)},
    "bt": {"meaning": "cross-fibre (transverse) exponent coefficient", "unit": "dimensionless",
           "bounds": (0, None)},
    "bfs": {"meaning": "fibre-sheet/fibre-normal shear exponent coefficient", "unit": "dimensionless",
            "bounds": (0, None)},
}
FIELDS = ("a0",)
VOLUMETRIC = "J - 1"
FORMULA = "(C/2)(exp(Q) - 1), Q = bf E11^2 + bt (E22^2 + E33^2 + 2 E23^2) + 2 bfs (E12^2 + E13^2)"


def psi(F, *, C=2000.0, bf=8.0, bt=2.0, bfs=4.0, a0=None):
    """(C/2)(exp(Q) - 1) in the fibre frame of a0 (module docstring)."""
    E = 0.5 * (F.T * F - ufl.Identity(3))
    f = a0 / ufl.sqrt(ufl.inner(a0, a0))
    Ef = E * f
    E_ff = ufl.inner(f, Ef)
    fibre_shear = ufl.inner(Ef, Ef) - E_ff**2  # E12^2 + E13^2
    transverse = ufl.inner(E, E) - E_ff**2 - 2.0 * fibre_shear  # E22^2 + E33^2 + 2 E23^2
    Q = bf * E_ff**2 + bt * transverse + 2.0 * bfs * fibre_shear
    return 0.5 * C * (ufl.exp(Q) - 1.0)
