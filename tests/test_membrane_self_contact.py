"""Self-contact of one membrane (model.problem.membrane_contact.MembraneSelfContact, docs/membranes.md).

A closed can (meshes.membrane.closed_can: radius 1, height H = 0.8, size 0.2; one connected membrane, its triangles
oriented inward), its wall held, StVK, pressed inward (p = 2e-3, 4e-3, 6e-3) from bumps 0.3 of its ends towards
each other: its two ends are facing_discs' mirror-image lower and upper discs, clamped at their rims, so the
self-contact of the whole can (the rule finds the other end's triangles for every pressed node) must give the
two-pass pair contact of the facing discs (each disc slave and master in turn) to round-off, node by node; the
penetration falls as 1/k, the contact forces are internal (sum 0), the answer is mirror-symmetric; without the
contact the ends pass through each other; before they meet the answer is the one without contact (no pair active).
From a config: examples/membrane_can.toml ([[contact]] self_contact = true on surface = "closed_can") gives the same
numbers; bad combinations of the keys are one-line ConfigErrors naming the key.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import EXAMPLES
from mpi4py import MPI
from scipy.spatial import cKDTree
from test_membrane_contact import STVK, _pressed_discs

from meshes.membrane import closed_can
from model.config.membrane import load_membrane, parse_membrane
from model.domain.distribute import build_domain
from model.errors import ConfigError
from model.problem.membrane import MembraneProblem, triangle_orientation
from model.problem.membrane_contact import MembraneSelfContact, pair_contacts
from model.solvers.membrane import inflate

COMM = MPI.COMM_WORLD
CAN = EXAMPLES / "membrane_can.toml"
H, BUMP, SIZE = 0.8, 0.3, 0.2
PRESSURES = [2e-3, 4e-3, 6e-3]


def _largest(values: np.ndarray) -> float:
    return COMM.allreduce(float(values.max(initial=-np.inf)), op=MPI.MAX)


def _gathered(problem: MembraneProblem) -> tuple[np.ndarray, np.ndarray]:
    """Every rank's owned nodes: rest points and displacements (the same on every rank)."""
    n = problem.V.dofmap.index_map.size_local
    X = problem.V.tabulate_dof_coordinates()[:n, :3]
    u = problem.u.x.array.reshape(-1, 3)[:n]
    return np.vstack(COMM.allgather(X)), np.vstack(COMM.allgather(u))


def _can(k: float | None = 10.0, pressures: list[float] | None = None, **keys: object
         ) -> tuple[MembraneProblem, list, MembraneSelfContact | None]:
    """The closed can, wall held, ends from bumps towards each other, inflated (inward); ``k`` None: no contact."""
    data = closed_can(1.0, H, SIZE) if COMM.rank == 0 else None
    orientation = triangle_orientation(*COMM.bcast((data.points, data.cells) if COMM.rank == 0 else None))
    problem = MembraneProblem(build_domain(COMM, data), STVK, orientation, {"wall": (0, 1, 2)})
    problem.u.interpolate(lambda x: np.vstack([0 * x[0], 0 * x[0], np.where(x[2] < H / 2, 1, -1) * BUMP
                                               * np.maximum(1 - x[0] ** 2 - x[1] ** 2, 0.0)]))
    contact = MembraneSelfContact(problem, k, **keys) if k is not None else None
    steps = inflate(problem, pressures or PRESSURES)
    return problem, steps, contact


def test_self_contact_of_a_closed_can() -> None:
    """The can's self-contact = the facing discs' two-pass contact (displacements node by node to 1e-10 of max
    |u| = 0.400, measured 1.2e-13; the same penetration 4.148e-4 < 2 p / k); k = 40: 1.037e-4 (the ratio 4 = the
    ratio of the k); slave + master force = 0; max u_z = -min u_z (the mirror image); the ends stop at the middle
    plane (max u_z = 0.4002), without contact they pass through it (0.588)."""
    problem, steps, contact = _can()
    report = contact.report()
    X, u = _gathered(problem)
    discs = _pressed_discs(H, BUMP)
    passes = pair_contacts(discs, "lower", "upper", 10.0, two_pass=True)
    inflate(discs, PRESSURES)
    X2, u2 = _gathered(discs)
    distance, index = cKDTree(X).query(X2)
    assert distance.max() < 1e-12
    assert np.abs(u[index] - u2).max() < 1e-10 * np.abs(u2).max()
    assert report["max_penetration"] == pytest.approx(passes[0].report()["max_penetration"], rel=1e-8)
    assert 0.0 < report["max_penetration"] < 2 * PRESSURES[-1] / 10.0
    assert report["active_points"] > 0 and report["paired_points"] >= report["active_points"]
    assert np.allclose(np.add(report["force"], report["master_force"]), 0.0, atol=1e-14)
    assert u[:, 2].max() == pytest.approx(-u[:, 2].min(), rel=1e-8)
    assert H / 2 - 1e-3 < u[:, 2].max() < H / 2 + 1e-3
    assert max(s.iterations for s in steps) <= 25
    stiffer = _can(40.0)[2].report()["max_penetration"]
    assert report["max_penetration"] / stiffer == pytest.approx(4.0, rel=0.05)
    free, _, _ = _can(None)
    assert _largest(free.u.x.array.reshape(-1, 3)[:, 2]) > H / 2 + 0.1  # without contact the ends cross


