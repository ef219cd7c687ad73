"""Overrides of a configuration's keys (model/config/overrides.py, ``run --set KEY=VALUE``).

- an override gives the configuration of the file edited by hand (dotted paths, ``material[0].E``, negative
  indices, arrays of numbers, appending an entry, a key the file lacks but the schema allows);
- every kind of bad override is a ConfigError with its one-line message naming the key (Python API), and
  from the command line exit code 2 with that one line, before any solve (nothing written);
- the recorded document (RunConfig.document, summary.json's "config") is the edited one, files made absolute.
"""

from __future__ import annotations

import copy
import subprocess
import sys
import tomllib
from pathlib import Path
from typing import Any

import pytest
from conftest import EXAMPLES, ROOT, environment, example, serial_only, write_toml

from model.config import ConfigError, load, parse
from model.config.overrides import apply, parse_assignment, parse_assignments, resolved, split_path

UNIAXIAL = EXAMPLES / "uniaxial.toml"


def edited(raw: dict[str, Any], *changes: tuple[list[Any], Any]) -> dict[str, Any]:
    """``raw`` with each (path as a list of keys and indices, value) set by plain item assignment."""
    out = copy.deepcopy(raw)
    for path, value in changes:
        node = out
        for part in path[:-1]:
            node = node.setdefault(part, {}) if isinstance(node, dict) else node[part]
        node[path[-1]] = value
    return out


def error(overrides: dict[str, Any], path: Path = UNIAXIAL) -> str:
    with pytest.raises(ConfigError) as info:
        load(path, overrides)
    message = str(info.value)
    assert "\n" not in message
    return message


# --- what an override does ------------------------------------------------------------------------------------------

@pytest.mark.parametrize(("overrides", "changes"), [
    ({"material.0.E": 2e5, "loading.steps": 20}, [(["material", 0, "E"], 2e5), (["loading", "steps"], 20)]),
    ({"material[0].nu": 0.25}, [(["material", 0, "nu"], 0.25)]),
    ({"boundary.3.value": [1.0e3, 0.0, 0.0]}, [(["boundary", 3, "value"], [1.0e3, 0.0, 0.0])]),
    ({"boundary.-1.value.0": 5.0}, [(["boundary", 3, "value", 0], 5.0)]),
    ({"mesh.cells.2": 2}, [(["mesh", "cells", 2], 2)]),
    ({"solver.petsc_options.ksp_type": "gmres", "output.png": False},
     [(["solver", "petsc_options", "ksp_type"], "gmres"), (["output", "png"], False)]),
    ({"probe.1": {"name": "middle", "point": [0.5, 0.5, 0.5]}},
     [(["probe", 1], {"name": "middle", "point": [0.5, 0.5, 0.5]})]),
])
def test_an_override_gives_the_file_edited_by_hand(overrides: dict[str, Any], changes: list[Any]) -> None:
    raw = tomllib.loads(UNIAXIAL.read_text())
    if any(path == ["probe", 1] for path, _ in changes):
        raw["probe"].append(None)  # edited() assigns the index: make room for the appended entry
    expected = edited(raw, *changes)
    assert apply(raw, overrides) == expected
    assert load(UNIAXIAL, overrides) == parse(expected, EXAMPLES)
    assert load(UNIAXIAL, overrides) != load(UNIAXIAL)
    assert load(UNIAXIAL, overrides).document == resolved(expected, EXAMPLES)


def test_an_override_creates_a_key_the_file_lacks(tmp_path: Path) -> None:
    """The file has no [solver] and no [dynamics]: --set creates them, as if the file had them."""
    raw = example("uniaxial")
    del raw["solver"]
    path = write_toml(raw, tmp_path / "nosolver.toml")
    assert load(path).solver.linear == "auto"
    config = load(path, {"solver.linear": "iterative", "solver.petsc_options.ksp_rtol": 1e-9})
    assert config.solver.linear == "iterative" and config.petsc_options["ksp_rtol"] == 1e-9
    assert config.document["solver"] == {"linear": "iterative", "petsc_options": {"ksp_rtol": 1e-9}}
    assert config == parse({**raw, "solver": {"linear": "iterative", "petsc_options": {"ksp_rtol": 1e-9}}},
                           tmp_path)
    assert "solver" not in tomllib.loads(path.read_text())  # the file is left alone


