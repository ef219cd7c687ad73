"""Self-contact of one membrane (model.problem.membrane_contact.MembraneSelfContact, docs/membranes.md).

The two mirror-image clamped discs of meshes.membrane.facing_discs (H = 0.8 apart, StVK, from a bump 0.3, p = 2e-3,
4e-3, 6e-3), taken as one membrane (region "all") against itself: the rule finds the other disc's triangles for
every node in contact (the own disc's lie beside the node at rest, |c| < 1/2: never paired), so the answer is that
of the two-pass pair contact (lower against upper and upper against lower) to round-off; the penetration falls as
1/k, the contact forces are internal (sum 0), the answer is mirror-symmetric; without the contact the discs pass
through each other; before they meet the answer is the one without contact (no pair active).
"""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI
from test_membrane_contact import _pressed_discs

from model.problem.membrane_contact import MembraneSelfContact, pair_contacts
from model.solvers.membrane import inflate

COMM = MPI.COMM_WORLD
H, BUMP = 0.8, 0.3
PRESSURES = [2e-3, 4e-3, 6e-3]


def _largest(values: np.ndarray) -> float:
    return COMM.allreduce(float(values.max(initial=-np.inf)), op=MPI.MAX)


def _run(kind: str, k: float = 10.0, pressures: list[float] | None = None) -> tuple[np.ndarray, list, list]:
    """The pressed discs with ``kind`` contact ("self", "two_pass" or "none"): u (owned rows), the steps and the
    contacts."""
    problem = _pressed_discs(H, BUMP)
    contacts = [MembraneSelfContact(problem, k)] if kind == "self" else \
        pair_contacts(problem, "lower", "upper", k, two_pass=True) if kind == "two_pass" else []
    steps = inflate(problem, pressures or PRESSURES)
    n = problem.V.dofmap.index_map.size_local
    return problem.u.x.array.reshape(-1, 3)[:n].copy(), steps, contacts


def test_self_contact_of_two_facing_sheets() -> None:
    """Self-contact of the whole membrane = the two-pass pair contact (displacements to 1e-10 of max |u|, the same
    penetration); penetration below 2 p / k, measured 4.148e-4 (k = 10) and 1.037e-4 (k = 40): ratio 4 = the
    ratio of the k; slave + master force = 0; max u_z = -min u_z (the mirror image); without contact max u_z =
    0.588 > H/2 (the discs cross), with it 0.4002 (each stops at the middle plane, the penetration shared)."""
    u_self, steps, (self_contact,) = _run("self")
    report = self_contact.report()
    u_two, _, passes = _run("two_pass")
    scale = _largest(np.abs(u_two))
    assert _largest(np.abs(u_self - u_two)) < 1e-10 * scale
    assert report["max_penetration"] == pytest.approx(passes[0].report()["max_penetration"], rel=1e-8)
    assert 0.0 < report["max_penetration"] < 2 * PRESSURES[-1] / 10.0
    assert report["active_points"] > 0 and report["paired_points"] >= report["active_points"]
    assert np.allclose(np.add(report["force"], report["master_force"]), 0.0, atol=1e-14)
    top, bottom = _largest(u_self[:, 2]), _largest(-u_self[:, 2])
    assert top == pytest.approx(bottom, rel=1e-8) and H / 2 - 1e-3 < top < H / 2 + 1e-3
    assert max(s.iterations for s in steps) <= 25
    _, _, (stiffer,) = _run("self", k=40.0)
    ratio = report["max_penetration"] / stiffer.report()["max_penetration"]
    assert ratio == pytest.approx(4.0, rel=0.05)
    u_free, _, _ = _run("none")
    assert _largest(u_free[:, 2]) > H / 2 + 0.1  # without contact the discs pass through each other


def test_apart_is_the_answer_without_contact() -> None:
    """Before the discs meet (p = 5e-4): no node pressed, the displacements of the run without contact to Newton's
    tolerance (measured 1.1e-10 of max |u| = 0.243: the contact's Newton takes the l2 line search, the run without
    it backtracking, so the last iterates differ in round-off of the tolerance, not in the equilibrium)."""
    u_self, _, (self_contact,) = _run("self", pressures=[5e-4])
    u_free, _, _ = _run("none", pressures=[5e-4])
    assert self_contact.report()["active_points"] == 0
    assert _largest(np.abs(u_self - u_free)) <= 1e-8 * _largest(np.abs(u_free))


@pytest.mark.parametrize(("keys", "message"), [
    ({"rings": 0}, r"^membrane self-contact: rings: 0 must be an integer >= 1$"),
    ({"reach": -1.0}, r"^membrane self-contact: reach: -1\.0 must be a finite number > 0$"),
    ({"region": "middle"}, r"^membrane self-contact: region: no region named 'middle'"),
])
def test_bad_arguments(keys: dict, message: str) -> None:
    problem = _pressed_discs(H, BUMP)
    with pytest.raises(ValueError, match=message):
        MembraneSelfContact(problem, 10.0, **keys)
