"""The Guccione law with an active fibre tension Ta, as in problem 3 of the cardiac mechanics benchmark of
Land et al. 2015 (Proc. R. Soc. A 471: 20150641), where Ta rises from 0 to 60 kPa:

    W = (C/2) (exp(Q) - 1) + Ta E_ff,      E_ff = f . E f = (I4 - 1)/2,

Q as in examples/guccione_law.py (the passive law). The active term adds Ta f0 (x) f0 to the second
Piola-Kirchhoff stress S = dW/dE, the benchmark's active stress. Ta is a parameter like the others, so a
configuration may give it as a load curve (examples/guccione_active.toml: Ta = [[0, 0], [1, 1000]]).
"""

import importlib.util
from pathlib import Path

import ufl

# the passive law is examples/guccione_law.py, loaded from beside this file (a law file is loaded by its path)
_spec = importlib.util.spec_from_file_location("guccione_law", Path(__file__).with_name("guccione_law.py"))
passive = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(passive)

PARAMETERS = {
    **passive.PARAMETERS,
    "Ta": {"meaning": "active tension along the fibres", "unit": "Pa (stress)", "bounds": (0, None)},
}
FIELDS = ("a0",)
VOLUMETRIC = "J - 1"
FORMULA = f"{passive.FORMULA} + Ta E_ff"


def psi(F, *, C=2000.0, bf=8.0, bt=2.0, bfs=4.0, Ta=0.0, a0=None):
    """(C/2)(exp(Q) - 1) + Ta E_ff in the fibre frame of a0 (module docstring)."""
    f = a0 / ufl.sqrt(ufl.inner(a0, a0))
    E_ff = ufl.inner(f, 0.5 * (F.T * F - ufl.Identity(3)) * f)
    return passive.psi(F, C=C, bf=bf, bt=bt, bfs=bfs, a0=a0) + Ta * E_ff
