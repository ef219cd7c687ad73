"""[[contact]] with master: contact and sliding between deformable bodies from a configuration
(examples/contact_bodies.toml; model.problem.body_contact through model.pipeline).

Two unit blocks stacked (meshes.stacked_blocks), rollers, a pressure p = 200 on top: a homogeneous uniaxial state,
so the contact force is p A (closed form) and the top moves as the same 1 x 1 x 2 block in one piece (run through
the pipeline too): to the Uzawa tolerance with augmented = true, off by the penalty's p/k without. Sliding holds
the upper block pulled up (the gap opens by p/k). Every bad [[contact]] with master is a one-line ConfigError
naming the key before any solve.
"""

from __future__ import annotations

import pytest
from conftest import example, run_raw
from mpi4py import MPI

from model.config import parse
from model.config.contact import parse_contact
from model.errors import ConfigError
from model.pipeline import build

P = 200.0
QUIET = {"xdmf": False, "vtu": False, "png": False}


def out_dir(tmp_path_factory: pytest.TempPathFactory, name: str) -> str:
    return MPI.COMM_WORLD.bcast(str(tmp_path_factory.mktemp(name)), root=0)


def bodies(**contact: object) -> dict:
    raw = example("contact_bodies")
    raw["contact"][0].update(contact)
    raw["output"] = dict(QUIET)
    return raw


def one_body(pressure: float = P) -> dict:
    """The same problem as one 1 x 1 x 2 block (same cells)."""
    raw = example("contact_bodies")
    raw["mesh"] = {"generator": "box", "size": [1.0, 1.0, 2.0], "cells": [2, 2, 4]}
    raw["material"] = [{**raw["material"][0], "region": "all"}]
    raw["boundary"] = [{"on": "zmin", "type": "displacement", "components": [2], "value": [0.0]},
                       {"on": "xmin", "type": "displacement", "components": [0], "value": [0.0]},
                       {"on": "ymin", "type": "displacement", "components": [1], "value": [0.0]},
                       {"on": "zmax", "type": "traction", "value": [0.0, 0.0, -pressure]}]
    del raw["contact"]
    raw["output"] = dict(QUIET)
    return raw


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> dict:
    return run_raw(one_body(), out_dir(tmp_path_factory, "one_body"))["steps"][-1]


def test_example_against_p_a_and_one_body(tmp_path_factory, reference) -> None:
    """augmented = true (the example): force p A, the one-body top and interface to the Uzawa tolerance."""
    summary = run_raw(bodies(), out_dir(tmp_path_factory, "contact_bodies"))
    assert summary["status"] == "completed"
    steps = [s for s in summary["steps"] if s["converged"]]
    assert [s["load_factor"] for s in steps] == [0.5, 1.0]
    for step in steps:
        pair = step["contact_pairs"]["upper_zmin-lower_zmax"]
        load = P * step["load_factor"]
        assert pair["normal_force"] == pytest.approx(load, rel=1e-9)  # p A, A = 1
        assert pair["force"][2] == pytest.approx(load, rel=1e-9)
        assert abs(pair["force"][0]) + abs(pair["force"][1]) < 1e-9 * load
        assert pair["active_points"] == 9  # the 3 x 3 nodes of the upper block's bottom
        assert pair["max_penetration"] < 1e-10 * 3**0.5 * 2  # the tolerance x the bodies' size (diagonal)
        assert (pair["kind"], pair["surface"], pair["master"]) == ("contact", "upper_zmin", "lower_zmax")
        assert step["contact"] == {k: pair[k] for k in ("max_penetration", "force", "active_points")}
    last = steps[-1]["probes"]
    assert max(abs(a - b) for a, b in zip(last["top"], reference["probes"]["top"])) < 1e-9
    assert last["interface"][2] == pytest.approx(last["top"][2] / 2, rel=1e-8)  # homogeneous: half the top's


@pytest.mark.parametrize("exact", [False, True])
def test_penalty_alone_is_off_by_p_over_k(tmp_path_factory, reference, exact: bool) -> None:
    """augmented = false: every slave node penetrates by p/k, the top lies p/k lower than the one body's; the same
    with exact = true (exact contact: on the flat faces the plane gap is the default's), bt on the total potential."""
    k = 1.0e7
    raw = bodies(augmented=False)
    del raw["contact"][0]["tolerance"]
    raw["contact"][0]["exact"] = exact
    summary = run_raw(raw, out_dir(tmp_path_factory, f"penalty{int(exact)}"))
    assert summary["solver"]["line_search"] == {"type": "bt", "merit": "total_potential"}
    last = summary["steps"][-1]
    pair = last["contact_pairs"]["upper_zmin-lower_zmax"]
    assert pair["max_penetration"] == pytest.approx(P / k, rel=1e-8)
    assert pair["normal_force"] == pytest.approx(P, rel=1e-10)
    assert last["probes"]["top"][2] - reference["probes"]["top"][2] == pytest.approx(-P / k, rel=1e-6)


