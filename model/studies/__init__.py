"""Studies of many runs: parameter sweeps (model.studies.sweep) and the child-process runner they use
(model.studies.runs). ``sweep(config, {key: [values]}, jobs=1, mode="grid", out=DIR)`` -> DataFrame."""

from model.studies.sweep import sweep

__all__ = ["sweep"]
