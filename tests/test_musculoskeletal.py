"""Contact, bones and dynamics through configuration files (the musculoskeletal loop of the thesis).

The modules have their own tests (test_contact.py, test_bones.py, test_dynamics.py); these run the
examples and the configuration keys that wire them: the run contract's contact section against the
closed form, a body carried rigidly by a bone, the passive/active jiggle of a muscle on a rotating
bone, and the errors of the new sections.
"""

from __future__ import annotations

import numpy as np
import pytest
from closed_form import principal_stress
from conftest import example, run_raw
from scipy.optimize import brentq

from model.config import parse
from model.errors import ConfigError
from model.pipeline import build


def neo_hookean_compression(axial: float, params: dict) -> float:
    """Nominal stress -P33 of uniaxial compression to ``axial`` with free lateral faces (P11 = P22 = 0)."""
    lateral = brentq(lambda l: principal_stress("neo_hookean", np.array([l, l, axial]), params)[0], 0.5, 2.0,
                     xtol=1e-15)
    return -principal_stress("neo_hookean", np.array([lateral, lateral, axial]), params)[2]


@pytest.mark.parametrize("method", ["vi", "penalty"])
def test_block_on_a_rigid_plane(shared_tmp, method: str) -> None:
    raw = example("contact_block")
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    k = 1e8
    if method == "penalty":
        raw["contact"][0].update(method="penalty", penalty=k)
    summary = run_raw(raw, shared_tmp)
    last = summary["steps"][-1]
    contact = last["contact"]
    assert set(contact) == {"max_penetration", "force", "active_points"}
    assert contact["active_points"] == 25  # every node of the 4 x 4 bottom face
    params = {"E": 1.0e4, "nu": 0.3}
    if method == "vi":
        expected = neo_hookean_compression(0.9, params)  # unit area
        assert contact["max_penetration"] <= 1e-10
        assert contact["force"][2] == pytest.approx(expected, rel=1e-8)
    else:  # the penalty lets the block sink by d = p / k: the block is compressed by 0.1 - d
        d = contact["max_penetration"]
        assert 0 < d < 1e-4
        assert contact["force"][2] == pytest.approx(neo_hookean_compression(0.9 + d, params), rel=1e-8)
        assert contact["force"][2] == pytest.approx(k * d, rel=1e-6)
    np.testing.assert_allclose(contact["force"][:2], 0.0, atol=1e-8)
    assert last["reactions"]["zmax"][2] == pytest.approx(-contact["force"][2], rel=1e-9)  # equilibrium


def test_a_body_carried_by_a_bone_has_no_strain(shared_tmp) -> None:
    raw = example("uniaxial")
    raw["material"] = [{"region": "all", "law": "neo_hookean", "E": 1e4, "nu": 0.3}]
    raw["bone"] = [{"name": "b", "hinge": {"axis": [0.0, 0.0, 1.0], "point": [0.5, 0.5, 0.0],
                                            "angles": [[0.0, 0.0], [1.0, 90.0]]}}]
    raw["boundary"] = [{"on": f, "type": "attached", "bone": "b"} for f in ("xmin", "xmax", "ymin", "ymax")]
    raw["loading"] = {"steps": 3}
    raw["probe"] = [{"name": "corner", "point": [1.0, 1.0, 1.0]}]
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    summary = run_raw(raw, shared_tmp)
    last = summary["steps"][-1]
    assert abs(last["strain_energy"]) < 1e-10
    np.testing.assert_allclose(last["probes"]["corner"], [-1.0, 0.0, 0.0], atol=1e-10)  # (1, 1) -> (0, 1)


def jiggle(summary: dict, stop: float, component: int) -> float:
    """Peak-to-peak motion of the belly centre after the bone stops (the bone then holds still)."""
    after = [s for s in summary["steps"] if s["converged"] and s["time"] > stop + 1e-12]
    return float(np.ptp([s["probes"]["belly_centre"][component] for s in after]))


def test_an_activated_muscle_jiggles_less(tmp_path_factory) -> None:
    from mpi4py import MPI

    out = MPI.COMM_WORLD.bcast(str(tmp_path_factory.mktemp("rotating")), root=0)
    raw = example("rotating_muscle")
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    passive = run_raw(raw, f"{out}/passive")
    raw["material"][0]["activation"] = 1.0
    raw["dynamics"]["initial"] = "equilibrium"
    active = run_raw(raw, f"{out}/active")
    for component in (1, 2):  # across (y) and along (z) the muscle: 0.46 and 0.41 of the passive amplitude
        assert jiggle(active, 0.05, component) < 0.6 * jiggle(passive, 0.05, component)


@pytest.mark.parametrize(("mutate", "key", "fragment"), [
    (lambda r: r["contact"][0].update(normal=[1.0, 1.0, 0.0]), r"contact\[0\]\.normal", "coordinate axis"),
    (lambda r: r["contact"][0].update(method="penalty"), r"contact\[0\]\.penalty", "missing"),
    (lambda r: r["contact"][0].update(bone="femur"), r"contact\[0\]\.bone", "no \\[\\[bone\\]\\] named 'femur'"),
    (lambda r: r.update(boundary=[{"on": "zmax", "type": "attached", "bone": "femur"}]), r"boundary\[0\]\.bone",
     "no \\[\\[bone\\]\\] named 'femur'"),
    (lambda r: r.update(bone=[{"name": "b"}], boundary=[{"on": "zmax", "type": "sliding", "bone": "b",
                                                          "penalty": 1e6}]),
     r"boundary\[0\]\.bone", "has no shape"),
    (lambda r: r.update(boundary=[{"on": "zmax", "type": "attached", "bone": "b", "value": [0.0]}]),
     r"boundary\[0\]\.value", "does not apply"),
    (lambda r: r.update(bone=[{"name": "b", "hinge": {"axis": [0, 0, 0], "point": [0, 0, 0], "angles": [[0, 0]]}}]),
     r"bone\[0\]\.hinge\.axis", "must not be zero"),
    (lambda r: r.update(dynamics={"scheme": "newmark", "dt": 0.1}), r"material\[0\]\.density", "missing"),
    (lambda r: r.update(dynamics={"scheme": "newmark", "dt": -0.1}), r"dynamics\.dt", "out of range"),
    (lambda r: r.update(dynamics={"scheme": "leapfrog"}), r"dynamics\.scheme", "not one of"),
])
def test_musculoskeletal_config_errors(mutate, key: str, fragment: str) -> None:
    raw = example("contact_block")
    mutate(raw)
    with pytest.raises(ConfigError, match=rf"^{key}: .*{fragment}"):
        parse(raw)


def test_contact_surface_is_checked_against_the_mesh() -> None:
    raw = example("contact_block")
    raw["contact"][0]["surface"] = "floor"
    with pytest.raises(ConfigError, match=r"^contact\[0\]\.surface: no boundary named 'floor'"):
        build(parse(raw))
