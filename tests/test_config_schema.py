"""The configuration schema as pydantic models (model.config): generated documents, examples, imports, values.

- docs/config.schema.json and docs/config.md are what the models generate (a key added to a model
  changes both, so a stale file fails here);
- every example validates against the JSON Schema, and a misspelt key does not;
- ``import model.config`` (and generating the documents) loads neither dolfinx nor petsc4py;
- every example loads to the same values as the hand-written parser it replaced (model/config/schema.py
  of commit OLD_PARSER, loaded from git under another package name);
- the first error in document order is the one reported.
"""

from __future__ import annotations

import importlib
import json
import math
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path
from typing import Annotated, Any

import jsonschema
import numpy as np
import pytest
from conftest import EXAMPLES, ROOT, RUN_EXAMPLES, environment, example, serial_only
from pydantic import Field, create_model

import forms
from model.config import ConfigError, LoadingConfig, RunConfig, load, parse
from model.config.base import key
from model.config.reference import MARKDOWN_FILE, SCHEMA_FILE, json_schema, render_markdown, schema_text

EXAMPLE_FILES = RUN_EXAMPLES  # the membrane runs: test_membrane_config.py
#: the last commit with the hand-written parser (model/config/schema.py, contact.py, dynamics.py)
OLD_PARSER = "43d1640997934dbbeb207e05723414bbadc3bef8"


# --- the generated documents ----------------------------------------------------------------------------------------

def test_checked_in_schema_is_the_generated_one() -> None:
    assert (ROOT / SCHEMA_FILE).read_text() == schema_text(), \
        f"{SCHEMA_FILE} is stale: run python -m model schema --out {SCHEMA_FILE} --markdown {MARKDOWN_FILE}"


def test_checked_in_reference_is_the_rendered_one() -> None:
    assert (ROOT / MARKDOWN_FILE).read_text() == render_markdown(), \
        f"{MARKDOWN_FILE} is stale: run python -m model schema --out {SCHEMA_FILE} --markdown {MARKDOWN_FILE}"


def test_a_new_key_changes_both_documents() -> None:
    """A key added to a section (here to [loading], in a copy of the document model) shows in the schema
    and in the reference, with its meaning and unit: the checks above fail until both are regenerated."""
    loading = create_model("LoadingPlus", __base__=LoadingConfig, ramp_time=(
        Annotated[float, Field(gt=0)], key("time over which the loads ramp up", "s (time)", default=2.0)))
    document = create_model("RunConfigPlus", __base__=RunConfig, loading=(loading, key("load stepping",
                                                                                        default_factory=loading)))
    assert schema_text(document) != schema_text()
    schema = json_schema(document)
    loading_schema = schema["$defs"]["LoadingPlus"]["properties"]["ramp_time"]
    assert loading_schema["x-unit"] == "s (time)" and loading_schema["exclusiveMinimum"] == 0
    markdown = render_markdown(document)
    assert markdown != render_markdown()
    row = next(line for line in markdown.splitlines() if line.startswith("| `ramp_time` "))
    assert row == "| `ramp_time` | number | `2.0` | > 0 | s (time) | time over which the loads ramp up |"


def test_reference_lists_every_key_of_every_section() -> None:
    """Each key of each section's models has a row under its section (the laws' own parameters excepted)."""
    markdown = render_markdown()
    config, laws = markdown.split("\n## Laws and their parameters\n")
    sections = config.split("\n## ")[1:]
    schema = json_schema()
    defs = schema["$defs"]

    def keys(s: dict[str, Any]) -> set[str]:
        s = defs[s["$ref"].rsplit("/", 1)[1]] if "$ref" in s else s
        if s.get("type") == "array" and "items" in s:
            return keys(s["items"])
        out = set(s.get("properties", {}))
        for member in s.get("oneOf", []) if "type" not in s else []:
            out |= keys(member)
        return out

    assert [s.split("\n", 1)[0].strip("[]") for s in sections] == list(schema["properties"])
    for text, (name, prop) in zip(sections, schema["properties"].items(), strict=True):
        rows = {line.split("`")[1] for line in text.splitlines() if line.startswith("| `")}
        assert keys(prop) <= rows, (name, keys(prop) - rows)
    assert "listed per law in the last section" in config
    for parameter in ("`E`", "`nu`", "`mu`", "`lmbda`"):
        assert f"| {parameter} |" not in config
    # the last section: every built-in law with every parameter, its unit and allowed range
    for entry in forms.REGISTRY.values():
        text = laws.split(f"### `{entry.name}`", 1)[1].split("\n### ", 1)[0]
        for p in entry.parameters:
            row = next(line for line in text.splitlines() if line.startswith(f"| `{p.name}` |"))
            assert p.unit in row, row


