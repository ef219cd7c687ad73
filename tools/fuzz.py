"""Fuzz the command line with mutated inputs: every bad input must be refused in one line, nothing may crash.

``python tools/fuzz.py --cases 500 --seed 1 --jobs 2 --out fuzz.json`` mutates the shipped examples
(examples/*.toml) and the command line, runs each case as ``python -m model run ...`` in a subprocess of its
own with a timeout, and classifies what happened:

    one-line error    exit 2, stderr's only error line "error: KEY: ..." (log warnings before it allowed)
    usage error       exit 2 from argparse (its usage line and "python -m model run: error: ...")
    traceback         a Python traceback or a PETSc error dump on stderr, whatever the exit code
    hang              still running at the timeout (killed)
    crash             killed by a signal (segmentation fault, abort ...)
    silent exit 0 on bad input   exit 0 on a mutation that must be refused
    ran               exit 0 on a mutation that is valid (or may be)
    solve failed      exit 1 with a one-line reason
    unclear exit      anything else (an exit code or stderr that fits none of the above)

Each mutation says whether it is a bad input (must be refused), a valid one (may run) or either (a value that
may be legal for its key, e.g. 0 or 1e308 for a modulus; refused or run are both fine). Only the small examples
(SMALL) get mutations that may run, always with one load step and no picture or time series, so a case takes
seconds. The mutation kinds:

    type        a value of the wrong type (a string for a number, a number for a table ...)
    range       0, -1, NaN, +-inf, +-1e308, 1e-308, +-2**63 in place of a number
    count       absurd counts: loading.steps, max_cutbacks, max_steps, mesh cells
    name        misspelt keys, unknown keys and sections, misspelt names (laws, boundaries, regions, kinds)
    removed     a key or a section removed (required ones must be refused)
    mesh        mesh.file missing, empty, binary, not UTF-8, of another format, a surface, a folder
    config      the configuration file missing, empty, binary, not UTF-8, UTF-16, another format, deeply nested
    cli         unknown options, --out naming a file, --set with bad syntax, --restart of nothing
    expression  deep and long expressions (5000 terms, 5000 parentheses), forbidden constructs
    valid       mutations that must run (another modulus, a probe more, steps = 2)

Exit code 1 when any case is a traceback, a hang, a crash or a silent exit 0 on bad input (each is listed with
its command line, runnable from the repository root); 0 otherwise. ``--out`` writes every case as JSON.
tests/test_fuzz.py runs a fixed-seed sample of cases that fail before any solve.
"""

from __future__ import annotations

import argparse
import collections
import json
import math
import os
import random
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import tomllib
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from model.studies.runs import toml_text, toml_value  # the TOML writer of sweeps (no dolfinx)

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
#: examples that run in seconds with one load step: the only ones given mutations that may run
SMALL = ("uniaxial", "cook", "twisting_bar", "guccione_beam", "contact_block")
#: appended to a solid run: one load step, no picture or time series (keeps a case that runs short)
SHORT = ("--set", "loading.steps=1", "--set", "output.png=false", "--set", "output.vtu=false",
         "--set", "output.xdmf=false")
FAILING = ("traceback", "internal error", "hang", "crash", "silent exit 0 on bad input")
CLASSES = ("one-line error", "usage error", "ran", "solve failed", *FAILING, "unclear exit")
KINDS = ("type", "range", "count", "name", "removed", "mesh", "config", "cli", "expression", "valid")

#: keys whose value names something (a law, a boundary, a region, a kind): a misspelling must be refused
NAME_KEYS = frozenset({"law", "on", "region", "type", "generator", "method", "formulation", "isotropic", "system",
                       "control", "surface", "master", "origin", "insertion", "bone", "linear", "tangent", "scheme",
                       "regions", "file", "volume_boundary", "variant", "matrix"})
#: keys a table cannot do without
REQUIRED = frozenset({"law", "on", "type", "generator", "file", "name", "point", "mesh", "material"})
#: bulk moduli: +inf is the incompressible limit, a legal value
BULK = frozenset({"lmbda", "K", "kappa"})
#: keys that must be positive (0 and negative refused)
POSITIVE = frozenset({"E", "mu", "density", "steps", "cells", "size", "radius", "length", "max_steps",
                      "sigma_max", "c1"})
