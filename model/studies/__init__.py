"""Studies over many runs: parameter sweeps (model.studies.sweep, with the child-process runner of
model.studies.runs) and mesh-convergence studies (model.studies.convergence).

    sweep(config, {key: [values]}, jobs=1, mode="grid", out=DIR)           -> pandas DataFrame
    converge(config, refine={key: [values]}, qois=[...], out=DIR)          -> ConvergenceStudy

The names are imported on first use, so that the command line's parser does not load pandas or dolfinx.
"""

from __future__ import annotations

import importlib
from typing import Any

_HOME = {"sweep": "sweep", "converge": "convergence", "ConvergenceStudy": "convergence"}

__all__ = sorted(_HOME)


def __getattr__(name: str) -> Any:
    if name not in _HOME:
        raise AttributeError(f"module 'model.studies' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"model.studies.{_HOME[name]}"), name)
    globals()[name] = value
    return value
