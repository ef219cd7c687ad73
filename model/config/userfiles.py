"""Python files a configuration names: "path/to/file.py:function" (shape targets S(x, t), user laws).

Paths are relative to the configuration file's folder. The file is imported once per call, as a
module of its own; nothing else of the project is imported here (no dolfinx).
"""

from __future__ import annotations

import importlib.util
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any


def load_function(spec: str, base: Path) -> Callable[..., Any]:
    """The function named by "path/to/file.py:name" (path relative to ``base``); ValueError otherwise."""
    path_text, sep, name = spec.rpartition(":")
    if not sep or not path_text or not name:
        raise ValueError(f"{spec!r}: write FILE.py:FUNCTION")
    path = Path(path_text)
    if not path.is_absolute():
        path = base / path
    if not path.is_file():
        raise ValueError(f"no such file: {path}")
    module_spec = importlib.util.spec_from_file_location(f"_user_{path.stem}", path)
    assert module_spec is not None and module_spec.loader is not None
    module = importlib.util.module_from_spec(module_spec)
    sys.modules[module_spec.name] = module  # dataclasses in the file look their module up here
    module_spec.loader.exec_module(module)
    function = getattr(module, name, None)
    if not callable(function):
        raise ValueError(f"{path} has no function {name!r}")
    return function
