"""The ``verify`` tool's names under their former module (model.verify.reference), imported on first
use: the code lives in evaluator (ReferenceEvaluator, reference), samples, emitter, checker and report."""

from __future__ import annotations

from typing import Any


def __getattr__(name: str) -> Any:
    import model.verify

    return getattr(model.verify, name)
