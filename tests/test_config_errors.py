"""Every kind of configuration error stops the run before any solve with a one-line ConfigError naming the key.

The contract (docs/configuration.md): "an unknown key, a wrong type, a
missing region or boundary name, or a value out of range stops the run with a
one-line error that names the key". Messages read ``KEY: explanation``. Pure
configuration errors come from model.config.parse; names that need the mesh
(regions, boundaries, probes, material coverage) from model.pipeline.build, which is
collective: every rank raises the same error.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import EXAMPLES, ROOT, example, serial_only
from mpi4py import MPI

import meshes
from model.config import load, parse
from model.errors import ConfigError
from model.pipeline import build

Raw = dict[str, Any]


def check_message(message: str, key: str, *fragments: str) -> str:
    """One line, starting with ``KEY: `` and an explanation, containing every fragment."""
    assert "\n" not in message, f"not one line: {message!r}"
    assert message.startswith(f"{key}: "), f"expected the key {key!r} first: {message!r}"
    assert len(message) > len(key) + 10, f"no explanation: {message!r}"
    for fragment in fragments:
        assert fragment in message, f"{fragment!r} not in {message!r}"
    return message


def parse_error(raw: Raw, key: str, *fragments: str) -> str:
    with pytest.raises(ConfigError) as info:
        parse(raw, EXAMPLES)
    return check_message(str(info.value), key, *fragments)


def build_error(raw: Raw, key: str, *fragments: str) -> str:
    """The ConfigError of build(), the same on every rank."""
    config = parse(raw, EXAMPLES)
    with pytest.raises(ConfigError) as info:
        build(config, MPI.COMM_WORLD)
    message = str(info.value)
    assert MPI.COMM_WORLD.allgather(message) == [message] * MPI.COMM_WORLD.size
    return check_message(message, key, *fragments)


def mutated(change: Callable[[Raw], Any]) -> Raw:
    raw = example("uniaxial")
    change(raw)
    return raw


def material(raw: Raw) -> Raw:
    return raw["material"][0]


def set_in(section: str, key: str, value: Any, index: int | None = None) -> Callable[[Raw], None]:
    def change(raw: Raw) -> None:
        table = raw.setdefault(section, {}) if index is None else raw[section][index]
        table[key] = value
    return change


def drop(section: str, index: int, *keys: str) -> Callable[[Raw], None]:
    def change(raw: Raw) -> None:
        for key in keys:
            del raw[section][index][key]
    return change


def expression_instead_of_value(text: str) -> Callable[[Raw], None]:
    def change(raw: Raw) -> None:
        del raw["boundary"][0]["value"]
        raw["boundary"][0]["expression"] = [text]
    return change


# (id, change of the uniaxial example, key named first, fragments the explanation contains)
PARSE_ERRORS: list[tuple[str, Callable[[Raw], Any], str, tuple[str, ...]]] = [
    # unknown keys
    ("unknown section", lambda r: r.__setitem__("solvr", {}), "solvr", ("unknown section", "solver")),
    ("unknown key in a section", lambda r: r["loading"].__setitem__("stpes", 5), "loading.stpes",
     ("unknown key", "steps")),
    ("unknown key in an array of tables", set_in("boundary", "valeu", [1.0], 1), "boundary[1].valeu",
     ("unknown key", "value")),
    ("unknown material parameter", lambda r: material(r).__setitem__("youngs", 1.0), "material[0].youngs",
     ("unknown parameter", "E, nu")),
    ("misspelt material region", lambda r: material(r).__setitem__("regoin", "body"), "material[0].regoin",
     ("unknown parameter",)),
    ("unknown probe key", set_in("probe", "pt", [0.0, 0.0, 0.0], 0), "probe[0].pt", ("unknown key",)),
    ("unknown output key", set_in("output", "vtk", True), "output.vtk", ("unknown key", "vtu")),
    ("unknown mesh key for a file", lambda r: r.__setitem__("mesh", {"file": "uniaxial.toml", "cells": [1]}),
     "mesh.cells", ("unknown key",)),
    # wrong types
    ("steps as a string", set_in("loading", "steps", "5"), "loading.steps", ("integer", "'5'")),
    ("steps as a float", set_in("loading", "steps", 5.0), "loading.steps", ("integer",)),
    ("steps as a boolean", set_in("loading", "steps", True), "loading.steps", ("integer",)),
    ("E as a string", lambda r: material(r).__setitem__("E", "1e4"), "material[0].E", ("number", "'1e4'")),
    ("E as a boolean", lambda r: material(r).__setitem__("E", True), "material[0].E", ("number", "True")),
    ("section not a table", lambda r: r.__setitem__("loading", 5), "loading", ("table",)),
    ("single [material] table", lambda r: r.__setitem__("material", r["material"][0]), "material",
     ("array of tables", "[[material]]")),
    ("region not a string", lambda r: material(r).__setitem__("region", 1), "material[0].region", ("string",)),
    ("value not an array", set_in("boundary", "value", 0.0, 0), "boundary[0].value", ("array",)),
    ("value entry not a number", set_in("boundary", "value", [2.0e3, "0", 0.0], 3), "boundary[3].value[1]",
     ("number",)),
    ("petsc option not a scalar", lambda r: r["solver"]["petsc_options"].__setitem__("snes_rtol", [1e-8]),
     "solver.petsc_options.snes_rtol", ("string, number or boolean",)),
    ("petsc option with a dash", lambda r: r["solver"]["petsc_options"].__setitem__("-snes_rtol", 1e-8),
     "solver.petsc_options.-snes_rtol", ("leading '-'",)),
    ("output flag not a boolean", set_in("output", "png", "yes"), "output.png", ("true or false",)),
    ("probe point not 3 numbers", set_in("probe", "point", [1.0, 1.0], 0), "probe[0].point", ("3 entries",)),
    # out of range
    ("nu = 0.5", lambda r: material(r).__setitem__("nu", 0.5), "material[0].nu", ("(-1, 0.5)",)),
    ("nu <= -1", lambda r: material(r).__setitem__("nu", -1.0), "material[0].nu", ("(-1, 0.5)",)),
    ("E < 0", lambda r: material(r).__setitem__("E", -1.0e4), "material[0].E", ("> 0",)),
    ("E not finite", lambda r: material(r).__setitem__("E", float("inf")), "material[0].E", ("finite",)),
    ("mu < 0", lambda r: material(r).clear() or material(r).update(law="stvk", mu=-1.0, lmbda=1.0),
     "material[0].mu", ("> 0",)),
    ("mooney_rivlin K = 0", lambda r: material(r).clear() or material(r).update(law="mooney_rivlin", c1=1.0,
                                                                                 c2=0.0, K=0.0),
     "material[0].K", ("> 0",)),
    ("degree 0", set_in("discretization", "degree", 0), "discretization.degree", (">= 1",)),
    ("degree 4", set_in("discretization", "degree", 4), "discretization.degree", ("1, 2 or 3",)),
    ("quadrature degree 0", set_in("discretization", "quadrature_degree", 0), "discretization.quadrature_degree",
     (">= 1",)),
    ("steps 0", set_in("loading", "steps", 0), "loading.steps", (">= 1",)),
    ("max_cutbacks < 0", set_in("loading", "max_cutbacks", -1), "loading.max_cutbacks", (">= 0",)),
    ("growth < 1", set_in("loading", "growth", 0.5), "loading.growth", (">= 1",)),
    # material parameter sets
    ("both (E, nu) and (mu, lmbda)", lambda r: material(r).update(mu=1.0, lmbda=1.0), "material[0].mu",
     ("(E, nu)", "(mu, lmbda)", "not both")),
    ("neither (E, nu) nor (mu, lmbda)", drop("material", 0, "E", "nu"), "material[0]", ("(E, nu)", "(mu, lmbda)")),
    ("E without nu", drop("material", 0, "nu"), "material[0].nu", ("missing",)),
    ("mooney_rivlin without K", lambda r: material(r).clear() or material(r).update(law="mooney_rivlin", c1=1.0,
                                                                                      c2=0.0),
     "material[0].K", ("missing",)),
    ("unknown law", lambda r: material(r).__setitem__("law", "neo_hooke"), "material[0].law",
     ("'neo_hooke'", "neo_hookean", "stvk", "mooney_rivlin", "corotated")),
    ("law missing", drop("material", 0, "law"), "material[0].law", ("missing",)),
    ("no material", lambda r: r.pop("material"), "material", ("missing",)),
    # boundaries
    ("boundary type unknown", set_in("boundary", "type", "fixed", 0), "boundary[0].type",
     ("'fixed'", "displacement, traction, pressure")),
    ("boundary type missing", drop("boundary", 0, "type"), "boundary[0].type", ("missing", "displacement")),
    ("boundary name missing", drop("boundary", 0, "on"), "boundary[0].on", ("missing",)),
    ("component out of range", set_in("boundary", "components", [3], 0), "boundary[0].components",
     ("0, 1, 2",)),
    ("component repeated", lambda r: r["boundary"][0].update(components=[0, 0], value=[0.0, 0.0]),
     "boundary[0].components", ("distinct",)),
    ("value length != components", set_in("boundary", "value", [0.0, 0.0], 0), "boundary[0].value",
     ("1 entry", "components", "got 2")),
    ("traction value length", set_in("boundary", "value", [1.0, 0.0], 3), "boundary[3].value", ("3 entries",)),
    ("components on a traction", set_in("boundary", "components", [0], 3), "boundary[3].components",
     ("only applies",)),
    ("both value and expression", set_in("boundary", "expression", ["0.0"], 0), "boundary[0].value",
     ("exactly one",)),
    ("expression calling __import__", expression_instead_of_value("__import__('os')"),
     "boundary[0].expression[0]", ("invalid expression", "may be called")),
    ("expression with an attribute", expression_instead_of_value("x.__class__"), "boundary[0].expression[0]",
     ("not allowed",)),
    ("expression with an unknown name", expression_instead_of_value("y + 1"), "boundary[0].expression[0]",
     ("unknown name 'y'", "x[0]")),
    ("expression syntax error", expression_instead_of_value("0.1 * (x[0]"), "boundary[0].expression[0]",
     ("invalid expression",)),
    ("expression indexing x[3]", expression_instead_of_value("x[3]"), "boundary[0].expression[0]",
     ("x[0], x[1] and x[2]",)),
    ("expression of a huge power", expression_instead_of_value("9**9**9**9"), "boundary[0].expression[0]",
     ("invalid expression",)),
    ("expressions count != components", lambda r: expression_instead_of_value("0.0")(r)
     or r["boundary"][0].__setitem__("expression", ["0.0", "0.0"]), "boundary[0].expression", ("1 strings",)),
    # discretization, mesh, probes
    ("mixed with degree 1", set_in("discretization", "formulation", "mixed"), "discretization.formulation",
     ("degree >= 2",)),
    ("unknown formulation", set_in("discretization", "formulation", "hybrid"), "discretization.formulation",
     ("displacement, mixed",)),
    ("missing mesh file", lambda r: r.__setitem__("mesh", {"file": "no/such/mesh.msh"}), "mesh.file",
     ("no such file",)),
    ("generator and file", lambda r: r["mesh"].__setitem__("file", "mesh.msh"), "mesh", ("exactly one",)),
    ("no [mesh]", lambda r: r.pop("mesh"), "mesh", ("missing",)),
    ("unknown generator", set_in("mesh", "generator", "cube"), "mesh.generator", ("'cube'", "box")),
    ("unknown generator parameter", set_in("mesh", "sizes", [1.0, 1.0, 1.0]), "mesh.sizes",
     ("unknown parameter", "'box'", "size", "cells")),
    ("name map with a generator", set_in("mesh", "regions", {"body": 1}), "mesh.regions", ("mesh.file",)),
    ("probe name used twice", lambda r: r["probe"].append({"name": "corner", "point": [0.0, 0.0, 0.0]}),
     "probe[1].name", ("twice",)),
    ("body force without a value", lambda r: r.__setitem__("body_force", [{"region": "all"}]),
     "body_force[0].value", ("missing",)),
]


@pytest.mark.parametrize(("change", "key", "fragments"), [case[1:] for case in PARSE_ERRORS],
                         ids=[case[0] for case in PARSE_ERRORS])
def test_parse_error(change: Callable[[Raw], Any], key: str, fragments: tuple[str, ...]) -> None:
    parse_error(mutated(change), key, *fragments)


def test_the_example_itself_is_valid() -> None:
    config = parse(example("uniaxial"), EXAMPLES)
    assert config.loading.steps == 5 and config.materials[0].law.name == "neo_hookean"
    assert [b.on for b in config.boundaries] == ["xmin", "ymin", "zmin", "xmax"]


# --- TOML files -----------------------------------------------------------------------------------------------------

def test_invalid_toml(tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text("[mesh]\ngenerator = \"box\"\ncells = = [4, 4, 4]\n")
    with pytest.raises(ConfigError) as info:
        load(path)
    check_message(str(info.value), "config", "invalid TOML", str(path), "line 3")


def test_duplicate_toml_key(tmp_path: Path) -> None:
    path = tmp_path / "twice.toml"
    path.write_text((EXAMPLES / "uniaxial.toml").read_text() + "\n[loading]\nsteps = 2\n")
    with pytest.raises(ConfigError) as info:
        load(path)
    check_message(str(info.value), "config", "invalid TOML")


def test_missing_config_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError) as info:
        load(tmp_path / "nothing.toml")
    check_message(str(info.value), "config", "no such file")


def test_mesh_file_relative_to_the_config(tmp_path: Path) -> None:
    """mesh.file is resolved against the directory of the TOML file, so the error names that path."""
    path = tmp_path / "run.toml"
    path.write_text("[mesh]\nfile = \"meshes/body.vtu\"\n[[material]]\nlaw = \"stvk\"\nE = 1.0\nnu = 0.0\n")
    with pytest.raises(ConfigError) as info:
        load(path)
    check_message(str(info.value), "mesh.file", str(tmp_path / "meshes" / "body.vtu"))


# --- names and values that need the mesh: build() on every rank -----------------------------------------------------

def test_generator_parameter_out_of_range() -> None:
    build_error(mutated(set_in("mesh", "cells", [0, 4, 4])), "mesh.cells", "box", "cells[0]", ">= 1")


def test_generator_parameter_wrong_type() -> None:
    build_error(mutated(set_in("mesh", "size", "unit")), "mesh.size", "box", "'unit'")


def test_unknown_region() -> None:
    build_error(mutated(set_in("material", "region", "muscle", 0)), "material[0].region",
                "'muscle'", "all", "body")


def test_unknown_boundary() -> None:
    build_error(mutated(set_in("boundary", "on", "top", 1)), "boundary[1].on", "'top'", "xmin", "zmax")


def test_unknown_body_force_region() -> None:
    raw = mutated(lambda r: r.__setitem__("body_force", [{"region": "bone", "value": [0.0, 0.0, -1.0]}]))
    build_error(raw, "body_force[0].region", "'bone'")


@pytest.mark.parametrize("point", [[2.0, 0.5, 0.5], [0.5, 0.5, -1e-3]])
def test_probe_outside_the_mesh(point: list[float]) -> None:
    raw = mutated(lambda r: r["probe"].append({"name": "outside", "point": point}))
    build_error(raw, "probe[1].point", "outside the mesh")


def test_overlapping_material_regions() -> None:
    raw = mutated(lambda r: r["material"].append({"region": "body", "law": "stvk", "E": 1.0, "nu": 0.2}))
    build_error(raw, "material[1].region", "overlaps", "material[0]")


@pytest.fixture
def two_regions(shared_tmp: Path) -> Path:
    """A .msh of the example's box split into volumes left (x < 1/2) and right, written by rank 0."""
    path = shared_tmp / "halves.msh"
    if MPI.COMM_WORLD.rank == 0:
        box = meshes.box(size=(1.0, 1.0, 1.0), cells=(4, 4, 4))
        tags = np.where(box.points[box.cells].mean(axis=1)[:, 0] < 0.5, 1, 2)
        meshes.write_msh(meshes.MeshData(box.points, box.cells, tags, box.facets, box.facet_tags,
                                         {"left": 1, "right": 2}, box.boundary_names), path)
    MPI.COMM_WORLD.barrier()
    return path


