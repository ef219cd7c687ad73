"""Elbow flexion of the layered arm against the conforming one (issue 14 item 3; examples/layered_arm_flexion.toml,
model.experiments.layered_arm.compare_flexion).

The arm segment (two muscles in fat; layered: cut open, the fat sliding on each muscle, muscle a against muscle b)
lies on a stationary humerus capsule 1 mm behind its skin; its proximal face is attached to the humerus, its distal
face to the forearm capsule, which turns forward about the elbow axis (the humerus' distal end); the muscles'
activations rise with the angle. The coarse mesh (size 15 mm, 8 elements per turn) in a few load steps: the forearm
gets to the angle, the distal face turns rigidly with it, the segment bends back onto the humerus and presses on it
(frictionless: the force is normal to the capsule's axis) without entering it beyond the penalty's p/k, the fat stays
on the muscles within its springs' give and slips on them far more, the muscles stay apart, every body is in
equilibrium (the attached faces' reactions, the humerus' push and the pairs' forces), and the layered skin's bulge
and displacement lie within stated bands of the conforming arm's (docs/layers.md has the numbers, the same on 1 and
2 ranks).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import EXAMPLES
from mpi4py import MPI

from forms.motions import HingeMotion
from model.config import RunConfig, load, parse
from model.experiments.layered_arm import (
    BONE_GAP,
    HUMERUS_RADIUS,
    TOUCHING_FLEXION,
    ArmResult,
    body_balance,
    compare_flexion,
    flexion_bones,
    flexion_config,
    run_touching_flexion,
    skin_difference,
    touching_flexion_raw,
)

#: The coarse mesh's run turns the forearm by 10 degrees (4 load steps, no cutback with the default line search): beyond
#: about 15 degrees Newton stalls on the layered arm (docs/layers.md, "Elbow flexion of the layered arm").
ANGLE = 10.0
STEPS = 4
MESH = {"size": 0.015, "turn_elements": 8}


def _assert_same_run(example: str, built: RunConfig) -> None:
    """The shipped example's configuration is ``built``, key by key."""
    shipped = load(EXAMPLES / example)
    for key in ("mesh", "discretization", "materials", "boundaries", "bones", "contacts", "loading", "petsc_options"):
        assert getattr(shipped, key) == getattr(built, key), key


def test_the_example_is_the_experiments_layered_run() -> None:
    """examples/layered_arm_flexion.toml is the layered run of these tests, flexion_config(layered=True)."""
    _assert_same_run("layered_arm_flexion.toml", flexion_config(True, ANGLE, steps=STEPS, **MESH))


@pytest.fixture(scope="module")
def runs() -> tuple[ArmResult, ArmResult]:
    return compare_flexion(angle=ANGLE, steps=STEPS, **MESH)


def test_the_forearm_turns_to_the_angle(runs: tuple[ArmResult, ArmResult]) -> None:
    """Both runs get to load factor 1; the distal face (attached to the forearm) is where the hinge carries it,
    Q X + c, and has turned by the angle about -x."""
    forearm = flexion_bones(ANGLE)[1]["hinge"]
    Q, c = HingeMotion(forearm["axis"], forearm["point"], forearm["angles"])(1.0)
    for run in runs:
        assert run.completed and run.angle == ANGLE
        X, u = run.distal_X, run.distal_u
        np.testing.assert_allclose(X + u, X @ Q.T + c, rtol=0.0, atol=1e-12)
        normal = Q @ np.array([0.0, 0.0, 1.0])  # the distal face's normal, +z at rest
        assert math.degrees(math.atan2(normal[1], normal[2])) == pytest.approx(ANGLE, abs=1e-9)  # forward, +y


def test_the_segment_rests_on_the_humerus(runs: tuple[ArmResult, ArmResult]) -> None:
    """The flexion bends the segment back onto the humerus (1 mm behind the skin at rest): the contact is active
    (measured 22-26 N on 5 nodes of the coarse skin, on one side of the line x = 0 nearest the bone, hence its x
    part), pushes the arm forward (+y) and is frictionless on the capsule's shaft (no axial force); the skin enters
    the capsule by the penalty's p / k only (5 um), far below the gap it closed."""
    for run in runs:
        bone = run.bone
        force = np.asarray(bone["force"])
        assert bone["active_points"] >= 3
        assert force[1] > 0.5 * np.linalg.norm(force) > 10.0  # N
        assert abs(force[2]) < 1e-9 * np.linalg.norm(force)
        assert 0.0 < bone["max_penetration"] < 0.05 * BONE_GAP
        assert bone["max_penetration"] < 0.01 * HUMERUS_RADIUS


def test_every_body_is_in_equilibrium(runs: tuple[ArmResult, ArmResult]) -> None:
    """Layered arm: the attached faces' reactions and the humerus' push balance (every other force is internal;
    measured 0.013 N of 25 N), and each body balances with the pairs' forces (the force on muscle a from the fat
    taken as minus the force on the fat, on muscle b from a as minus the force on a from b): below 1 % of the
    humerus' push (measured <= 0.013 N). (The conforming arm's faces share nodes, which its reactions count twice.)"""
    _, layered = runs
    residuals = body_balance(layered)
    total = residuals.pop("all")
    assert np.linalg.norm(total) < 0.01 * np.linalg.norm(layered.bone["force"]), total
    scale = np.linalg.norm(layered.bone["force"])
    for body, residual in residuals.items():
        assert np.linalg.norm(residual) < 0.01 * scale, (body, residual)
    assert MPI.COMM_WORLD.allreduce(scale, op=MPI.MAX) == scale  # the same on every rank