def test_sliding_holds_the_upper_block_pulled_up(tmp_path_factory) -> None:
    """sliding = true, the top pulled up by p: the springs pull the upper block down with p A; the gap is p/k."""
    raw = bodies(sliding=True, augmented=False)
    del raw["contact"][0]["tolerance"]
    raw["boundary"][-1]["value"] = [0.0, 0.0, P]
    last = run_raw(raw, out_dir(tmp_path_factory, "sliding"))["steps"][-1]
    pair = last["contact_pairs"]["upper_zmin-lower_zmax"]
    assert pair["kind"] == "sliding"
    assert pair["normal_force"] == pytest.approx(-P, rel=1e-10)
    assert pair["max_gap"] == pytest.approx(P / 1.0e7, rel=1e-8) and pair["max_penetration"] == 0.0
    assert "sliding_energy" in last



def test_exact_sliding_from_the_configuration(tmp_path_factory) -> None:
    """sliding = true, exact = true: the same answer as the interpolated normals (the blocks stay flat: force -p A,
    gap p/k) on the line search of a consistent potential (bt on the total potential)."""
    raw = bodies(sliding=True, augmented=False)
    del raw["contact"][0]["tolerance"]
    raw["contact"][0]["exact"] = True
    raw["boundary"][-1]["value"] = [0.0, 0.0, P]
    summary = run_raw(raw, out_dir(tmp_path_factory, "exact"))
    assert summary["solver"]["line_search"] == {"type": "bt", "merit": "total_potential"}
    pair = summary["steps"][-1]["contact_pairs"]["upper_zmin-lower_zmax"]
    assert pair["kind"] == "sliding"
    assert pair["normal_force"] == pytest.approx(-P, rel=1e-9)
    assert pair["max_gap"] == pytest.approx(P / 1.0e7, rel=1e-8) and pair["max_penetration"] == 0.0


BODY = {"surface": "upper_zmin", "master": "lower_zmax", "method": "penalty", "penalty": 1.0e7}


@pytest.mark.parametrize("raw, key, fragment", [
    ({**BODY, "method": "vi"}, "contact[0].method", "penalty"),
    ({**BODY, "method": "vi", "penalty": None}, "contact[0].method", "penalty"),
    ({**BODY, "obstacle": "plane", "point": [0, 0, 0], "normal": [0, 0, 1]}, "contact[0].obstacle", "master"),
    ({**BODY, "point": [0, 0, 0]}, "contact[0].point", "master"),
    ({**BODY, "bone": "humerus"}, "contact[0].bone", "master"),
    ({**BODY, "master": "upper_zmin"}, "contact[0].master", "differ"),
    ({**BODY, "master": ""}, "contact[0].master", "empty"),
    ({**BODY, "master": 3}, "contact[0].master", "string"),
    ({**BODY, "sliding": "yes"}, "contact[0].sliding", "true or false"),
    ({**BODY, "sliding": True, "augmented": True}, "contact[0].augmented", "sliding"),
    ({**BODY, "quadrature_degree": 2}, "contact[0].quadrature_degree", "vertex"),
    ({**BODY, "exact": True, "augmented": True}, "contact[0].augmented", "exact"),
    ({**BODY, "sliding": True, "exact": 1}, "contact[0].exact", "true or false"),
    ({"surface": "zmin", "obstacle": "plane", "point": [0, 0, 0], "normal": [0, 0, 1], "method": "penalty",
      "penalty": 1.0, "exact": True}, "contact[0].exact", "master"),
    ({"surface": "zmin", "obstacle": "plane", "point": [0, 0, 0], "normal": [0, 0, 1], "method": "penalty",
      "penalty": 1.0, "sliding": True}, "contact[0].sliding", "master"),
    ({"surface": "zmin", "method": "penalty", "penalty": 1.0}, "contact[0].obstacle", "master"),
])
def test_contact_table_errors(raw: dict, key: str, fragment: str) -> None:
    raw = {k: v for k, v in raw.items() if v is not None}
    with pytest.raises(ConfigError) as err:
        parse_contact(raw, "contact[0]")
    message = str(err.value)
    assert message.startswith(f"{key}: ") and "\n" not in message and fragment in message, message


def test_document_errors() -> None:
    """P1 only; one [[contact]] per pair."""
    raw = bodies()
    raw["discretization"]["degree"] = 2
    with pytest.raises(ConfigError, match=r"^contact\[0\]\.master: contact between bodies needs P1 .*degree 2"):
        parse(raw)
    raw = bodies()
    raw["contact"].append(dict(raw["contact"][0]))
    with pytest.raises(ConfigError, match=r"^contact\[1\]\.master: the pair 'upper_zmin' on 'lower_zmax' is "
                                          r"already contact\[0\]$"):
        parse(raw)


@pytest.mark.parametrize("change, key, fragments", [
    ({"master": "lower_top"}, "contact[0].master", ("no boundary named 'lower_top'", "lower_zmax", "upper_zmin")),
    ({"surface": "upper_bottom"}, "contact[0].surface", ("no boundary named 'upper_bottom'", "lower_zmax")),
    ({"master": "upper_xmin"}, "contact[0].master", ("shares nodes", "another body")),
])
def test_mesh_errors_before_any_solve(change: dict, key: str, fragments: tuple[str, ...]) -> None:
    """Names checked against the mesh (and listed) when the problem is built, the same on every rank."""
    with pytest.raises(ConfigError) as err:
        build(parse(bodies(**change)))
    message = str(err.value)
    assert message.startswith(f"{key}: ") and "\n" not in message, message
    for fragment in fragments:
        assert fragment in message, message
