"""Overrides of a configuration's keys by dotted paths: ``material.0.E=2e5``, ``loading.steps=20``.

A path names tables by key and arrays by index (``boundary.3.value``, ``mesh.size.0``); ``material[0].E``
(the form error messages use) is accepted too. From the command line (``run --set KEY=VALUE``, repeatable)
the value is TOML (``--set 'boundary.0.value=[0.1]'``, ``--set output.png=false``); a bare word that is
not TOML is taken as a string (``--set material.0.law=stvk``) and then checked like any other value.

A key the file does not have but the schema allows is created, with the tables above it
(``--set solver.linear=iterative`` on a file without [solver]); an index may name an entry of an array
or the next one, which appends it (``material.1={...}``). The overridden document is then checked
exactly like a file, so a bad value gets the same one-line error naming the key. Errors of the path
itself (ConfigError, one line, the key as the file's errors write it, e.g. ``material[5].E``):

    missing "=", empty key, the same key twice, a value that is not TOML, an index out of range,
    an index into a table, a key into an array or into a value.

``resolved(raw, base)`` is the document summary.json records as "config": JSON types, and every
string that names an existing file relative to the configuration's folder (``mesh.file``, a law's
``FILE.py:FUNCTION`` ...) made absolute.
"""

from __future__ import annotations

import copy
import datetime
import re
import tomllib
import types
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, Union, get_origin

from pydantic import BaseModel

from model.config.base import format_key, locate
from model.errors import ConfigError

#: what a bare (unquoted) word may be: no spaces, quotes, brackets, braces, commas, "=" or "#"
_BARE = re.compile(r"[^\s\"'\[\]{},=#]+")
_EXAMPLE = "e.g. material.0.E=2e5"


def split_path(path: str) -> list[str | int]:
    """"material.0.E" or "material[0].E" -> ["material", 0, "E"] (indices may be negative: "-1" -> -1)."""
    text = path.strip()
    if not text:
        raise ConfigError(f"--set {path!r}: the key is empty (write KEY=VALUE, {_EXAMPLE})")
    parts: list[str | int] = []
    for part in re.sub(r"\[(-?\d+)\]", r".\1", text).split("."):
        part = part.strip()
        if not part:
            raise ConfigError(f"{text}: empty part in the dotted key (write it like material.0.E)")
        parts.append(int(part) if re.fullmatch(r"-?\d+", part) else part)
    return parts


def split_values(text: str) -> list[str]:
    """"1e4,2e4" -> ["1e4", "2e4"]; commas inside brackets, braces or quotes belong to the value:
    "[0.1,0],[0.2,0]" -> ["[0.1,0]", "[0.2,0]"]."""
    parts, depth, quote, current = [], 0, "", []
    for ch in text:
        if quote:
            if ch == quote:
                quote = ""
        elif ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append("".join(current).strip())
            current = []
            continue
        current.append(ch)
    parts.append("".join(current).strip())
    return parts


def parse_value(text: str, key: str | None = None) -> Any:
    """A command-line value as TOML (numbers, booleans, strings in quotes, arrays, inline tables); a bare
    word that is not TOML (no spaces, quotes, brackets, commas) is a string. ``key`` names the error."""
    where = f"{key}: " if key else ""
    if not text.strip():
        raise ConfigError(f"{where}no value after \"=\" (write KEY=VALUE, {_EXAMPLE})")
    shown = repr(text) if len(text) <= 80 else f"{text[:60]!r}... ({len(text)} characters)"
    try:
        return tomllib.loads(f"value = {text}")["value"]
    except RecursionError:
        raise ConfigError(f"{where}cannot read the value {shown} as TOML: arrays or tables nested too deeply") from None
    except tomllib.TOMLDecodeError:
        if _BARE.fullmatch(text.strip()):
            return text.strip()
        raise ConfigError(f"{where}cannot read the value {shown} as TOML (write it like 1e5, true, \"text\", "
                          "[1, 2] or {a = 1})") from None


def parse_assignment(text: str) -> tuple[str, Any]:
    """"KEY=VALUE" (VALUE as TOML) -> (KEY, value)."""
    key, sep, value = text.partition("=")
    if not sep:
        raise ConfigError(f"--set {text!r}: no \"=\" (write KEY=VALUE, {_EXAMPLE})")
    if not key.strip():
        raise ConfigError(f"--set {text!r}: the key is empty (write KEY=VALUE, {_EXAMPLE})")
    key = key.strip()
    return key, parse_value(value, format_key(split_path(key)))


def parse_assignments(texts: Iterable[str]) -> dict[str, Any]:
    """The command line's ``--set KEY=VALUE`` arguments as overrides {KEY: value}, in their order; the same
    key given twice (also as ``material[0].E`` and ``material.0.E``, or inside a table given whole) is an
    error."""
    out: dict[str, Any] = {}
    for text in texts:
        key, value = parse_assignment(text)
        _check_unique([*out, key])
        out[key] = value
    return out


