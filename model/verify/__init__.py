"""The checker of hand-derived formulas: UFL reference values of psi, P and A (emit), comparisons
with a user's own values (check, a Python API and ``verify check``), and the formulas printed in the
seed documents (seeds).

Modules: evaluator (ReferenceEvaluator: the UFL reference), samples (F and field samples), emitter
(emit), checker (check, compare), report (Report, CheckRow), layouts (tangent layouts and stress
measures), files (.npz, .npy directory, CSV, JSON), element (a user's element vector and stiffness),
seeds (the seed documents' formulas), commands (the command line). The names below are imported on
first use, so that the command line's parser does not load dolfinx.
"""

from __future__ import annotations

import importlib
from typing import Any

_HOME = {
    "QUANTITIES": "evaluator", "ReferenceEvaluator": "evaluator", "reference": "evaluator",
    "deformation_samples": "samples", "field_samples": "samples",
    "emit": "emitter",
    "check": "checker", "check_file": "checker", "compare": "checker", "load_for_check": "checker",
    "CheckRow": "report", "Report": "report", "format_rows": "report",
}

__all__ = sorted(_HOME)


def __getattr__(name: str) -> Any:
    if name not in _HOME:
        raise AttributeError(f"module 'model.verify' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"model.verify.{_HOME[name]}"), name)
    globals()[name] = value
    return value