def test_an_array_of_tables_the_file_lacks_is_created(tmp_path: Path) -> None:
    raw = example("uniaxial")
    del raw["probe"]
    path = write_toml(raw, tmp_path / "noprobe.toml")
    config = load(path, {"probe.0.name": "tip", "probe.0.point": [1.0, 0.5, 0.5]})
    assert [(p.name, tuple(p.point)) for p in config.probes] == [("tip", (1.0, 0.5, 0.5))]


@pytest.mark.parametrize(("text", "expected"), [
    ("loading.steps=20", ("loading.steps", 20)),
    ("material.0.E=2e5", ("material.0.E", 2e5)),
    ("output.png=false", ("output.png", False)),
    ("boundary.0.value=[0.1]", ("boundary.0.value", [0.1])),
    ("material.0.law=stvk", ("material.0.law", "stvk")),
    ('material.0.law="stvk"', ("material.0.law", "stvk")),
    ("mesh.file=../meshes/a b.msh".replace(" ", "_"), ("mesh.file", "../meshes/a_b.msh")),
    ("solver.petsc_options={ksp_type = 'cg'}", ("solver.petsc_options", {"ksp_type": "cg"})),
    (" loading.steps = 3 ", ("loading.steps", 3)),
])
def test_values_are_toml_and_bare_words_strings(text: str, expected: tuple[str, Any]) -> None:
    assert parse_assignment(text) == expected


def test_split_path() -> None:
    assert split_path("material.0.E") == split_path("material[0].E") == ["material", 0, "E"]
    assert split_path("boundary[-1].value[2]") == ["boundary", -1, "value", 2]


# --- one message per kind of bad override (Python API) --------------------------------------------------------------

def test_missing_equals_sign() -> None:
    with pytest.raises(ConfigError, match=r"^--set 'loading\.steps': no \"=\" \(write KEY=VALUE, e\.g\. "
                                          r"material\.0\.E=2e5\)$"):
        parse_assignments(["loading.steps"])


@pytest.mark.parametrize("text", ["=3", " =3"])
def test_empty_key(text: str) -> None:
    with pytest.raises(ConfigError, match=rf"^--set {text!r}: the key is empty \(write KEY=VALUE, e\.g\. "):
        parse_assignments([text])


def test_empty_part_of_a_key() -> None:
    assert error({"loading..steps": 3}) == "loading..steps: empty part in the dotted key (write it like material.0.E)"


def test_unknown_key_names_what_the_section_allows() -> None:
    assert error({"loading.stpes": 3}) == "loading.stpes: unknown key, did you mean 'steps'? (allowed: control, " \
        "growth, max_cutbacks, max_steps, steps, volume_boundary, volume_origin, volume_ratio)"
    assert error({"solver.lienar": "direct"}).startswith(
        "solver.lienar: unknown key, did you mean 'linear'? (allowed: ")
    assert error({"material.0.Ee": 2e5}) == \
        "material[0].Ee: neo_hookean: unknown parameter 'Ee' (allowed: E, nu, mu, lmbda)"


def test_unknown_key_in_a_section_the_file_lacks() -> None:
    assert error({"dynamics.shceme": "newmark"}) == \
        "dynamics.shceme: unknown key, did you mean 'scheme'? (allowed: dt, end_time, initial, load_ramp, rayleigh, " \
        "rho_infinity, scheme)"


def test_unknown_section() -> None:
    assert error({"loadng.steps": 3}).startswith(
        "loadng: unknown section, did you mean 'loading'? (allowed: body_force, bone, boundary, ")


