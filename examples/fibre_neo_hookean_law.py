"""A fibre-reinforced neo-Hookean energy of a user's own (the forms/user_law.py contract), used by
examples/verify_diagnosis.py and tests/planted_bugs.py.

    W = (mu/2)(I1 - 3) - mu ln J + (lmbda/2)(ln J)^2 + k1/(2 k2) (exp(k2 (I4 - 1)^2) - 1),

I1 = tr(F^T F), J = det F, I4 = a0 . C a0 with the unit fibre direction a0 (a field per sample). The fibre term
acts in tension and in compression (no switch), so that psi is smooth everywhere: no breakpoint at I4 = 1.
"""

import ufl

PARAMETERS = {
    "mu": {"meaning": "shear modulus", "unit": "Pa (stress)", "bounds": (0, None), "exclusive": True},
    "lmbda": {"meaning": "Lame's first parameter", "unit": "Pa (stress)", "bounds": (0, None)},
    "k1": {"meaning": "fibre stiffness", "unit": "Pa (stress)", "bounds": (0, None)},
    "k2": {"meaning": "fibre exponent", "unit": "dimensionless", "bounds": (0, None), "exclusive": True},
}
FIELDS = ("a0",)
FORMULA = "(mu/2)(I1 - 3) - mu ln J + (lmbda/2)(ln J)^2 + k1/(2 k2)(exp(k2 (I4 - 1)^2) - 1)"


def psi(F, *, mu=3.0, lmbda=7.0, k1=2.0, k2=0.1, a0=None):
    """W(F) of the module docstring."""
    C = F.T * F
    J = ufl.det(F)
    I4 = ufl.inner(a0, C * a0)
    isotropic = 0.5 * mu * (ufl.tr(C) - 3.0) - mu * ufl.ln(J) + 0.5 * lmbda * ufl.ln(J) ** 2
    return isotropic + k1 / (2.0 * k2) * (ufl.exp(k2 * (I4 - 1.0) ** 2) - 1.0)