def test_apart_is_the_answer_without_contact() -> None:
    """Before the ends meet (p = 5e-4): no node pressed, the displacements of the run without contact to Newton's
    tolerance (measured 1.1e-10 of max |u| = 0.243: the contact's Newton takes the l2 line search, the run without
    it backtracking, so the last iterates differ in round-off of the tolerance, not in the equilibrium)."""
    problem, _, contact = _can(pressures=[5e-4])
    free, _, _ = _can(None, pressures=[5e-4])
    assert contact.report()["active_points"] == 0
    u, u_free = problem.u.x.array, free.u.x.array
    assert _largest(np.abs(u - u_free)) <= 1e-8 * _largest(np.abs(u_free))


@pytest.mark.parametrize(("keys", "message"), [
    ({"rings": 0}, r"^membrane self-contact: rings: 0 must be an integer >= 1$"),
    ({"reach": -1.0}, r"^membrane self-contact: reach: -1\.0 must be a finite number > 0$"),
    ({"region": "middle"}, r"^membrane self-contact: region: no region named 'middle'"),
    ({"augmented": True}, r"^membrane self-contact: penalty only"),
])
def test_bad_arguments(keys: dict, message: str) -> None:
    problem = _pressed_discs(H, BUMP)
    with pytest.raises(ValueError, match=message):
        MembraneSelfContact(problem, 10.0, **keys)


def test_the_example(shared_tmp) -> None:  # noqa: ANN001
    """examples/membrane_can.toml: the numbers of test_self_contact_of_a_closed_can (penetration 4.148e-4, the ends'
    deflection 0.4002, 40 pressed nodes, Newton 7, 19, 14), the contact recorded with its rings and reach."""
    from model.experiments.membrane_run import run_membrane

    config = load_membrane(CAN)
    summary = run_membrane(config, shared_tmp / "can", COMM)
    assert summary["status"] == "completed"
    (spec,) = summary["pairs"]
    assert spec["self_contact"] is True and spec["region"] == "all" and spec["rings"] == 2
    assert spec["reach"] == pytest.approx(0.18, rel=0.2)
    last = summary["steps"][-1]
    (pair,) = last["pairs"]
    assert pair["pair"] == "all-self" and pair["active_points"] > 0
    assert pair["max_penetration"] == pytest.approx(4.1479e-4, rel=1e-3)
    assert last["centre_deflection"] == pytest.approx(0.40021, rel=1e-4)
    assert np.allclose(np.add(pair["force"], pair["master_force"]), 0.0, atol=1e-14)


@pytest.mark.parametrize(("contact", "message"), [
    ({"master": "upper"}, r"^contact\[0\]\.master: not with self_contact = true \(the surface is its own master\)$"),
    ({"two_pass": True}, r"^contact\[0\]\.two_pass: not with self_contact = true"),
    ({"augmented": True}, r"^contact\[0\]\.augmented: not with self_contact = true"),
    ({"tolerance": 1e-6}, r"^contact\[0\]\.tolerance: not with self_contact = true \(penalty only: there is no "
                          r"Uzawa tolerance\)$"),
    ({"surface": "top"}, r"^contact\[0\]\.surface: closed_can has no region 'top' \(regions: lower, upper, wall\)$"),
    ({"rings": 0}, r"^contact\[0\]\.rings: "),
    ({"reach": -0.1}, r"^contact\[0\]\.reach: "),
    ({"self_contact": False, "surface": "lower"}, r"^contact\[0\]\.master: missing"),
    ({"self_contact": False, "surface": "lower", "master": "upper", "rings": 2}, r"^contact\[0\]\.rings: only with "
                                                                     r"self_contact = true$"),
])
def test_bad_self_contact_keys(contact: dict, message: str) -> None:
    base = {"self_contact": True, "penalty": 10.0}
    with pytest.raises(ConfigError, match=message) as err:
        load_membrane(CAN, {"contact": [{**base, **contact}]})
    assert "\n" not in str(err.value)


def test_contact_names_and_surfaces() -> None:
    """Two contacts with one name are refused (summary.json reports each by name); self-contact on the flat disc is
    refused (no node lies off another triangle's plane at rest: it could never pair); surface = "all" spelled out is
    the default's whole membrane."""
    with pytest.raises(ConfigError, match=r"^contact\[1\]\.name: 'x' names two contacts") as err:
        load_membrane(CAN, {"contact": [{"self_contact": True, "penalty": 10.0, "name": "x"},
                                        {"self_contact": True, "penalty": 10.0, "surface": "lower", "name": "x"}]})
    assert "\n" not in str(err.value)
    with pytest.raises(ConfigError, match=r"^contact\[0\]\.self_contact: the disc is flat at rest"):
        parse_membrane({"membrane": {"surface": "disc", "radius": 1.0, "size": 0.2, "law": "stvk", "young": 1.0,
                                     "nu": 0.3, "thickness": 0.01},
                        "contact": [{"self_contact": True, "penalty": 10.0}], "inflation": {"pressures": [1e-3]}},
                       EXAMPLES)
    config = load_membrane(CAN, {"contact": [{"self_contact": True, "penalty": 10.0, "surface": "all"}]})
    assert config.contacts[0].region == "all" and config.contacts[0].label == "all-self"