def test_the_fat_stays_on_the_muscles_and_slides(runs: tuple[ArmResult, ArmResult]) -> None:
    _, layered = runs
    for m in "ab":
        pair = layered.pairs[f"fat_on_{m}"]
        give = max(pair["max_gap"], pair["max_penetration"])
        assert pair["kind"] == "sliding" and pair["active_points"] > 0
        assert give < 0.1 * layered.bulge_max  # the springs hold the fat on the muscle: |g| = |p| / k
        assert layered.slip[m]["max"] > 20.0 * give  # ... and it slides along it


def test_the_muscles_do_not_enter_each_other(runs: tuple[ArmResult, ArmResult]) -> None:
    _, layered = runs
    contact = layered.pairs["a_on_b"]
    assert contact["kind"] == "contact"
    assert contact["max_penetration"] <= 1e-6 * 0.13  # the augmented Lagrangian's tolerance x the arm's size
    assert layered.muscle_gap > 0.0  # the fat between them is squeezed, not pierced


def test_layered_against_conforming(runs: tuple[ArmResult, ArmResult]) -> None:
    """The flexion's bending and shortening dominate the skin's motion (12.3 mm at most): the layered skin moves
    like the conforming one to within 0.57 mm (5 %); relative to the mid-length section's translation the
    layered skin bulges more (1.30 against 1.05 mm at most, 0.72 against 0.63 mm on average: the muscles, free to
    slide, do not hold the fat's section), within 1.05-1.6 times the conforming bulge; the bone's push differs by
    less than 20 %; the fat slips on the muscles by 1.4-1.5 mm (a and b alike: the bending, not the activation,
    drives it)."""
    conforming, layered = runs
    assert conforming.bulge_max > 0.0 and layered.bulge_max > 0.0
    assert 1.05 * conforming.bulge_max < layered.bulge_max < 1.6 * conforming.bulge_max
    assert 1.05 * conforming.bulge_mean < layered.bulge_mean < 1.6 * conforming.bulge_mean
    difference = skin_difference(conforming, layered)
    assert 0.0 < difference["max"] < 0.1 * difference["max_conforming"]
    push = [np.linalg.norm(run.bone["force"]) for run in runs]
    assert push[1] == pytest.approx(push[0], rel=0.2)
    for m in "ab":
        assert 0.5e-3 < layered.slip[m]["max"] < 3e-3  # m
    assert MPI.COMM_WORLD.allreduce(layered.bulge_max, op=MPI.MAX) == layered.bulge_max  # the same on every rank


# --- the touching muscles flexed: the activation presses their shared face, the flexion unloads it ----------------


def test_the_touching_example_is_the_experiments_run() -> None:
    """examples/layered_arm_touching_flexion.toml is run_touching_flexion's configuration."""
    _assert_same_run("layered_arm_touching_flexion.toml", parse(touching_flexion_raw()))


@pytest.fixture(scope="module")
def touching() -> ArmResult:
    return run_touching_flexion()


def test_the_activation_presses_the_muscles_and_the_flexion_unloads_them(touching: ArmResult) -> None:
    """The muscles' shared face (a_flat against b_flat, penalty 1e11) through the load, both muscles activated to 1
    over its first half, the forearm turned by 5 degrees over the second (measured, Debian 12: 5.11, 10.30, 4.29,
    0.022 N on 34, 34, 22, 1 nodes): the force rises with the activation (about linearly), and the flexion takes it
    back, first by more than 40 %, then to below 2 % (Debian 13's mesh: 5.07, 10.21, 4.23, 0.094 N); the force
    pushes a along -x, the face's normal; the faces never enter each other beyond the penalty's p / k (3.1 um at
    10 N)."""
    assert touching.completed and touching.angle == TOUCHING_FLEXION["angle"]
    history = touching.history
    assert [h["load_factor"] for h in history] == pytest.approx([0.0, 0.25, 0.5, 0.75, 1.0])
    force = [h["normal_force"] for h in history]
    active = [h["active_points"] for h in history]
    assert force[0] == pytest.approx(0.0, abs=1e-12)
    assert 5.0 < force[2] < 20.0 and force[1] == pytest.approx(0.5 * force[2], rel=0.1)  # N
    assert 0.2 * force[2] < force[3] < 0.6 * force[2] and force[4] < 0.02 * force[2]
    assert active[1] >= 10 and active[2] >= active[3] >= active[4]
    assert all(0.0 <= h["max_penetration"] < 1e-5 for h in history)  # m
    assert history[2]["force"][0] == pytest.approx(-force[2], rel=1e-3)
    assert MPI.COMM_WORLD.allreduce(force[2], op=MPI.MAX) == force[2]  # the same on every rank


def test_the_touching_arm_balances_and_its_fat_slides(touching: ArmResult) -> None:
    """Each body balances with its faces' reactions and the pairs' forces to 0.1 % of the largest contact force
    (measured 1.7e-3 N of 10.3 N), the distal face turned rigidly with the forearm, and the fat stays on the
    muscles within its springs' give while slipping on them far more (0.63 / 0.62 mm at most on a / b)."""
    largest = max(h["normal_force"] for h in touching.history)
    for body, residual in body_balance(touching).items():
        assert np.linalg.norm(residual) < 1e-3 * largest, (body, residual)
    Q, c = HingeMotion(**flexion_bones(TOUCHING_FLEXION["angle"])[1]["hinge"])(1.0)
    np.testing.assert_allclose(touching.distal_X + touching.distal_u, touching.distal_X @ Q.T + c, atol=1e-12)
    for m in "ab":
        pair = touching.pairs[f"fat_on_{m}"]
        give = max(pair["max_gap"], pair["max_penetration"])
        assert give < 0.1 * touching.bulge_max
        assert touching.slip[m]["max"] > 20.0 * give
