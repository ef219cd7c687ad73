"""Overrides of a configuration's keys by dotted paths: ``material.0.E=2e5``, ``loading.steps=20``.

A path names tables by key and arrays of tables by index (``boundary.3.value``); ``material[0].E``
(the form error messages use) is accepted too. From the command line the value is TOML
(``--set 'boundary.0.value=[0.1]'``, ``--set output.png=false``); a bare word that is not TOML is
taken as a string (``--set material.0.law=stvk``). The overridden document is then checked exactly
like a file, so a bad value gets the same one-line error naming the key.
"""

from __future__ import annotations

import copy
import re
import tomllib
from collections.abc import Mapping
from typing import Any

from model.errors import ConfigError


def split_path(path: str) -> list[str | int]:
    """"material.0.E" or "material[0].E" -> ["material", 0, "E"]."""
    parts: list[str | int] = []
    for part in re.sub(r"\[(\d+)\]", r".\1", path.strip()).split("."):
        if not part:
            raise ConfigError(f"{path}: not a dotted key (e.g. material.0.E)")
        parts.append(int(part) if part.isdigit() else part)
    return parts


def parse_value(text: str) -> Any:
    """A command-line value as TOML (numbers, booleans, strings in quotes, arrays, inline tables); a bare
    word that is not TOML is a string."""
    try:
        return tomllib.loads(f"value = {text}")["value"]
    except tomllib.TOMLDecodeError:
        if re.fullmatch(r"[A-Za-z_][\w./:-]*", text.strip()):
            return text.strip()
        raise ConfigError(f"cannot read the value {text!r} (write it as TOML: 1e5, true, \"text\", [1, 2])") from None


def parse_assignment(text: str) -> tuple[str, Any]:
    """"KEY=VALUE" (VALUE as TOML) -> (KEY, value)."""
    key, sep, value = text.partition("=")
    if not sep or not key.strip():
        raise ConfigError(f"--set {text!r}: write KEY=VALUE, e.g. material.0.E=2e5")
    return key.strip(), parse_value(value)


def apply(raw: Mapping[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    """A copy of the parsed TOML document ``raw`` with each dotted path set to its value.

    Missing tables are created (``solver.petsc_options.ksp_type``); an index must name an existing
    entry of an array, or the next one (which appends a table).
    """
    out = copy.deepcopy(dict(raw))
    for path, value in overrides.items():
        parts = split_path(path)
        node: Any = out
        for i, part in enumerate(parts):
            where = ".".join(str(p) for p in parts[: i + 1])
            last = i == len(parts) - 1
            if isinstance(part, int):
                if not isinstance(node, list):
                    raise ConfigError(f"{where}: {'.'.join(str(p) for p in parts[:i])} is not an array of tables")
                if part > len(node):
                    raise ConfigError(f"{where}: index {part} is out of range (the array has {len(node)} entries)")
                if part == len(node):
                    node.append({})
                if last:
                    node[part] = value
                else:
                    node = node[part]
                continue
            if not isinstance(node, dict):
                raise ConfigError(f"{where}: {'.'.join(str(p) for p in parts[:i])} is not a table")
            if last:
                node[part] = value
            else:
                node = node.setdefault(part, [] if isinstance(parts[i + 1], int) else {})
    return out