def _check_unique(keys: Iterable[str]) -> None:
    """ConfigError when two of the dotted ``keys`` name the same key, or one lies inside the other."""
    seen: dict[tuple[str | int, ...], str] = {}
    for key in keys:
        parts = tuple(split_path(key))
        for other, text in seen.items():
            short, long = sorted((parts, other), key=len)
            if long[: len(short)] == short:
                inside = "" if len(short) == len(long) else f" (inside {format_key(list(short))}, given whole)"
                raise ConfigError(f"{format_key(list(long))}: given twice{inside}: {text!r} and {key!r}")
        seen[parts] = key


def _expects(schema: Any, document: Any, parts: list[str | int]) -> str | None:
    """What the schema wants at ``parts`` of ``document``: "array", "table" or None (a value, or unknown)."""
    try:
        spot = locate(schema, document, (), tuple(parts))
    except (KeyError, IndexError, TypeError, AttributeError):
        return None
    tp = spot.annotation
    if get_origin(tp) in (tuple, list):
        return "array"
    if get_origin(tp) in (dict, Union, types.UnionType) or isinstance(tp, type) and issubclass(tp, BaseModel):
        return "table"
    return None


def _keys(schema: Any, document: Any, parts: list[str | int]) -> list[str]:
    """The keys the schema allows in the table at ``parts`` of ``document`` (empty when unknown)."""
    try:
        tp = locate(schema, document, (), tuple(parts)).annotation
    except (KeyError, IndexError, TypeError, AttributeError):
        return []
    return sorted(tp.toml_keys()) if isinstance(tp, type) and hasattr(tp, "toml_keys") else []


def _entries(n: int) -> str:
    return f"{n} {'entry' if n == 1 else 'entries'}"


def apply(raw: Mapping[str, Any], overrides: Mapping[str, Any], schema: Any = None) -> dict[str, Any]:
    """A copy of the parsed TOML document ``raw`` with each dotted path set to its value.

    Missing tables and arrays are created (``solver.petsc_options.ksp_type``; which of the two, from
    ``schema``, the RunConfig by default); an index must name an existing entry of an array (negative:
    from the end) or the next one (which appends it). ConfigError naming the key otherwise.
    """
    if schema is None:
        from model.config.document import RunConfig

        schema = RunConfig
    _check_unique(overrides)
    out = copy.deepcopy(dict(raw))
    for path, value in overrides.items():
        parts = split_path(path)
        name = format_key(parts)
        node: Any = out
        for i, part in enumerate(parts):
            above, last = format_key(parts[:i]), i == len(parts) - 1
            if isinstance(part, int):
                if isinstance(node, dict):
                    keys = _keys(schema, out, parts[:i]) or list(map(str, node))
                    allowed = f" ({', '.join(keys)})" if keys else ""
                    raise ConfigError(f"{name}: {above} is a table, not an array: name one of its keys{allowed} "
                                      "instead of an index")
                if not isinstance(node, list):
                    raise ConfigError(f"{name}: {above} is a value ({node!r}), not an array")
                n = len(node)
                if not -n <= part <= n:
                    raise ConfigError(f"{name}: index {part} is out of range: {above} has {_entries(n)} "
                                      f"(indices 0 to {n - 1}, or {n} to append one)" if n else
                                      f"{name}: index {part} is out of range: {above} is empty (0 appends an entry)")
                if part == n:
                    node.append(None)
                key: str | int = part % n if part < 0 else part
            else:
                if isinstance(node, list):
                    dotted = ".".join(map(str, parts[:i]))
                    raise ConfigError(f"{name}: {above} is an array of {_entries(len(node))}, not a table: give an "
                                      f"index, e.g. {dotted}.0.{'.'.join(map(str, parts[i:]))}")
                if not isinstance(node, dict):
                    raise ConfigError(f"{name}: {above} is a value ({node!r}), not a table")
                key = part
            if last:
                node[key] = value
                break
            child = node[key] if (isinstance(node, dict) and key in node) or isinstance(node, list) else None
            if child is None:  # create what the schema has there (a table unless it says array)
                want = _expects(schema, out, parts[: i + 1])
                child = [] if want == "array" or (want is None and isinstance(parts[i + 1], int)) else {}
                node[key] = child
            node = child
    return out


def resolved(raw: Mapping[str, Any], base: Path) -> dict[str, Any]:
    """The document as JSON types (TOML dates as ISO strings), every string naming an existing file relative to
    ``base`` (also "FILE.py:FUNCTION") made absolute: what summary.json records as "config"."""

    def file(text: str) -> str:
        path_text, sep, function = text.rpartition(":") if text.count(":") == 1 else ("", "", "")
        candidate = path_text if sep and path_text.endswith(".py") else text
        if not ("/" in candidate or Path(candidate).suffix) or Path(candidate).is_absolute():
            return text
        path = (Path(base) / candidate).resolve()
        if not path.is_file():
            return text
        return f"{path}:{function}" if candidate is not text else str(path)

    def walk(value: Any) -> Any:
        if isinstance(value, Mapping):
            return {str(k): walk(v) for k, v in value.items()}
        if isinstance(value, (list, tuple)):
            return [walk(v) for v in value]
        if isinstance(value, str):
            return file(value)
        if isinstance(value, (datetime.date, datetime.time)):
            return value.isoformat()
        return value

    return walk(raw)


__all__ = ["apply", "parse_assignment", "parse_assignments", "parse_value", "resolved", "split_path", "split_values"]