@serial_only
def test_command_line_writes_both(tmp_path: Path) -> None:
    out, markdown = tmp_path / "schema.json", tmp_path / "config.md"
    result = subprocess.run([sys.executable, "-m", "model", "schema", "--out", str(out), "--markdown", str(markdown)],
                            cwd=ROOT, env=environment(), capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert out.read_text() == (ROOT / SCHEMA_FILE).read_text()
    assert markdown.read_text() == (ROOT / MARKDOWN_FILE).read_text()


def test_taplo_associates_the_examples_with_the_schema() -> None:
    config = tomllib.loads((ROOT / ".taplo.toml").read_text())
    rule = next(r for r in config["rule"] if "schema" in r)
    assert "examples/*.toml" in rule["include"]
    assert (ROOT / rule["schema"]["path"]).resolve() == (ROOT / SCHEMA_FILE).resolve()


# --- the examples against the JSON Schema ---------------------------------------------------------------------------

@pytest.fixture(scope="module")
def validator() -> jsonschema.Draft202012Validator:
    schema = json.loads((ROOT / SCHEMA_FILE).read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


@pytest.mark.parametrize("path", EXAMPLE_FILES, ids=[p.stem for p in EXAMPLE_FILES])
def test_example_validates_against_the_schema(path: Path, validator: jsonschema.Draft202012Validator) -> None:
    errors = [f"{list(e.absolute_path)}: {e.message}" for e in validator.iter_errors(tomllib.loads(path.read_text()))]
    assert errors == []


@pytest.mark.parametrize(("change", "where"), [
    (lambda r: r["loading"].__setitem__("stpes", 5), ["loading"]),
    (lambda r: r["material"][0].__setitem__("region", 3), ["material", 0, "region"]),
    (lambda r: r["boundary"][3].__setitem__("components", [0]), ["boundary", 3]),
    (lambda r: r["solver"].__setitem__("pd_rtol", 1e-6), ["solver"]),
    (lambda r: r["boundary"][0].__setitem__("type", "fixed"), ["boundary", 0]),
    (lambda r: r.__setitem__("dynamics", {"dt": 0.1}), ["dynamics"]),
])
def test_schema_refuses_what_the_models_refuse(change: Any, where: list[Any],
                                               validator: jsonschema.Draft202012Validator) -> None:
    raw = example("uniaxial")
    change(raw)
    with pytest.raises(ConfigError):
        parse(raw, EXAMPLES)
    errors = list(validator.iter_errors(raw))
    assert errors and any(list(e.absolute_path)[: len(where)] == where for e in errors), errors


# --- no dolfinx -----------------------------------------------------------------------------------------------------

def test_config_and_its_documents_load_without_dolfinx() -> None:
    code = ("import sys, model.config, model.config.reference as r; r.render_markdown(); "
            "model.config.load('examples/arm_flexion.toml'); "
            "print(sorted(m for m in ('dolfinx', 'petsc4py', 'basix', 'model.compat') if m in sys.modules))")
    result = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=environment(), capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[]"


# --- the same values as the hand-written parser ---------------------------------------------------------------------

@pytest.fixture(scope="module")
def old_parser(tmp_path_factory: pytest.TempPathFactory) -> Any:
    """model/config/schema.py (with its contact.py and dynamics.py) of OLD_PARSER, as the package _old_config."""
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("needs the git history")
    folder = tmp_path_factory.mktemp("old") / "_old_config"
    folder.mkdir()
    (folder / "__init__.py").write_text("")
    for name in ("schema", "contact", "dynamics"):
        text = subprocess.run(["git", "show", f"{OLD_PARSER}:model/config/{name}.py"], cwd=ROOT, capture_output=True,
                              text=True, check=True).stdout
        for module in ("contact", "dynamics"):
            text = text.replace(f"model.config.{module}", f"_old_config.{module}")
        (folder / f"{name}.py").write_text(text)
    sys.path.insert(0, str(folder.parent))
    try:
        yield importlib.import_module("_old_config.schema")
    finally:
        sys.path.remove(str(folder.parent))
        for name in [m for m in sys.modules if m == "_old_config" or m.startswith("_old_config.")]:
            del sys.modules[name]


def plain(value: Any) -> Any:
    """A value as comparable data: containers keep their kind (tuple or list), arrays their shape, floats their
    bits, functions their name and file, rigid motions and obstacles their values at a few times."""
    if isinstance(value, bool) or value is None or isinstance(value, (int, str, Path)):
        return value
    if isinstance(value, float):
        return ("float", value) if math.isfinite(value) else ("float", repr(value))
    if isinstance(value, np.ndarray):
        return ("ndarray", value.shape, value.tolist())
    if isinstance(value, tuple):
        return ("tuple", [plain(v) for v in value])
    if isinstance(value, list):
        return ("list", [plain(v) for v in value])
    if isinstance(value, dict):
        return ("dict", {k: plain(v) for k, v in value.items()})
    if callable(value) and hasattr(value, "__code__"):
        return ("function", value.__name__, value.__code__.co_filename)
    if hasattr(value, "parameters") and hasattr(value, "energy"):  # a law
        return ("law", type(value).__name__, plain(value.parameters()))
    if callable(value):  # a rigid motion
        return (type(value).__name__, [plain(tuple(np.asarray(part).round(12).tolist() for part in value(t)))
                                       for t in (0.0, 0.3, 1.0)])
    return (type(value).__name__, plain(dict(vars(value))))


#: the attributes the rest of the project reads, per object
ATTRIBUTES = {
    "mesh": ("generator", "file", "params", "regions", "boundaries", "cell_data", "facet_data"),
    "discretization": ("degree", "quadrature_degree", "formulation"),
    "materials": ("region", "law", "fields", "fibres", "activation", "density"),
    "fibres": ("type", "origin", "insertion", "regions", "file"),
    "boundaries": ("on", "type", "components", "value", "expression", "points", "bone", "penalty",
                   "quadrature_degree"),
    "body_forces": ("region", "value"),
    "loading": ("steps", "max_cutbacks", "growth"),
    "petsc_options": None,
    "probes": ("name", "point"),
    "output": ("dir", "xdmf", "vtu", "png"),
    "solver": ("method", "tangent", "petsc_options", "pd_max_iterations", "pd_rtol", "pd_atol"),
    "bones": ("name", "motion", "obstacle", "shape"),
    "contacts": ("spec", "bone"),
    "spec": ("surface", "obstacle", "method", "penalty", "augmented", "tolerance", "max_uzawa", "quadrature_degree"),
    "dynamics": ("scheme", "dt", "end_time", "rayleigh", "rho_infinity", "load_ramp", "initial", "is_dynamic"),
}


def snapshot(obj: Any, name: str) -> Any:
    """``obj``'s ATTRIBUTES[name] (recursively) as plain data."""
    if isinstance(obj, tuple) and name in ("materials", "boundaries", "body_forces", "probes", "bones", "contacts"):
        return ("tuple", [snapshot(item, name) for item in obj])
    names = ATTRIBUTES.get(name)
    if names is None or obj is None:
        return plain(obj)
    out = {k: snapshot(getattr(obj, k), k) if k in ("fibres", "spec") else plain(getattr(obj, k)) for k in names}
    if name == "dynamics":
        out["load_scale"] = [plain(obj.load_scale(t)) for t in (0.0, 0.25, 0.5, 2.0)]
    if name == "discretization" and obj.quadrature_degree == "auto":
        # "auto" (after the old parser) is its default 2 x degree, except for P1's materials (one point, exact)
        out["quadrature_degree"] = plain(2 * obj.degree)
    return out


def run_config_snapshot(config: Any) -> dict[str, Any]:
    fields = ("mesh", "discretization", "materials", "boundaries", "body_forces", "loading", "petsc_options",
              "probes", "output", "solver", "bones", "contacts", "dynamics")
    return {k: snapshot(getattr(config, k), k) for k in fields}


#: examples that use what the old parser did not have (a law of the user's own; a .geo mesh, probe snap; the
#: contact keys of the layered arms, self-contact and the twins; path following and curved .geo meshes; parameter
#: curves)
NEWER = ("guccione_beam", "guccione_active", "spindle", "twisting_bar_render", "contact_bodies",
         "layered_arm", "layered_arm_touching", "layered_arm_flexion",
         "layered_arm_gap", "layered_arm_touching_flexion", "self_contact_slot", "twin_muscles",
         "thick_sphere", "ventricle")
OLD_EXAMPLES = [p for p in EXAMPLE_FILES if p.stem not in NEWER]


@pytest.mark.parametrize("path", OLD_EXAMPLES, ids=[p.stem for p in OLD_EXAMPLES])
def test_example_loads_to_the_values_of_the_old_parser(path: Path, old_parser: Any) -> None:
    raw = tomllib.loads(path.read_text())
    new = load(path)
    if "parameters" in raw:  # [parameters] came after the old parser: their numbers written into the expressions
        names = raw.pop("parameters")
        for b in raw["boundary"]:
            if "expression" in b:
                b["expression"] = [re.sub(r"\b[A-Za-z_]\w*\b", lambda m: repr(names.get(m[0], m[0])).strip("'"), e)
                                   for e in b["expression"]]
        new = parse(raw, path.parent)
    raw.pop("units", None)  # [units] (labels only) came after the old parser
    if raw.get("discretization", {}).get("quadrature_degree") == "auto":  # after the old parser: its default
        del raw["discretization"]["quadrature_degree"]
    old = old_parser.parse(raw, path.parent)
    assert run_config_snapshot(new) == run_config_snapshot(old)


def test_overrides_load_to_the_values_of_the_old_parser(old_parser: Any) -> None:
    """Defaults and the kinds of values the examples leave out: dynamics, sliding, a file mesh, targets."""
    raw = example("contact_block")
    raw["bone"] = [{"name": "floor", "obstacle": "plane", "point": [0.0, 0.0, -1.0], "normal": [0, 0, 1],
                    "transform": {"times": [0, 1], "rotations": [[0, 0, 0], [[1, 0, 0], [0, 0, -1], [0, 1, 0]]],
                                  "translations": [[0, 0, 0], [0, 0, 1]]}}]
    raw["boundary"].append({"on": "xmin", "type": "sliding", "bone": "floor", "penalty": 1e6,
                            "quadrature_degree": "vertex"})
    raw["boundary"].append({"on": "xmax", "type": "pressure", "value": [2.0]})
    raw["boundary"].append({"on": "ymax", "type": "displacement", "components": [1],
                            "expression": ["0.1*x[0]*t"], "points": [[1, 1, 1]]})
    raw["contact"].append({"surface": "ymin", "bone": "floor", "method": "penalty", "penalty": 5,
                           "augmented": True, "max_uzawa": 3})
    raw["material"][0]["density"] = 1000
    raw["dynamics"] = {"scheme": "generalized_alpha", "dt": 0.05, "rayleigh": [1, 0.001], "rho_infinity": 0.5,
                       "load_ramp": 0.5, "initial": "equilibrium"}
    raw["discretization"] = {"degree": 2}
    raw["solver"] = {"petsc_options": {"snes_rtol": 1e-9, "ksp_type": "preonly", "snes_monitor": True}}
    raw["body_force"] = [{"value": [0, 0, -9.81]}]
    assert run_config_snapshot(parse(raw, EXAMPLES)) == run_config_snapshot(old_parser.parse(raw, EXAMPLES))


# --- which error is reported ----------------------------------------------------------------------------------------

def test_the_first_error_in_document_order_is_reported() -> None:
    """Two wrong keys: the one written first is named, whatever the sections' order in the models."""
    raw = example("uniaxial")
    raw["output"]["png"] = "yes"
    raw["loading"]["steps"] = 0
    first = "output" if list(raw).index("output") < list(raw).index("loading") else "loading"
    with pytest.raises(ConfigError, match=rf"^{first}\."):
        parse(raw, EXAMPLES)
    reordered = {"output": raw.pop("output"), **raw} if first == "loading" else {"loading": raw.pop("loading"), **raw}
    other = "output" if first == "loading" else "loading"
    with pytest.raises(ConfigError, match=rf"^{other}\."):
        parse(reordered, EXAMPLES)


def test_keys_of_another_kind_are_named() -> None:
    raw = example("uniaxial")
    raw["boundary"][3]["points"] = [[1.0, 0.5, 0.5]]  # a traction
    with pytest.raises(ConfigError, match=r"^boundary\[3\]\.points: only applies to type = 'displacement', "
                                          r"not 'traction'$"):
        parse(raw, EXAMPLES)