def test_index_out_of_range() -> None:
    assert error({"material.5.E": 2e5}) == \
        "material[5].E: index 5 is out of range: material has 1 entry (indices 0 to 0, or 1 to append one)"
    assert error({"boundary.-5.value": [0.0]}) == \
        "boundary[-5].value: index -5 is out of range: boundary has 4 entries (indices 0 to 3, or 4 to append one)"


def test_appending_an_incomplete_entry_is_checked_like_the_file() -> None:
    assert error({"material.1.E": 2e5}).startswith("material[1].law: missing (one of arap, ")


def test_indexing_a_table() -> None:
    assert error({"loading.0": 3}) == \
        "loading[0]: loading is a table, not an array: name one of its keys (control, growth, max_cutbacks, " \
        "max_steps, steps, volume_boundary, volume_origin, volume_ratio) instead of an index"


def test_keying_an_array() -> None:
    assert error({"material.E": 2e5}) == \
        "material.E: material is an array of 1 entry, not a table: give an index, e.g. material.0.E"
    assert error({"mesh.cells.x": 2}) == \
        "mesh.cells.x: mesh.cells is an array of 3 entries, not a table: give an index, e.g. mesh.cells.0.x"


def test_keying_or_indexing_a_value() -> None:
    assert error({"loading.steps.x": 3}) == "loading.steps.x: loading.steps is a value (5), not a table"
    assert error({"loading.steps.0": 3}) == "loading.steps[0]: loading.steps is a value (5), not an array"


@pytest.mark.parametrize(("text", "message"), [
    ("loading.steps=abc", "loading.steps: must be an integer, got 'abc'"),
    ("loading.steps=1.5", "loading.steps: must be an integer, got 1.5"),
    ("output.png=yes", "output.png: must be true or false, got 'yes'"),
    ("material.0.E=[1]", "material[0].E: must be a number, got [1] (or a load curve: a table [[t0, p0], [t1, p1], "
                         "...] whose rows are two finite numbers [t, value], or an expression of t; row 0 is 1)"),
])
def test_value_of_the_wrong_type(text: str, message: str) -> None:
    assert error(parse_assignments([text])) == message


@pytest.mark.parametrize("value", ["[1,", '"open', "{a = }", "1 2"])
def test_invalid_toml_value(value: str) -> None:
    with pytest.raises(ConfigError) as info:
        parse_assignments([f"boundary.0.value={value}"])
    assert str(info.value) == f"boundary[0].value: cannot read the value {value!r} as TOML (write it like 1e5, " \
                              "true, \"text\", [1, 2] or {a = 1})"


def test_missing_value() -> None:
    with pytest.raises(ConfigError, match=r"^loading\.steps: no value after \"=\" \(write KEY=VALUE"):
        parse_assignments(["loading.steps="])


@pytest.mark.parametrize(("texts", "message"), [
    (["loading.steps=3", "loading.steps=4"], "loading.steps: given twice: 'loading.steps' and 'loading.steps'"),
    (["material.0.E=1e4", "material[0].E=2e4"], "material[0].E: given twice: 'material.0.E' and 'material[0].E'"),
    (["loading={steps = 3}", "loading.steps=4"],
     "loading.steps: given twice (inside loading, given whole): 'loading' and 'loading.steps'"),
])
def test_same_key_twice(texts: list[str], message: str) -> None:
    with pytest.raises(ConfigError) as info:
        parse_assignments(texts)
    assert str(info.value) == message


def test_same_key_twice_from_python() -> None:
    assert error({"material.0.E": 1e4, "material[0].E": 2e4}) == \
        "material[0].E: given twice: 'material.0.E' and 'material[0].E'"
    assert error({"loading": {"steps": 3}, "loading.steps": 4}) == \
        "loading.steps: given twice (inside loading, given whole): 'loading' and 'loading.steps'"