def test_materials_not_covering_the_mesh(two_regions: Path) -> None:
    raw = mutated(lambda r: r.__setitem__("mesh", {"file": str(two_regions)}))
    material(raw)["region"] = "left"
    build_error(raw, "material", "192 cells", "right")


def test_materials_covering_the_mesh_are_accepted(two_regions: Path) -> None:
    raw = mutated(lambda r: r.__setitem__("mesh", {"file": str(two_regions)}))
    raw["material"] = [{**material(raw), "region": "left"}, {**material(raw), "region": "right", "law": "stvk"}]
    setup = build(parse(raw, EXAMPLES))
    assert sorted(setup.domain.regions) == ["left", "right"]


# --- through the command line: exit code 2, one line on stderr, nothing written ------------------------------------

def run_cli(config: Path, *args: str, cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-m", "model", "run", str(config), *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=120)


@serial_only
@pytest.mark.parametrize(("edit", "key"), [
    (("steps = 5", "stpes = 5"), "loading.stpes"),
    (("nu = 0.3", "nu = 0.5"), "material[0].nu"),
    (("on = \"xmax\"", "on = \"right\""), "boundary[3].on"),  # found by build(), still before any solve
    (("cells = [4, 4, 4]", "cells = [4, 0, 4]"), "mesh.cells"),
])
def test_cli_config_error(tmp_path: Path, edit: tuple[str, str], key: str) -> None:
    text = (EXAMPLES / "uniaxial.toml").read_text()
    assert edit[0] in text
    config = tmp_path / "bad.toml"
    config.write_text(text.replace(edit[0], edit[1]))
    out = tmp_path / "out"
    result = run_cli(config, "--out", str(out), cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith(f"error: {key}: "), lines[0]
    assert result.stdout == ""
    assert not out.exists() and not (tmp_path / "results").exists()


@serial_only
def test_cli_invalid_toml(tmp_path: Path) -> None:
    config = tmp_path / "broken.toml"
    config.write_text("[mesh\n")
    result = run_cli(config, cwd=tmp_path)
    assert result.returncode == 2
    assert result.stderr.splitlines() == [result.stderr.strip()]
    assert result.stderr.startswith(f"error: config: {config}: invalid TOML")
    assert list(tmp_path.iterdir()) == [config]


# --- what tools/fuzz.py found: each a one-line ConfigError naming the key or the file, before any solve ---------------

def file_error(tmp_path: Path, content: bytes, *fragments: str) -> str:
    path = tmp_path / "config.toml"
    path.write_bytes(content)
    with pytest.raises(ConfigError) as info:
        load(path)
    message = check_message(str(info.value), "config", str(path), *fragments)
    assert len(message) < 300, message
    return message


def test_binary_config_file(tmp_path: Path) -> None:
    file_error(tmp_path, b"\x91\x00\xff" + bytes(range(256)), "is a binary file", "UTF-8")


def test_config_file_not_utf8(tmp_path: Path) -> None:
    text = (EXAMPLES / "uniaxial.toml").read_text()
    file_error(tmp_path, ("# d\xe9formation\n" + text).encode("latin-1"), "is not UTF-8 text", "byte 0xe9")
    file_error(tmp_path, text.encode("utf-16"), "UTF-8")


def test_config_nested_too_deeply(tmp_path: Path) -> None:
    file_error(tmp_path, ("a = " + "[" * 5000 + "]" * 5000).encode(), "nested too deeply")


def test_config_file_is_a_folder(tmp_path: Path) -> None:
    with pytest.raises(ConfigError) as info:
        load(tmp_path)
    check_message(str(info.value), "config", "is a folder")


def test_override_nested_too_deeply() -> None:
    from model.config.overrides import parse_assignments

    with pytest.raises(ConfigError) as info:
        parse_assignments(["boundary.0.value=" + "[" * 3000 + "]" * 3000])
    message = check_message(str(info.value), "boundary[0].value", "nested too deeply")
    assert len(message) < 300, message


@pytest.mark.parametrize(("text", "fragment"), [
    (" + ".join(["x[0]"] * 5000), "34997 characters, at most 10000"),
    (" + ".join(["x[0]"] * 500), "nested 503 levels deep, at most 200"),
    ("-" * 5000 + "x[0]", "nested"),  # Python 3.11's parser stops ("too deeply to read"), 3.13's counts the levels
    ("sin(" * 1000 + "x[0]" + ")" * 1000, "too many nested parentheses"),
])
def test_expression_too_deep_or_long(text: str, fragment: str) -> None:
    raw = example("twisting_bar")
    index = next(i for i, b in enumerate(raw["boundary"]) if "expression" in b)
    raw["boundary"][index]["expression"][0] = text
    message = parse_error(raw, f"boundary[{index}].expression[0]", "expression too deep/long", fragment)
    assert len(message) < 300, message


def test_expression_of_200_levels_is_accepted() -> None:
    from model.config.expressions import compile_expression

    assert compile_expression(" + ".join(["x[0]"] * 150))(np.ones((3, 2))).tolist() == [150.0, 150.0]


@pytest.mark.parametrize("value", [1e308, -1e308, 1.0e10])
def test_probe_coordinate_absurd(value: float) -> None:
    parse_error(mutated(lambda raw: raw["probe"][0].__setitem__("point", [0.5, value, 0.5])), "probe[0].point[1]",
                "out of range", "within +-1e+09")


def test_format_length_of_inf() -> None:
    from model.domain.probes import format_length

    assert format_length(float("inf")) == "inf"
    assert format_length(1.23e-4) == "1.2e-4"


@pytest.mark.parametrize(("key", "value", "fragment"), [
    ("steps", 9223372036854775808, "must be <= 100000"),
    ("steps", 100_001, "must be <= 100000"),
    ("max_cutbacks", 9223372036854775808, "must be <= 50"),
    ("max_steps", 10**9, "must be <= 100000"),
])
def test_counts_have_a_maximum(key: str, value: int, fragment: str) -> None:
    parse_error(mutated(set_in("loading", key, value)), f"loading.{key}", fragment)


def test_time_steps_have_a_maximum() -> None:
    raw = example("rotating_muscle")
    raw["dynamics"]["dt"] = 1e-300
    parse_error(raw, "dynamics.dt", "time steps, at most 100000")


def test_misspelt_isotropic_key_is_named() -> None:
    raw = example("isometric")
    raw["material"][0]["isotropc"] = raw["material"][0].pop("isotropic")
    parse_error(raw, "material[0].isotropc", "unknown parameter 'isotropc', did you mean 'isotropic'?")


@pytest.mark.parametrize(("law", "guess"), [("neo_hokean", "neo_hookean"), ("Mooney_Rivlin", "mooney_rivlin"),
                                            ("stvkk", "stvk")])
def test_misspelt_law_did_you_mean(law: str, guess: str) -> None:
    parse_error(mutated(set_in("material", "law", law, 0)), "material[0].law", f"{law!r} is not one of",
                f"(did you mean {guess!r}?)")


def test_misspelt_law_key_is_named() -> None:
    raw = mutated(lambda raw: raw["material"][0].__setitem__("lwa", raw["material"][0].pop("law")))
    parse_error(raw, "material[0].lwa", "unknown key, did you mean 'law'?")


def test_misspelt_isotropic_value_did_you_mean() -> None:
    raw = example("isometric")
    raw["material"][0]["isotropic"] = "stvkk"
    parse_error(raw, "material[0].isotropic", "'stvkk' is not one of mooney_rivlin, stvk (did you mean 'stvk'?)")


def test_misspelt_kind_did_you_mean() -> None:
    parse_error(mutated(set_in("boundary", "type", "displacemnt", 0)), "boundary[0].type",
                "(did you mean 'displacement'?)")


def test_nu_zero_in_the_mixed_formulation_is_named_nu() -> None:
    raw = example("cook")
    raw["material"][0]["nu"] = 0.0
    parse_error(raw, "material[0].nu", "nu = 0.0 gives lmbda = 0", "mixed formulation")


def test_output_dir_naming_a_file(tmp_path: Path) -> None:
    (tmp_path / "taken").write_text("x")
    parse_error(mutated(set_in("output", "dir", str(tmp_path / "taken"))), "output.dir", "is a file, not a folder")


@pytest.mark.parametrize("cells", [[2**63, 4, 4], [10**6, 10**6, 10**6]])
def test_generator_count_has_a_maximum(cells: list[int]) -> None:
    build_error(mutated(set_in("mesh", "cells", cells)), "mesh.cells", "must be <= 10000")


def test_turn_elements_has_a_maximum() -> None:
    from meshes._validate import ParameterError
    from meshes.arm_segment import check_turn_elements

    with pytest.raises(ParameterError, match=r"turn_elements must be an integer in \[6, 10000\]"):
        check_turn_elements("layered_arm", 2**63)