#: coordinates: +-1e308 and +-2**63 are absurd
COORDINATES = frozenset({"point", "origin", "insertion", "volume_origin", "center", "centre"})
#: free-form tables whose keys and values the schema does not fix
FREE = frozenset({"petsc_options"})


@dataclass
class Case:
    """One mutated run: ``args`` after ``python -m model``; ``files`` written into the case's folder first."""

    id: int
    kind: str
    what: str
    expect: str  # "bad" (must be refused), "valid" (must run), "either"
    args: list[str]
    files: dict[str, bytes] = field(default_factory=dict, repr=False)
    dirs: tuple[str, ...] = ()
    timeout: float = 60.0
    folder: str = ""


@dataclass
class Outcome:
    id: int
    kind: str
    what: str
    expect: str
    outcome: str
    exit_code: int | None
    seconds: float
    command: str
    stderr: str


# --- TOML ------------------------------------------------------------------------------------------------------------

def absolute(raw: Any, base: Path) -> Any:
    """The document with every string that names a file relative to ``base`` made absolute (a written copy of
    an example reads the example's files)."""
    if isinstance(raw, dict):
        return {k: absolute(v, base) for k, v in raw.items()}
    if isinstance(raw, list):
        return [absolute(v, base) for v in raw]
    if isinstance(raw, str) and ("/" in raw or "." in raw) and " " not in raw:
        path_text, sep, function = raw.rpartition(":") if raw.count(":") == 1 else (raw, "", "")
        candidate = base / path_text
        if path_text and candidate.is_file():
            return f"{candidate.resolve()}{sep}{function}"
    return raw