def test_value_out_of_range_is_the_laws_error() -> None:
    assert error({"material.0.nu": 0.7}) == "material[0].nu: neo_hookean: nu = 0.7, must be in (-1, 0.5)"
    assert error({"loading.steps": 0}) == "loading.steps: 0 is out of range, must be >= 1"


def test_value_out_of_range_matches_the_file(tmp_path: Path) -> None:
    """The same mistake in the file and as an override: the same message."""
    raw = example("uniaxial")
    raw["material"][0]["nu"] = 0.7
    with pytest.raises(ConfigError) as in_file:
        load(write_toml(raw, tmp_path / "bad.toml"))
    assert str(in_file.value) == error({"material.0.nu": 0.7})


def test_resolved_makes_named_files_absolute(tmp_path: Path) -> None:
    (tmp_path / "m.msh").write_text("")
    (tmp_path / "laws").mkdir()
    (tmp_path / "laws" / "mine.py").write_text("")
    raw = {"mesh": {"file": "m.msh"}, "material": [{"region": "all", "law": "laws/mine.py:psi", "E": 1.0}],
           "boundary": [{"on": "xmin.msh.missing"}], "output": {"dir": "results/x"}}
    assert resolved(raw, tmp_path) == {
        "mesh": {"file": str((tmp_path / "m.msh").resolve())},
        "material": [{"region": "all", "law": f"{(tmp_path / 'laws' / 'mine.py').resolve()}:psi", "E": 1.0}],
        "boundary": [{"on": "xmin.msh.missing"}], "output": {"dir": "results/x"}}


# --- the command line -----------------------------------------------------------------------------------------------

def run_cli(tmp: Path, *sets: str) -> subprocess.CompletedProcess:
    command = [sys.executable, "-m", "model", "run", str(UNIAXIAL), "--out", str(tmp / "out")]
    for text in sets:
        command += ["--set", text]
    return subprocess.run(command, cwd=ROOT, env=environment(), capture_output=True, text=True, timeout=300)


@serial_only
@pytest.mark.parametrize(("sets", "message"), [
    (["loading.steps"], "--set 'loading.steps': no \"=\" (write KEY=VALUE, e.g. material.0.E=2e5)"),
    (["=3"], "--set '=3': the key is empty (write KEY=VALUE, e.g. material.0.E=2e5)"),
    (["loading.stpes=3"], "loading.stpes: unknown key, did you mean 'steps'? (allowed: control, growth, max_cutbacks, "
                          "max_steps, steps, volume_boundary, volume_origin, volume_ratio)"),
    (["material.5.E=2e5"],
     "material[5].E: index 5 is out of range: material has 1 entry (indices 0 to 0, or 1 to append one)"),
    (["loading.0=3"], "loading[0]: loading is a table, not an array: name one of its keys (control, growth, "
                      "max_cutbacks, max_steps, steps, volume_boundary, volume_origin, volume_ratio) instead of an "
                      "index"),
    (["material.E=2e5"], "material.E: material is an array of 1 entry, not a table: give an index, e.g. material.0.E"),
    (["loading.steps=abc"], "loading.steps: must be an integer, got 'abc'"),
    (["loading.steps=1.5"], "loading.steps: must be an integer, got 1.5"),
    (["boundary.0.value=[0.1,"], "boundary[0].value: cannot read the value '[0.1,' as TOML (write it like 1e5, true, "
                                 "\"text\", [1, 2] or {a = 1})"),
    (["loading.steps=3", "loading.steps=4"], "loading.steps: given twice: 'loading.steps' and 'loading.steps'"),
    (["material.0.nu=0.7"], "material[0].nu: neo_hookean: nu = 0.7, must be in (-1, 0.5)"),
])
def test_command_line_errors(tmp_path: Path, sets: list[str], message: str) -> None:
    result = run_cli(tmp_path, *sets)
    assert result.returncode == 2, result.stdout + result.stderr
    assert result.stderr.splitlines() == [f"error: {message}"]
    assert not (tmp_path / "out").exists()  # before any solve: nothing written
