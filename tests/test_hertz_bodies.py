"""Hertz contact with both bodies deformable (issue 14): two elastic spheres (octants, E2 = 2 E1, non-matching
meshes) pressed together by an approach d = 2e-3 R (contact radius a = (R d / 2)^(1/2) = 0.032 R), contact
between the bodies with augmented-Lagrangian penalty (model.experiments.hertz; model.problem.body_contact).

Against F = (4/3) E* (R/2)^(1/2) d^(3/2), 1/E* = (1 - nu^2)/E1 + (1 - nu^2)/E2, and a = (R d / 2)^(1/2): within
5 % on the finest mesh (pole size 0.004, P1). The force error falls with h (+7.15, +4.69, +3.25 % for the pole
sizes 0.008, 0.0057, 0.004 with the grading and far size scaled alike: -m slow; observed order 1.5), towards the
finite spheres' stiffening (Richardson: -0.2 to +1.2 %; docs/layers.md).
"""

from __future__ import annotations

import math

import pytest

from model.experiments.hertz import hertz_force, hertz_spheres

#: (pole size, growth, far size): the graded mesh refined as a whole by 2^(1/2) per level
MESHES = ((0.008, 0.3, 0.25), (0.008 / 2**0.5, 0.3 / 2**0.5, 0.25 / 2**0.5), (0.004, 0.15, 0.125))
D = 2.0e-3


def test_hertz_force_formula() -> None:
    """Two equal spheres of equal material: F = (4/3) E/(2 (1 - nu^2)) (R/2)^(1/2) d^(3/2); a rigid plane
    (E2 -> inf, R2 -> inf) gives the sphere-on-plane (4/3) E/(1 - nu^2) R^(1/2) d^(3/2)."""
    E, nu, R, d = 1.0e4, 0.3, 1.0, 1e-3
    assert hertz_force(d, R, R, E, E, nu, nu) == pytest.approx(4 / 3 * E / (2 * (1 - nu**2)) * math.sqrt(R / 2)
                                                               * d**1.5, rel=1e-14)
    assert hertz_force(d, R, 1e30, E, 1e30, nu, nu) == pytest.approx(4 / 3 * E / (1 - nu**2) * d**1.5, rel=1e-12)


def test_two_deformable_spheres_against_hertz() -> None:
    """The finest test mesh, two load steps (one step converges on Debian 12 in 17 Newton iterations, but Debian
    13's mesh needs a cut-back after 30): force within 5 % of Hertz, F ~ d^(3/2), contact radius within one pole
    size, penetration below the Uzawa tolerance (1e-6 of the bounding-box diagonal)."""
    pole, growth, size = MESHES[-1]
    result = hertz_spheres(pole, growth, size, approach=D, steps=2)
    assert result.completed
    half, point = result.points
    assert point.approach == pytest.approx(D, rel=1e-12)
    assert math.log(point.force / half.force) / math.log(2.0) == pytest.approx(1.5, abs=0.05)
    assert abs(point.error) < 0.05, point
    assert point.error > 0.0  # P1 and the finite spheres are both stiffer than Hertz's half-spaces
    assert abs(point.contact_radius - math.sqrt(0.5 * D)) <= pole, point
    assert point.max_penetration <= 1e-6 * result.contact.size
    assert point.uzawa_rounds <= 4, point


def test_spheres_that_start_apart() -> None:
    """meshes.sphere_pair(gap = g0 = D): the spheres start D apart and the upper equator moves down by 2 D in three
    steps (coarse mesh): at t = 1/3 they are still apart (d = -D/3: no force, no active node), then touch, and from
    there the run is the touching spheres' moved rigidly by g0 (neo-Hookean: translation does not change the stress):
    the force at the approach d = t 2D - g0 is the force of the run without a gap at the same d (the same at d = D/3,
    2e-4 apart at d = D: the Uzawa rounds' different paths, within their tolerance), and within the coarse mesh's
    error of Hertz's (+7.8 % at D/3, +7.2 % at D). 10 s."""
    pole, growth, size = MESHES[0]
    apart = hertz_spheres(pole, growth, size, approach=D, steps=3, gap=D)
    touching = hertz_spheres(pole, growth, size, approach=D, steps=3)
    assert apart.completed and touching.completed and len(apart.points) == 3
    first, *pressed = apart.points
    assert first.approach == pytest.approx(-D / 3, rel=1e-12)
    assert first.force == 0.0 and first.active_points == 0 and first.hertz == 0.0
    assert [p.approach for p in pressed] == pytest.approx([D / 3, D], rel=1e-9)
    same = {round(p.approach / D, 6): p for p in touching.points}
    for point in pressed:
        assert point.active_points > 0
        reference = same[round(point.approach / D, 6)]
        assert point.force == pytest.approx(reference.force, rel=1e-3), (point, reference)
        assert 0.0 < point.error < 0.12, point  # P1 on the coarse mesh: +7 % at d = D


@pytest.mark.slow
def test_hertz_mesh_refinement_and_exponent() -> None:
    """Three meshes: errors fall (about like h), the finest within 5 %; F ~ d^(3/2) between d/2 and d."""
    errors = []
    for pole, growth, size in MESHES:
        result = hertz_spheres(pole, growth, size, approach=D, steps=2)
        half, full = result.points
        errors.append(full.error)
        assert math.log(full.force / half.force) / math.log(2.0) == pytest.approx(1.5, abs=0.05)
    assert errors[0] > errors[1] > errors[2] > 0.0 and errors[2] < 0.05, errors
