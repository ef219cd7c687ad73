"""The arm_segment generator (meshes.arm_segment) and the cylinder's axis vertices.

arm_segment: named groups and tags, volumes and areas against closed forms, layout, conformity
across the fat/muscle/tendon interfaces, parameter errors.  Rank-independent: every rank builds
its own mesh, so it also passes under mpirun -n 2.

Faceting tolerances: curved surfaces carry CURVATURE_ELEMENTS = 16 elements per 2 pi, and every
mesh vertex lies on the exact surface, so a circle of radius r is an inscribed polygon of >= 16
sides, whose area is short of pi r^2 by at most 1 - 16 sin(2 pi / 16) / (2 pi) = 2.55 %
(FACETING_16).  The tendon disks are exactly 16-gons (-2.550 % measured); the convex tendons lose
between 0 and 2.55 % (-1.83 % measured), the bellies about as much (-1.58 %, -1.60 %; their profile
is not convex in z, so the sign is not guaranteed and the check is two-sided).  The fat is the
cylinder (skin circle R = 0.03 with edges <= size = 0.005: >= 38 sides, <= 0.46 % short) minus the
muscles (up to 2.55 % of their volume too little removed, i.e. up to 0.3 % of the fat gained):
-0.19 % measured, checked to 1 %.  The end faces (proximal, distal): -0.38 % measured, checked to 1 %.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_meshes import assert_conforming, assert_valid, face_points, key_set

from meshes import GENERATORS, ParameterError, arm_segment, cylinder, generate
from meshes.arm_segment import ARM_SEGMENT_FACES, ARM_SEGMENT_REGIONS, belly_volume
from meshes.topology import signed_volumes, tet_faces

L, R, RM, RT, LT, SPACING = 0.12, 0.03, 0.011, 0.004, 0.02, 0.024
#: Largest relative area deficit of a circle faceted by an inscribed polygon of 16 sides.
FACETING_16 = 1.0 - 16.0 * math.sin(2.0 * math.pi / 16.0) / (2.0 * math.pi)


@pytest.fixture(scope="module")
def arm():
    """The arm segment at its default parameters (once per module)."""
    return arm_segment()


def area(mesh, name: str) -> float:
    """Total area of the triangles of the boundary ``name``."""
    p = mesh.points[mesh.boundary_facets(name)]
    return float(0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum())


def relative_error(value: float, exact: float) -> float:
    return value / exact - 1.0


# --- arm_segment ------------------------------------------------------------------------------------


def test_registered() -> None:
    assert GENERATORS["arm_segment"] is arm_segment


def test_names_and_tags(arm) -> None:
    assert arm.region_names == {"fat": 1, "belly_a": 2, "tendon_a": 3, "belly_b": 4, "tendon_b": 5}
    assert arm.boundary_names == {
        "a_origin": 1, "a_insertion": 2, "b_origin": 3, "b_insertion": 4, "proximal": 5, "distal": 6, "skin": 7,
    }
    assert tuple(arm.region_names) == ARM_SEGMENT_REGIONS and tuple(arm.boundary_names) == ARM_SEGMENT_FACES
    assert set(np.unique(arm.cell_tags).tolist()) == {1, 2, 3, 4, 5}  # every cell is named


def test_valid_and_conforming(arm) -> None:
    assert_valid(arm)  # includes: no degenerate tetrahedron
    assert np.all(signed_volumes(arm.points, arm.cells) != 0.0)
    assert_conforming(arm)  # every face shared by <= 2 tets; named faces = the whole boundary, once each
    faces = {name: key_set(tet_faces(arm.region_cells(name))) for name in ARM_SEGMENT_REGIONS}
    for muscle in ("a", "b"):
        belly, tendon = faces[f"belly_{muscle}"], faces[f"tendon_{muscle}"]
        assert len(belly & tendon) > 0, muscle  # the two tendon/belly disks
        assert len(faces["fat"] & belly) > 0 and len(faces["fat"] & tendon) > 0, muscle
    assert not faces["belly_a"] & faces["belly_b"] and not faces["tendon_a"] & faces["tendon_b"]


def test_volumes(arm) -> None:
    tendons = 2.0 * math.pi * RT**2 * LT  # the two tendons of one muscle
    d = RM - RT
    belly = math.pi * (L - 2.0 * LT) * (RT**2 + RT * d + 3.0 / 8.0 * d**2)  # pi int r(z)^2 dz
    assert belly_volume(L, RM, RT, LT) == pytest.approx(belly, rel=1e-14)
    fat = math.pi * R**2 * L - 2.0 * (belly + tendons)
    for muscle in ("a", "b"):
        assert -FACETING_16 < relative_error(arm.volume(f"tendon_{muscle}"), tendons) < 0.0
        assert abs(relative_error(arm.volume(f"belly_{muscle}"), belly)) < FACETING_16
    assert abs(relative_error(arm.volume("fat"), fat)) < 0.01
    assert arm.volume() == pytest.approx(sum(arm.volume(r) for r in ARM_SEGMENT_REGIONS), rel=1e-12)


def test_areas(arm) -> None:
    disk = math.pi * RT**2
    for name in ("a_origin", "a_insertion", "b_origin", "b_insertion"):
        assert -FACETING_16 - 1e-9 < relative_error(area(arm, name), disk) < 0.0, name
    for name in ("proximal", "distal"):
        assert abs(relative_error(area(arm, name), math.pi * R**2 - 2.0 * disk)) < 0.01, name
    assert abs(relative_error(area(arm, "skin"), 2.0 * math.pi * R * L)) < 0.01


def test_layout(arm) -> None:
    tol = 1e-9
    for muscle, x0 in (("a", -0.5 * SPACING), ("b", 0.5 * SPACING)):
        for end, z in (("origin", 0.0), ("insertion", L)):
            disk = face_points(arm, f"{muscle}_{end}")
            assert np.allclose(disk[:, 2], z, atol=tol)
            assert np.hypot(disk[:, 0] - x0, disk[:, 1]).max() < RT + tol
        for region, radius in ((f"tendon_{muscle}", RT), (f"belly_{muscle}", RM)):
            points = arm.points[np.unique(arm.region_cells(region))]
            # surface vertices lie on the geometry to 3e-8 (the B-spline loft's circle at the tendon/belly junction)
            assert np.hypot(points[:, 0] - x0, points[:, 1]).max() < radius + 1e-6, region
        tendon_z = arm.points[np.unique(arm.region_cells(f"tendon_{muscle}")), 2]
        assert np.all((tendon_z < LT + tol) | (tendon_z > L - LT - tol))
        belly_z = arm.points[np.unique(arm.region_cells(f"belly_{muscle}")), 2]
        assert belly_z.min() > LT - tol and belly_z.max() < L - LT + tol
    assert np.allclose(face_points(arm, "proximal")[:, 2], 0.0, atol=tol)
    assert np.allclose(face_points(arm, "distal")[:, 2], L, atol=tol)
    skin = face_points(arm, "skin")
    assert np.allclose(np.hypot(skin[:, 0], skin[:, 1]), R, atol=1e-6)


@pytest.mark.parametrize(("params", "message"), [
    ({"length": -1.0}, "arm_segment: length must be > 0, got -1.0"),
    ({"radius": 0.0}, "arm_segment: radius must be > 0, got 0.0"),
    ({"muscle_radius": float("nan")}, "arm_segment: muscle_radius must be > 0"),
    ({"tendon_radius": "thin"}, "arm_segment: tendon_radius must be a real number > 0"),
    ({"tendon_length": -0.01}, "arm_segment: tendon_length must be > 0"),
    ({"spacing": 0}, "arm_segment: spacing must be > 0"),
    ({"size": -1}, "arm_segment: size must be > 0, got -1"),
    ({"tendon_radius": 0.011}, "arm_segment: tendon_radius must be < muscle_radius (0.011), got 0.011"),
    ({"tendon_length": 0.06}, "arm_segment: tendon_length must be < length / 2 (0.06), got 0.06"),
    ({"spacing": 0.02}, "arm_segment: spacing must be > 2 * muscle_radius (0.022)"),
    ({"radius": 0.023}, "arm_segment: radius must be > spacing / 2 + muscle_radius"),
    ({"spacing": 0.04}, "arm_segment: radius must be > spacing / 2 + muscle_radius (0.031)"),
    ({"belly_radius": 0.01}, "arm_segment: unknown parameter 'belly_radius'"),
])
def test_errors(params: dict[str, object], message: str) -> None:
    with pytest.raises(ParameterError) as info:
        generate("arm_segment", **params)
    assert message in str(info.value)


# --- cylinder: vertices on the axis and at (radius, 0) ---------------------------------------------


@pytest.mark.parametrize(("radius", "length", "size"), [(0.5, 2.0, 0.25), (0.3, 2.0, 0.3), (0.04, 0.1, 0.007)])
def test_cylinder_axis_and_rim_vertices(radius: float, length: float, size: float) -> None:
    mesh = cylinder(radius=radius, length=length, size=size)
    layers = max(1, round(length / size))
    for z in np.linspace(0.0, length, layers + 1):  # on every extrusion layer
        for x in (0.0, radius):
            distance = np.linalg.norm(mesh.points - [x, 0.0, z], axis=1).min()
            assert distance <= 1e-12, (x, z)
    bottom, top = face_points(mesh, "bottom"), face_points(mesh, "top")
    for points, z in ((bottom, 0.0), (top, length)):
        for x in (0.0, radius):
            assert np.linalg.norm(points - [x, 0.0, z], axis=1).min() <= 1e-12, (x, z)
