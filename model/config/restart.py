"""What a restart (``python -m model run CONFIG --restart DIR``) may change of the run it continues, and the check.

A restart continues the same problem from its last checkpoint, so everything that decides the solution path must
be what the earlier run had: the mesh, the discretization, the materials and their fields (fibres, activation),
bones and contacts, the loads (boundary conditions, body forces, [loading] but max_cutbacks and max_steps, [dynamics]),
[parameters], [units] and the probes (the summary's steps of both runs must report the same quantities). Only
the keys of MAY_CHANGE may differ: ``output.*`` (what is written), ``solver.*`` (how each step is solved: method,
tangent, linear solver, matrix, PETSc options and tolerances), ``loading.max_cutbacks`` and ``loading.max_steps``
(when the stepping gives up; the steps it converges are the same).

The comparison is key by key, between the configuration documents after overrides (``config.document``, which
summary.json records as "config"), so a refusal names the first key that differs, in the order of this run's
document (then the keys only the earlier run has). The documents are compared as written: a key given in one and
left out of the other differs, even when the value given is the default. A string naming a file (the documents
hold files made absolute: ``mesh.file``, a law's ``FILE.py:FUNCTION``, ...) is compared by the SHA-256 of the
file's contents, recorded in summary.json's checkpoint record ("problem": {"files": {key: digest}}): a file moved
with the same contents is the same, a file changed on disk under the same name differs. A checkpoint written
before that record existed has its files compared by name only (``same_problem`` returns a warning saying so).

No dolfinx here: the check runs before the mesh is built.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

#: the keys (dotted prefixes) a restart may change
MAY_CHANGE = ("output", "solver", "loading.max_cutbacks", "loading.max_steps")

#: the end of a refusal's message
RULE = ("a restart continues the same problem (only output.*, solver.*, loading.max_cutbacks and loading.max_steps "
        "may change)")

_ABSENT = object()


def _dotted(path: tuple[str | int, ...]) -> str:
    return ".".join(str(p) for p in path)


def may_change(path: tuple[str | int, ...]) -> bool:
    """Whether a restart may change the key at ``path`` (a key of MAY_CHANGE or below one)."""
    dotted = _dotted(path)
    return any(dotted == k or dotted.startswith(k + ".") for k in MAY_CHANGE)


def _file(value: Any) -> Path | None:
    """The file an absolute path string names ("FILE.py:FUNCTION": FILE.py), when it is one."""
    if not isinstance(value, str):
        return None
    head, sep, _ = value.rpartition(":")
    path = Path(head if sep and head.endswith(".py") else value)
    try:
        return path if path.is_absolute() and path.is_file() else None
    except OSError:  # a name too long, ...
        return None


def _sha256(path: Path) -> str | None:
    digest = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                digest.update(block)
    except OSError:
        return None
    return digest.hexdigest()


def file_digests(document: dict[str, Any] | None) -> dict[str, str]:
    """The SHA-256 of the contents of every file a key a restart may not change names, by its dotted key: the
    checkpoints' record of them ("problem": {"files": ...})."""
    digests: dict[str, str] = {}

    def walk(value: Any, path: tuple[str | int, ...]) -> None:
        if may_change(path):
            return
        if isinstance(value, dict):
            for k, v in value.items():
                walk(v, (*path, k))
        elif isinstance(value, list):
            for i, v in enumerate(value):
                walk(v, (*path, i))
        else:
            file = _file(value)
            digest = _sha256(file) if file is not None else None
            if digest is not None:
                digests[_dotted(path)] = digest

    walk(document or {}, ())
    return digests


def _show(value: Any) -> str:
    """A value for the message: a string whole (a file's path is useless cut), anything else cut at 80 characters."""
    text = repr(value) if isinstance(value, float) else json.dumps(value)
    return text if len(text) <= 80 or isinstance(value, str) and len(text) <= 1000 else text[:77] + "..."


def first_difference(here: Any, there: Any, digests_here: dict[str, str],
                     digests_there: dict[str, str] | None) -> str | None:
    """The first key a restart may not change whose value differs between this run's document ``here`` and the
    earlier run's ``there``, as "KEY is A here, B in the run being continued" (None: no such key). Tables and
    arrays of tables are compared key by key and entry by entry, other arrays (a point, mesh.cells) as one value.
    Files by the digests of their contents where both runs recorded them (``digests_there`` None: by name)."""

    def differ(a: Any, b: Any, path: tuple[str | int, ...]) -> str | None:
        if may_change(path):
            return None
        if isinstance(a, dict) and isinstance(b, dict):
            keys: list[str | int] = [*a, *(k for k in b if k not in a)]
            return next(filter(None, (differ(a.get(k, _ABSENT), b.get(k, _ABSENT), (*path, k)) for k in keys)), None)
        if isinstance(a, list) and isinstance(b, list) and any(isinstance(v, dict) for v in (*a, *b)):  # tables
            items = range(max(len(a), len(b)))
            return next(filter(None, (differ(a[i] if i < len(a) else _ABSENT, b[i] if i < len(b) else _ABSENT,
                                             (*path, i)) for i in items)), None)
        key = _dotted(path)
        if digests_there is not None and key in digests_here and key in digests_there:
            if digests_here[key] == digests_there[key]:
                return None
            return f"{key}: the contents of {_file(a)} differ from the run being continued's (SHA-256)"
        if a is not _ABSENT and b is not _ABSENT and a == b and isinstance(a, bool) == isinstance(b, bool):
            return None
        mine = "is not given" if a is _ABSENT else f"is {_show(a)}"
        theirs = "not given" if b is _ABSENT else _show(b)
        return f"{key} {mine} here, {theirs} in the run being continued"

    return differ(here, there, ())


def same_problem(document: dict[str, Any] | None, digests: dict[str, str],
                 earlier: dict[str, Any]) -> tuple[str | None, str | None]:
    """Whether this configuration (its ``document`` and file ``digests``) continues the problem of the earlier
    run whose summary.json is ``earlier``: (the refusal, without the folder and None when it may go on, a
    warning or None)."""
    there = earlier.get("config")
    if not isinstance(there, dict):
        return f"summary.json has no \"config\" to compare this configuration with; {RULE}", None
    if document is None:
        return f"this configuration has no document to compare (load it with model.load_config); {RULE}", None
    record = earlier.get("checkpoint", {}).get("problem")
    recorded = record.get("files") if isinstance(record, dict) else None
    difference = first_difference(document, there, digests, recorded if isinstance(recorded, dict) else None)
    if difference is not None:
        return f"{difference}; {RULE}", None
    if recorded is None:
        return None, ("the checkpoint has no record of the contents of the files the configuration names (written "
                      "before restarts compared them): files compared by name only")
    return None, None


__all__ = ["MAY_CHANGE", "RULE", "file_digests", "first_difference", "may_change", "same_problem"]