def leaves(node: Any, parts: tuple[str | int, ...] = ()) -> Iterator[tuple[tuple[str | int, ...], Any]]:
    """(path, value) of every value of a document, tables and arrays included (not the root)."""
    if parts:
        yield parts, node
    if isinstance(node, dict):
        for k, v in node.items():
            yield from leaves(v, (*parts, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from leaves(v, (*parts, i))


def dotted(parts: tuple[str | int, ...]) -> str:
    return ".".join(str(p) for p in parts)


def last_name(parts: tuple[str | int, ...]) -> str:
    """The key a path ends in (for an array entry: the array's key)."""
    return next((str(p) for p in reversed(parts) if isinstance(p, str)), "")


def edited(raw: dict[str, Any], parts: tuple[str | int, ...], value: Any = None, *, remove: bool = False,
           rename: str | None = None) -> dict[str, Any]:
    out = json.loads(json.dumps(raw, allow_nan=True))
    node = out
    for p in parts[:-1]:
        node = node[p]
    if remove:
        del node[parts[-1]]
    elif rename is not None:
        node[rename] = node.pop(parts[-1])
    else:
        node[parts[-1]] = value
    return out


def misspell(word: str, rng: random.Random) -> str:
    """A plausible typo of ``word``: two letters swapped, one dropped or doubled (never ``word`` itself)."""
    for _ in range(20):
        i = rng.randrange(len(word)) if word else 0
        choice = rng.randrange(3)
        if choice == 0 and len(word) > 2 and i < len(word) - 1 and word[i] != word[i + 1]:
            typo = word[:i] + word[i + 1] + word[i] + word[i + 2:]
        elif choice == 1 and len(word) > 2:
            typo = word[:i] + word[i + 1:]
        else:
            typo = word[:i + 1] + word[i:i + 1] + word[i + 1:]
        if typo != word and typo:
            return typo
    return word + "x"


# --- the mutations ---------------------------------------------------------------------------------------------------

class Builder:
    """Builds the candidate cases (their arguments name the case's folder "{case}")."""

    def __init__(self, rng: random.Random) -> None:
        self.rng = rng
        self.candidates: dict[str, list[dict[str, Any]]] = collections.defaultdict(list)
        self.examples = {p.stem: tomllib.loads(p.read_text()) for p in sorted(EXAMPLES.glob("*.toml"))}

    def membrane(self, name: str) -> bool:
        return "membrane" in self.examples[name]

    def add(self, kind: str, what: str, expect: str, args: list[str], files: dict[str, bytes] | None = None,
            dirs: tuple[str, ...] = (), example: str | None = None, short: bool = True) -> None:
        """A candidate; ``example``: the shipped example it runs (mutations that may run: small ones only)."""
        if expect != "bad" and example is not None and example not in SMALL:
            return
        if short and (example is None or not self.membrane(example)):
            args = [*args, *SHORT]
        self.candidates[kind].append({"kind": kind, "what": what, "expect": expect, "args": args,
                                      "files": files or {}, "dirs": dirs})

    def run_args(self, example: str, *sets: str) -> list[str]:
        args = ["run", str(EXAMPLES.relative_to(ROOT) / f"{example}.toml")]
        for s in sets:
            args += ["--set", s]
        return [*args, "--out", "{case}/out"]

    def written(self, example: str, raw: dict[str, Any], *extra: str) -> tuple[list[str], dict[str, bytes]]:
        """Arguments running a written copy of an example's (edited) document."""
        text = toml_text(absolute(raw, EXAMPLES))
        return ["run", "{case}/config.toml", *extra, "--out", "{case}/out"], {"config.toml": text.encode()}

    # -- per example --------------------------------------------------------------------------------------------------

    def example_mutations(self, name: str, raw: dict[str, Any]) -> None:
        for parts, value in leaves(raw):
            if any(p in FREE for p in parts) or parts[0] in ("units",):
                continue
            key = last_name(parts)
            where = f"{name}: {dotted(parts)}"
            self.type_mutations(name, parts, value, where)
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                self.range_mutations(name, parts, value, key, where)
            if isinstance(value, str) and key in NAME_KEYS and not isinstance(parts[-1], int) or \
                    isinstance(value, str) and key == "regions":
                typo = misspell(Path(value).name if key == "file" else value, self.rng)
                new = str(Path(value).with_name(typo)) if key == "file" else typo
                args, files = self.written(name, edited(raw, parts, new))
                if key == "file":  # a path: keep it relative to the example's folder, so the file is missing
                    args, files = self.written(name, edited(absolute(raw, EXAMPLES), parts,
                                                            str(EXAMPLES / Path(value).with_name(typo))))
                self.add("name", f"{where} = {new!r} (misspelt)", "bad", args, files, example=name)
            if isinstance(parts[-1], str):
                self.key_mutations(name, raw, parts, key, where)

    def type_mutations(self, name: str, parts: tuple[str | int, ...], value: Any, where: str) -> None:
        if isinstance(value, bool):
            wrong: list[Any] = ["yes", 1]
        elif isinstance(value, (int, float)):
            wrong = ["abc", True, [1.0, 2.0], {"a": 1}]
        elif isinstance(value, str):
            wrong = [12345, True, ["x"], {"a": 1}]
        elif isinstance(value, list):
            wrong = ["abc", 7, {"a": 1}]
        else:
            wrong = [7, "abc", [1, 2]]
        for w in wrong:
            self.add("type", f"{where} = {toml_value(w)}", "bad",
                     self.run_args(name, f"{dotted(parts)}={toml_value(w)}"), example=name)

    def range_mutations(self, name: str, parts: tuple[str | int, ...], value: float, key: str, where: str) -> None:
        integer = isinstance(value, int)
        coordinate = key in COORDINATES
        for new in (0, -1, math.nan, math.inf, -math.inf, 1e308, -1e308, 1e-308, 2**63, -(2**63) - 1):
            if isinstance(new, float) and math.isnan(new):
                expect = "bad"
            elif isinstance(new, float) and math.isinf(new):
                expect = "either" if key in BULK and new > 0 else "bad"
            elif new in (1e308, -1e308, 2**63, -(2**63) - 1):
                expect = "bad" if coordinate or integer else "either"
            elif new in (0, -1):
                expect = "bad" if key in POSITIVE else "either"
            else:
                expect = "either"
            sets = [f"{dotted(parts)}={toml_value(new)}"]
            self.add("range", f"{where} = {toml_value(new)}", expect, self.run_args(name, *sets), example=name,
                     short=parts[:2] != ("loading", "steps"))

    def key_mutations(self, name: str, raw: dict[str, Any], parts: tuple[str | int, ...], key: str,
                      where: str) -> None:
        typo = misspell(key, self.rng)
        args, files = self.written(name, edited(raw, parts, rename=typo))
        self.add("name", f"{where} spelt {typo!r}", "bad", args, files, example=name)
        required = key in REQUIRED and not (key == "type" and parts[0] == "solver")
        args, files = self.written(name, edited(raw, parts, remove=True))
        self.add("removed", f"{where} removed", "bad" if required else "either", args, files, example=name)

    # -- the whole run ------------------------------------------------------------------------------------------------

    def unknown_names(self) -> None:
        for name, raw in self.examples.items():
            tables = [p for p, v in leaves(raw) if isinstance(v, dict) and not any(x in FREE for x in p)]
            for parts in tables:
                key = dotted((*parts, "colour"))
                self.add("name", f"{name}: unknown key {key}", "bad", self.run_args(name, f"{key}=1"), example=name)
            self.add("name", f"{name}: unknown section [colour]", "bad", self.run_args(name, "colour.x=1"),
                     example=name)

    def counts(self) -> None:
        for name in SMALL:
            for key in ("loading.steps", "loading.max_cutbacks", "loading.max_steps"):
                for value in (2**63, 10**9, 10**18):
                    self.add("count", f"{name}: {key} = {value}", "bad", self.run_args(name, f"{key}={value}"),
                             example=name, short=key != "loading.steps")
        for cells in ([10**6, 10**6, 10**6], [2**63, 4, 4], [0, 4, 4], [-4, 4, 4]):
            self.add("count", f"uniaxial: mesh.cells = {cells}", "bad",
                     self.run_args("uniaxial", f"mesh.cells={toml_value(cells)}"), example="uniaxial")
        self.add("count", "uniaxial: discretization.quadrature_degree = 12345", "bad",
                 self.run_args("uniaxial", "discretization.quadrature_degree=12345"), example="uniaxial")

    def meshes(self) -> None:
        raw = self.examples["uniaxial"]
        png = (ROOT / "docs" / "isometric.png").read_bytes()
        files: dict[str, bytes] = {
            "empty.msh": b"", "empty.vtu": b"", "empty.xdmf": b"", "empty.inp": b"", "empty.geo": b"",
            "binary.msh": bytes(self.rng.randrange(256) for _ in range(4096)),
            "binary.vtu": bytes(self.rng.randrange(256) for _ in range(4096)),
            "latin1.msh": "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n3 1 \"muscle\xe9\"\n".encode(
                "latin-1"),
            "latin1.inp": "*NODE\n1, 0.0, 0.0, 0.0 ** \xe9\n".encode("latin-1"),
            "picture.msh": png, "picture.vtu": png, "config.msh": (EXAMPLES / "uniaxial.toml").read_bytes(),
            "surface.obj": (EXAMPLES / "twisting_bar_skin.obj").read_bytes(),
            "surface.stl": b"solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
                           b"endloop\nendfacet\nendsolid s\n",
            "broken.geo": b"Point(1) = {0, 0, 0;\nVolume(1) = {42};\n",
            "truncated.msh": b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 8 1 8\n",
            "text.vtu": b"<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid><Piece NumberOfPoints=\"2\"",
            "nodes_only.inp": b"*NODE\n1, 0, 0, 0\n2, 1, 0, 0\n",
        }
        for file_name, content in files.items():
            doc = edited(raw, ("mesh",), {"file": f"{{case}}/{file_name}"})
            args, config = self.written("uniaxial", doc)
            self.add("mesh", f"uniaxial: mesh.file = {file_name}", "bad", args, {**config, file_name: content})
        for what, path in (("missing", "{case}/missing.msh"), ("a folder", "{case}/folder.msh")):
            doc = edited(raw, ("mesh",), {"file": path})
            args, config = self.written("uniaxial", doc)
            self.add("mesh", f"uniaxial: mesh.file {what}", "bad", args, config,
                     dirs=("folder.msh",) if what == "a folder" else ())
        for name in ("spindle", "thick_sphere", "ventricle"):
            self.add("mesh", f"{name}: mesh.parameters = {{size = 0}}", "bad",
                     self.run_args(name, "mesh.parameters={size = 0}"), example=name)

    def configs(self) -> None:
        text = (EXAMPLES / "uniaxial.toml").read_text()
        deep = "a = " + "[" * 5000 + "]" * 5000 + "\n"
        files = {
            "empty": b"", "binary": bytes(self.rng.randrange(256) for _ in range(2048)),
            "latin1": ("# d\xe9formation\n" + text).encode("latin-1"), "utf16": text.encode("utf-16"),
            "picture": (ROOT / "docs" / "isometric.png").read_bytes(), "json": json.dumps({"mesh": {}}).encode(),
            "gmsh": (EXAMPLES / "spindle.geo").read_bytes(), "truncated": text[: len(text) // 2].encode(),
            "nested arrays": deep.encode(), "nested tables": ("a = " + "{b = " * 3000 + "1" + "}" * 3000).encode(),
            "null bytes": text.encode().replace(b"\n", b"\0\n", 3), "bom": b"\xef\xbb\xbf" + text.encode(),
            "one huge line": ("# " + "x" * 10**6 + "\n" + text).encode(),  # a 1 MB comment: valid TOML
            "dates": (text + "\n[parameters]\nwhen = 1979-05-27\n").encode(),
        }
        for what, content in files.items():
            expect = "valid" if what == "one huge line" else "bad"
            self.add("config", f"config file: {what}", expect,
                     ["run", "{case}/config.toml", "--out", "{case}/out"], {"config.toml": content},
                     short=expect == "valid")
        self.add("config", "config file: missing", "bad", ["run", "{case}/missing.toml", "--out", "{case}/out"],
                 short=False)
        self.add("config", "config file: a folder", "bad", ["run", "{case}/folder.toml", "--out", "{case}/out"],
                 dirs=("folder.toml",), short=False)
        for name, raw in self.examples.items():
            self.add("config", f"{name}: an example missing [mesh]", "bad", *self.written(name, edited(
                raw, ("mesh",), remove=True)) if "mesh" in raw else self.written(name, {**raw, "mesh": 1}),
                example=name)

    def command_lines(self) -> None:
        base = ["run", "examples/uniaxial.toml"]
        out = ["--out", "{case}/out"]
        cases: list[tuple[str, list[str], dict[str, bytes], tuple[str, ...]]] = [
            ("unknown option --outt", [*base, "--outt", "{case}/out"], {}, ()),
            ("unknown option --sett", [*base, "--sett", "loading.steps=1", *out], {}, ()),
            ("two configs", [*base, "examples/cook.toml", *out], {}, ()),
            ("no config", ["run", *out], {}, ()),
            ("unknown command", ["rnu", "examples/uniaxial.toml"], {}, ()),
            ("--out an existing file", [*base, "--out", "{case}/taken"], {"taken": b"x"}, ()),
            ("--out below a file", [*base, "--out", "{case}/taken/out"], {"taken": b"x"}, ()),
            ("--set no =", [*base, "--set", "loading.steps", *out], {}, ()),
            ("--set empty key", [*base, "--set", "=3", *out], {}, ()),
            ("--set empty part", [*base, "--set", "loading..steps=3", *out], {}, ()),
            ("--set not TOML", [*base, "--set", "boundary.0.value=[0.1,", *out], {}, ()),
            ("--set index out of range", [*base, "--set", "material.5.E=1", *out], {}, ()),
            ("--set index into a table", [*base, "--set", "loading.0=1", *out], {}, ()),
            ("--set key into an array", [*base, "--set", "material.E=1", *out], {}, ()),
            ("--set key into a value", [*base, "--set", "loading.steps.x=1", *out], {}, ()),
            ("--set twice", [*base, "--set", "loading.steps=2", "--set", "loading.steps=3", *out], {}, ()),
            ("--set unknown section", [*base, "--set", "colour=1", *out], {}, ()),
            ("--set huge index", [*base, "--set", "material.9223372036854775808.E=1", *out], {}, ()),
            ("--set negative index", [*base, "--set", "material.-5.E=1", *out], {}, ()),
            ("--set 3000 parts", [*base, "--set", ".".join(["a"] * 3000) + "=1", *out], {}, ()),
            ("--set deep array", [*base, "--set", "boundary.0.value=" + "[" * 3000 + "]" * 3000, *out], {}, ()),
            ("--set non-UTF-8 bytes", [*base, "--set", "material.0.law=\udce9", *out], {}, ()),
            ("--restart nothing", [*base, "--restart", "{case}/nothing"], {}, ()),
            ("--restart an empty folder", [*base, "--restart", "{case}/empty"], {}, ("empty",)),
            ("--restart a file", [*base, "--restart", "{case}/taken"], {"taken": b"x"}, ()),
            ("--restart a folder of junk", [*base, "--restart", "{case}/junk"],
             {"junk/summary.json": b"{not json", "junk/checkpoint.h5": b"\x00" * 64}, ()),
            ("--restart and another --out", [*base, "--restart", "{case}/a", "--out", "{case}/b"], {}, ("a",)),
        ]
        for what, args, files, dirs in cases:
            self.add("cli", what, "bad", args, files, dirs, short=False)

    def expressions(self) -> None:
        raw = self.examples["twisting_bar"]
        index = next(i for i, b in enumerate(raw["boundary"]) if "expression" in b)
        texts = {
            "5000 terms": ("bad", " + ".join(["x[0]"] * 5000)),
            "5000 parentheses": ("bad", "(" * 5000 + "x[0]" + ")" * 5000),
            "150 parentheses": ("valid", "(" * 150 + "x[0]" + ")" * 150),
            "5000 minus signs": ("bad", "-" * 5000 + "x[0]"),
            "1000 nested sin": ("bad", "sin(" * 1000 + "x[0]" + ")" * 1000),
            "a 200000-digit number": ("bad", "1" * 200000),
            "9**9**9**9": ("bad", "9**9**9**9"),
            "1/0": ("bad", "1/0"),
            "x[3]": ("bad", "x[3]"),
            "__import__": ("bad", "__import__('os').getcwd()"),
            "attribute": ("bad", "x[0].real"),
            "lambda": ("bad", "(lambda: 1)()"),
            "empty": ("bad", ""),
            "a string": ("bad", "'abc'"),
            "log(-1)": ("either", "log(-1 + 0*x[0])"),
            "50 terms": ("valid", " + ".join(["0*x[0]"] * 50)),
        }
        for what, (expect, text) in texts.items():
            doc = edited(raw, ("boundary", index, "expression", 0), text)
            args, files = self.written("twisting_bar", doc)
            self.add("expression", f"twisting_bar: boundary.{index}.expression.0 = {what}", expect, args, files,
                     example="twisting_bar")

    def valid(self) -> None:
        for name in SMALL:
            raw = self.examples[name]
            material = raw["material"][0]
            for k in ("E", "mu", "c1"):
                if k in material:
                    self.add("valid", f"{name}: material.0.{k} x 2", "valid",
                             self.run_args(name, f"material.0.{k}={toml_value(material[k] * 2)}"), example=name)
            self.add("valid", f"{name}: a probe more", "valid",
                     self.run_args(name, "probe.-1.snap=true") if raw.get("probe") else self.run_args(name),
                     example=name)
            self.add("valid", f"{name}: loading.growth = 2", "valid", self.run_args(name, "loading.growth=2"),
                     example=name)
        self.add("valid", "uniaxial: loading.steps = 2", "valid", self.run_args("uniaxial", "loading.steps=2"),
                 example="uniaxial", short=False)

    def build(self) -> dict[str, list[dict[str, Any]]]:
        for name, raw in self.examples.items():
            self.example_mutations(name, raw)
        self.unknown_names()
        self.counts()
        self.meshes()
        self.configs()
        self.command_lines()
        self.expressions()
        self.valid()
        return self.candidates


def sample(candidates: dict[str, list[dict[str, Any]]], n: int, rng: random.Random,
           bad_only: bool = False) -> list[dict[str, Any]]:
    """``n`` candidates, the kinds taken in turn (each kind's candidates shuffled), so every kind is covered."""
    pools = {}
    for kind in KINDS:
        pool = [c for c in candidates.get(kind, []) if not bad_only or c["expect"] == "bad"]
        rng.shuffle(pool)
        if pool:
            pools[kind] = pool
    chosen: list[dict[str, Any]] = []
    while len(chosen) < n and any(pools.values()):
        for kind in KINDS:
            if pools.get(kind) and len(chosen) < n:
                chosen.append(pools[kind].pop())
    return chosen


def make_cases(n: int, seed: int, work: Path, bad_only: bool = False, timeout: float = 60.0,
               kinds: list[str] | None = None) -> list[Case]:
    """``n`` cases of seed ``seed`` (only ``kinds``, all by default), their files under ``work``."""
    rng = random.Random(seed)
    candidates = Builder(rng).build()
    if kinds:
        candidates = {k: v for k, v in candidates.items() if k in kinds}
    cases = []
    for i, c in enumerate(sample(candidates, n, rng, bad_only)):
        folder = work / f"{i:04d}"
        args = [a.replace("{case}", str(folder)) for a in c["args"]]
        cases.append(Case(i, c["kind"], c["what"], c["expect"], args, c["files"], c["dirs"], timeout, str(folder)))
    return cases


# --- running and classifying -----------------------------------------------------------------------------------------

def environment() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [env.get("PYTHONPATH")])])
    env.update(OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", PYTHONDONTWRITEBYTECODE="1")
    return env


def command(case: Case, python: str = sys.executable) -> list[str]:
    return [python, "-m", "model", *case.args]


def replay(case: Case) -> str:
    """The case's command line, runnable from the repository root."""
    return f"PYTHONPATH=. {shlex.join(['python', '-m', 'model', *case.args])}"


def shown(command_line: str, width: int = 400) -> str:
    """A command line for the screen: a huge one shortened (the JSON report has it whole)."""
    return command_line if len(command_line) <= width else \
        f"{command_line[:width]} ... ({len(command_line)} characters: the whole line is in the --out report)"


def classify(expect: str, code: int | None, stderr: str, timed_out: bool) -> str:
    if timed_out:
        return "hang"
    if code is not None and code < 0:
        return "crash"
    if "Traceback (most recent call last)" in stderr or "PETSC ERROR" in stderr:
        return "traceback"
    lines = [line for line in stderr.splitlines() if line.strip()]
    errors = [line for line in lines if line.startswith("error: ")]
    if code == 3 and any(line.startswith("error: internal error") for line in errors):
        return "internal error"  # a bug the command line caught: its traceback is in a file
    if code == 0:
        return "silent exit 0 on bad input" if expect == "bad" else "ran"
    if code == 2 and len(errors) == 1 and lines[-1] == errors[0]:
        return "one-line error"
    if code == 2 and lines and lines[0].startswith("usage: ") and ": error: " in lines[-1]:
        return "usage error"
    if code == 1 and len(errors) == 1 and lines[-1] == errors[0]:
        return "solve failed"
    return "unclear exit"


def run_case(case: Case, python: str = sys.executable) -> Outcome:
    """Write the case's files, run it, classify what happened."""
    folder = Path(case.folder)
    folder.mkdir(parents=True, exist_ok=True)
    for name, content in case.files.items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_bytes(content)
    for name in case.dirs:
        (folder / name).mkdir(parents=True, exist_ok=True)
    # an argument that is not UTF-8 (a lone surrogate: the bytes the shell would pass) goes as bytes
    args = [a.encode("utf-8", "surrogateescape") for a in command(case, python)]
    start = time.monotonic()
    process = subprocess.Popen(args, cwd=ROOT, env=environment(), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               start_new_session=True)
    timed_out = False
    try:
        _, err = process.communicate(timeout=case.timeout)
    except subprocess.TimeoutExpired:
        timed_out = True
        os.killpg(process.pid, signal.SIGKILL)
        _, err = process.communicate()
    seconds = time.monotonic() - start
    stderr = err.decode("utf-8", "replace")
    outcome = classify(case.expect, process.returncode, stderr, timed_out)
    return Outcome(case.id, case.kind, case.what, case.expect, outcome, None if timed_out else process.returncode,
                   round(seconds, 2), replay(case), stderr[-2000:])


def table(outcomes: list[Outcome]) -> str:
    """Counts per class, and per mutation kind and class."""
    counts = collections.Counter(o.outcome for o in outcomes)
    lines = [f"{len(outcomes)} cases", "", f"{'class':<30} {'cases':>6}"]
    lines += [f"{c:<30} {counts[c]:>6}" for c in CLASSES if counts[c]]
    shown = [c for c in CLASSES if counts[c]]
    short = {c: c.replace("silent exit 0 on bad input", "silent 0").replace("one-line error", "one-line")
             .replace("usage error", "usage").replace("solve failed", "failed").replace("unclear exit", "unclear")
             for c in shown}
    lines += ["", f"{'kind':<12}" + "".join(f"{short[c]:>11}" for c in shown) + f"{'total':>8}"]
    for kind in KINDS:
        mine = [o for o in outcomes if o.kind == kind]
        if mine:
            per = collections.Counter(o.outcome for o in mine)
            lines.append(f"{kind:<12}" + "".join(f"{per[c]:>11}" for c in shown) + f"{len(mine):>8}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=500, help="how many cases (default 500)")
    parser.add_argument("--seed", type=int, default=1, help="the random seed (the same seed, the same cases)")
    parser.add_argument("--jobs", type=int, default=2, help="cases run at the same time (default 2)")
    parser.add_argument("--out", type=Path, default=None, help="write every case and its outcome here (JSON)")
    parser.add_argument("--timeout", type=float, default=60.0, help="seconds before a case is a hang (default 60)")
    parser.add_argument("--work", type=Path, default=None,
                        help="folder of the cases' files and results (default: a temporary folder, removed when "
                             "no case fails)")
    parser.add_argument("--bad-only", action="store_true", help="only mutations that must be refused")
    parser.add_argument("--kind", action="append", choices=KINDS, default=None, help="only these kinds (repeatable)")
    args = parser.parse_args(argv)
    work = args.work or Path(tempfile.mkdtemp(prefix="fuzz-"))
    cases = make_cases(args.cases, args.seed, work, args.bad_only, args.timeout, args.kind)
    print(f"{len(cases)} cases (seed {args.seed}, {args.jobs} jobs, timeout {args.timeout:g} s), files in {work}",
          flush=True)
    outcomes: list[Outcome] = []
    with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        for outcome in pool.map(run_case, cases):
            outcomes.append(outcome)
            if outcome.outcome in FAILING or outcome.outcome == "unclear exit":
                print(f"[{outcome.id:04d}] {outcome.outcome}: {outcome.what}", flush=True)
    print()
    print(table(outcomes))
    failing = [o for o in outcomes if o.outcome in FAILING]
    review = [o for o in outcomes if o.outcome in ("unclear exit", "solve failed") and o.expect == "bad"
              or o.outcome == "one-line error" and o.expect == "valid"]
    for title, group in (("failing", failing), ("to review", review)):
        if group:
            print(f"\n{title}:")
            for o in group:
                last = next((line for line in reversed(o.stderr.splitlines()) if line.strip()), "")
                print(f"  [{o.id:04d}] {o.outcome} ({o.kind}: {o.what}): {last[:200]}\n    {shown(o.command)}")
    if args.out is not None:
        args.out.write_text(json.dumps({"seed": args.seed, "cases": len(outcomes),
                                        "counts": collections.Counter(o.outcome for o in outcomes),
                                        "outcomes": [asdict(o) for o in outcomes]}, indent=1))
    if not failing and args.work is None:
        shutil.rmtree(work, ignore_errors=True)
    return 1 if failing else 0


if __name__ == "__main__":
    sys.exit(main())
