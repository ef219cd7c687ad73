"""The support check (model.problem.supports): a mesh piece with a rigid-body mode nothing holds is a one-line
ConfigError naming the piece and the free modes, before any solve; every shipped example passes it; contact between
deformable bodies is a warning, a dynamic run and [solver] allow_rigid_modes = true skip it. Collective: runs serially
and under mpirun -n 2 (the same pieces, numbers and messages)."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import EXAMPLES, RUN_EXAMPLES, example, run_raw
from mpi4py import MPI

from model.errors import ConfigError

QUIET = {"xdmf": False, "vtu": False, "png": False}
REMEDY = "add a displacement boundary condition, a bone"


def box(*boundaries: dict[str, Any], cells: int = 2) -> dict[str, Any]:
    """A unit cube (6 tetrahedra per hexahedron) pulled on x = 1, with the given extra boundary conditions."""
    return {"mesh": {"generator": "box", "size": [1.0, 1.0, 1.0], "cells": [cells, cells, cells]},
            "material": [{"region": "all", "law": "neo_hookean", "E": 1.0e4, "nu": 0.3}],
            "boundary": [{"on": "xmax", "type": "traction", "value": [100.0, 0.0, 0.0]}, *boundaries],
            "loading": {"steps": 1},
            "output": dict(QUIET)}


def refused(raw: dict[str, Any], out: Path) -> str:
    """The ConfigError's message of a run of ``raw`` (nothing solved or written: no summary.json)."""
    with pytest.raises(ConfigError) as caught:
        run_raw(raw, out)
    message = str(caught.value)
    assert "\n" not in message
    assert not (out / "summary.json").exists()
    return message


def check(raw: dict[str, Any]) -> list[str]:
    """Build ``raw`` and run the check alone (no solve); its warnings."""
    from model.config import parse
    from model.pipeline import build
    from model.problem.supports import check_supports

    setup = build(parse(raw, EXAMPLES))
    return check_supports(setup.problem, setup.contacts, setup.sliding)


def test_traction_only_box_is_refused(shared_tmp: Path) -> None:
    message = refused(box(), shared_tmp)
    assert message.startswith("boundary: the body (region 'body', 48 cells, centroid (0.5, 0.5, 0.5)): nothing holds "
                              "its translation along x, y and z and rotation about x, y and z: " + REMEDY), message


def test_one_component_on_a_face_holds_one_translation_and_two_rotations(shared_tmp: Path) -> None:
    """u_x = 0 on x = 0 holds the translation along x and the rotations about y and z (the rank of its rows applied
    to the six modes is 3): the others are named. Also in the mixed formulation (its displacement dofs)."""
    roller = {"on": "xmin", "type": "displacement", "components": [0], "value": [0.0]}
    for raw in (box(roller), {**box(roller, cells=1),
                              "discretization": {"degree": 2, "quadrature_degree": 2, "formulation": "mixed"}}):
        message = refused(raw, shared_tmp)
        assert ": nothing holds its translation along y and z and rotation about x: " + REMEDY in message, message


def test_held_boxes_pass() -> None:
    """Clamped; three rollers (the uniaxial example's: x, y, z on three faces); a single clamped node holds the
    translations only."""
    assert check(box({"on": "xmin", "type": "displacement", "value": [0.0, 0.0, 0.0]})) == []
    rollers = [{"on": f, "type": "displacement", "components": [i], "value": [0.0]}
               for i, f in enumerate(("xmin", "ymin", "zmin"))]
    assert check(box(*rollers)) == []
    with pytest.raises(ConfigError, match=r"nothing holds its rotation about x, y and z: "):
        check(box({"on": "xmin", "type": "displacement", "value": [0.0, 0.0, 0.0], "points": [[0.0, 0.0, 0.0]]}))


def two_boxes(path: Path) -> Path:
    """A .msh file of two unit boxes side by side (1 apart along x), regions box_a and box_b: two pieces."""
    from meshes import box as make_box
    from meshes.combine import combine, moved
    from meshes.data import write_msh

    if MPI.COMM_WORLD.rank == 0:
        block = make_box((1.0, 1.0, 1.0), (2, 2, 2))
        write_msh(combine({"box_a": block, "box_b": moved(block, (2.0, 0.0, 0.0))}), path)
    MPI.COMM_WORLD.barrier()
    return path


def test_loaded_piece_beside_a_clamped_one_is_refused(shared_tmp: Path) -> None:
    raw = box()
    raw["mesh"] = {"file": str(two_boxes(shared_tmp / "two_boxes.msh"))}
    raw["boundary"] = [{"on": "box_a_xmin", "type": "displacement", "value": [0.0, 0.0, 0.0]},
                       {"on": "box_b_xmax", "type": "traction", "value": [100.0, 0.0, 0.0]}]
    message = refused(raw, shared_tmp / "run")
    assert message.startswith("boundary: mesh piece 2 of 2 (region 'box_b', 48 cells, centroid (2.5, 0.5, 0.5)): "
                              "nothing holds its translation along x, y and z and rotation about x, y and z: "), message
    raw["boundary"].append({"on": "box_b_xmin", "type": "displacement", "value": [0.0, 0.0, 0.0]})
    assert check(raw) == []


