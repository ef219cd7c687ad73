"""The Guccione law with an active fibre tension Ta, as in problem 3 of the cardiac mechanics benchmark of
Land et al. 2015 (Proc. R. Soc. A 471: 20150641), where Ta rises from 0 to 60 kPa:

    W = (C/2) (exp(Q) - 1) + Ta E_ff,      E_ff = f . E f = (I4 - 1)/2,

Q as in examples/guccione_law.py (the passive law). The active term adds Ta f0 (x) f0 to the second
Piola-Kirchhoff stress S = dW/dE, the benchmark's active stress. Ta is a parameter like the others, so a
configuration may give it as a load curve (examples/guccione_active.toml: Ta = [[0, 0], [1, 1000]]).
"""

import ufl

PARAMETERS = {
    "C": {"meaning": "stiffness scale", "unit": "Pa (stress)", "bounds": (0, None), "exclusive": True},
    "bf": {"meaning": "fibre-direction exponent coefficient", "unit": "dimensionless", "bounds": (0, None)},
    "bt": {"meaning": "cross-fibre (transverse) exponent coefficient", "unit": "dimensionless",
           "bounds": (0, None)},
    "bfs": {"meaning": "fibre-sheet/fibre-normal shear exponent coefficient", "unit": "dimensionless",
            "bounds": (0, None)},
    "Ta": {"meaning": "active tension along the fibres", "unit": "Pa (stress)", "bounds": (0, None)},
}
FIELDS = ("a0",)
VOLUMETRIC = "J - 1"
FORMULA = "(C/2)(exp(Q) - 1) + Ta E_ff, Q = bf E11^2 + bt (E22^2 + E33^2 + 2 E23^2) + 2 bfs (E12^2 + E13^2)"


def psi(F, *, C=2000.0, bf=8.0, bt=2.0, bfs=4.0, Ta=0.0, a0=None):
    """(C/2)(exp(Q) - 1) + Ta E_ff in the fibre frame of a0 (module docstring)."""
    E = 0.5 * (F.T * F - ufl.Identity(3))
    f = a0 / ufl.sqrt(ufl.inner(a0, a0))
    Ef = E * f
    E_ff = ufl.inner(f, Ef)
    fibre_shear = ufl.inner(Ef, Ef) - E_ff**2  # E12^2 + E13^2
    transverse = ufl.inner(E, E) - E_ff**2 - 2.0 * fibre_shear  # E22^2 + E33^2 + 2 E23^2
    Q = bf * E_ff**2 + bt * transverse + 2.0 * bfs * fibre_shear
    return 0.5 * C * (ufl.exp(Q) - 1.0) + Ta * E_ff