def test_pieces_in_contact_warn_and_a_floating_pair_is_refused(shared_tmp: Path) -> None:
    """The stacked blocks (examples/contact_bodies.toml): the upper block's rollers leave its translation along z to
    the contact with the lower one: a warning. Without the lower block's support the pair floats as a whole along
    z: refused."""
    raw = example("contact_bodies")
    raw["output"] = dict(QUIET)
    warnings = check(copy.deepcopy(raw))
    assert warnings == ["mesh piece 2 of 2 (region 'upper', 48 cells, centroid (0.5, 0.5, 1.5)): only contact with "
                        "mesh piece 1 can hold its translation along z; a solve fails while that contact is open"]
    raw["boundary"] = [b for b in raw["boundary"] if b["on"] != "lower_zmin"]
    message = refused(raw, shared_tmp)
    assert message.startswith("boundary: mesh pieces 1 and 2 of 2 (in contact with one another): nothing holds their "
                              "translation along z as a whole: "), message


def test_sliding_on_a_bone_holds_the_normal() -> None:
    """A box sliding on a plane bone (its face z = 0 on the plane z = 0: zero-length normal springs) and rollers on
    x = 0 and y = 0: held (the plane holds the translation along z and the rotations about x and y)."""
    raw = box({"on": "zmin", "type": "sliding", "bone": "floor", "penalty": 1.0e6},
              {"on": "xmin", "type": "displacement", "components": [0], "value": [0.0]},
              {"on": "ymin", "type": "displacement", "components": [1], "value": [0.0]})
    raw["bone"] = [{"name": "floor", "obstacle": "plane", "point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0]}]
    assert check(copy.deepcopy(raw)) == []
    raw["boundary"] = raw["boundary"][:3]  # without the roller on y = 0: the translation along y is free
    with pytest.raises(ConfigError, match=r"nothing holds its translation along y: "):
        check(raw)


def test_allow_rigid_modes_and_dynamics_skip_the_check(shared_tmp: Path) -> None:
    """[solver] allow_rigid_modes = true: no ConfigError (the solve is the user's; with MUMPS the singular system
    fails or drifts: either is accepted here), and summary.json's warnings say the check was skipped. A dynamic run
    needs no support: a free box accelerates."""
    from model.errors import SolveFailed

    raw = box(cells=1)
    raw["solver"] = {"allow_rigid_modes": True}
    raw["loading"] = {"steps": 1, "max_cutbacks": 0}
    try:
        run_raw(raw, shared_tmp / "allowed")
    except SolveFailed:
        pass
    import json

    warnings = json.loads((shared_tmp / "allowed" / "summary.json").read_text())["warnings"]
    assert warnings[0].startswith("the support check was skipped (solver.allow_rigid_modes = true)"), warnings
    raw = box(cells=1)
    raw["material"][0]["density"] = 1000.0
    raw["dynamics"] = {"scheme": "newmark", "dt": 0.01, "end_time": 0.01}
    summary = run_raw(raw, shared_tmp / "dynamic")
    assert summary["status"] == "completed" and summary["steps"][-1]["converged"]


#: mesh overrides that keep the examples' meshing short (the supports do not depend on the mesh size)
COARSER = {"arm_segment": {"size": 0.016, "turn_elements": 8}, "layered_arm": {"size": 0.018},
           "layered_arm_gap": {"size": 0.03, "gap": 0.003}, "arm_flexion": {"size": 0.016},
           "layered_arm_flexion": {"size": 0.0225}, "layered_arm_touching_flexion": {"size": 0.0225}}


@pytest.mark.parametrize("path", RUN_EXAMPLES, ids=[p.stem for p in RUN_EXAMPLES])
def test_shipped_examples_pass_the_check(path: Path) -> None:
    """Every examples/*.toml (solid runs) builds and passes the check (meshes coarsened where meshing is slow); the
    only warning is the stacked blocks' contact."""
    raw = example(path.stem)
    raw["mesh"].update(COARSER.get(path.stem, {}))
    warnings = check(raw)
    assert len(warnings) == (1 if path.stem == "contact_bodies" else 0), warnings


def test_pieces_are_numbered_by_centroid() -> None:
    """mesh_pieces: the same numbering on any number of ranks (by centroid), every local cell labelled."""
    from model.config import parse
    from model.pipeline import build
    from model.problem.supports import mesh_pieces

    raw = {"mesh": {"generator": "stacked_blocks", "size": [1.0, 1.0, 1.0], "cells": [2, 2, 2], "gap": 0.5},
           "material": [{"region": "all", "law": "neo_hookean", "E": 1.0e4, "nu": 0.3}],
           "boundary": [{"on": "lower_zmin", "type": "displacement", "value": [0.0, 0.0, 0.0]}]}
    domain = build(parse(raw, EXAMPLES)).domain
    labels, pieces = mesh_pieces(domain)
    assert [p.number for p in pieces] == [1, 2] and [p.regions for p in pieces] == [["lower"], ["upper"]]
    assert [p.cells for p in pieces] == [48, 48]
    np.testing.assert_allclose(pieces[1].centroid, [0.5, 0.5, 2.0], atol=1e-12)
    upper = domain.region_cells("upper")
    assert np.all(labels[upper] == 1) and np.all(labels[domain.region_cells("lower")] == 0)
