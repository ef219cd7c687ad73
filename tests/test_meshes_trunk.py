"""The trunk generator (meshes.trunk): named groups, geometry, volume, conformity, parameter errors.

Rank-independent: every rank builds its own small mesh, so it also passes under mpirun -n 2.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_meshes import assert_conforming, assert_valid, face_points

from meshes import GENERATORS, ParameterError, generate
from meshes.topology import signed_volumes
from meshes.trunk import trunk, trunk_centre, trunk_radius, trunk_volume


@pytest.fixture(scope="module")
def mesh():
    return trunk(size=0.4)


def test_registered() -> None:
    assert GENERATORS["trunk"] is trunk


def test_groups_valid_and_conforming(mesh) -> None:
    assert_valid(mesh)
    assert_conforming(mesh)
    assert mesh.region_names == {"trunk": 1}
    assert mesh.boundary_names == {"base": 1, "top": 2, "bark": 3}
    assert np.all(mesh.cell_tags == 1)
    assert np.all(signed_volumes(mesh.points, mesh.cells) != 0)


def test_geometry(mesh) -> None:
    height, rb, rt, bend = 10.0, 0.5, 0.15, 0.6
    assert np.allclose(face_points(mesh, "base")[:, 2], 0.0, atol=1e-9)
    assert np.allclose(face_points(mesh, "top")[:, 2], height, atol=1e-9)
    assert mesh.points[:, 2].min() == pytest.approx(0.0, abs=1e-9)
    assert mesh.points[:, 2].max() == pytest.approx(height, abs=1e-9)
    # bark vertices lie on the lofted surface: distance to the centreline = radius(z) (loft tolerance)
    bark = face_points(mesh, "bark")
    distance = np.linalg.norm(bark[:, :2] - trunk_centre(bark[:, 2], height, bend), axis=1)
    assert np.allclose(distance, trunk_radius(bark[:, 2], height, rb, rt), rtol=0.02, atol=2e-3)
    # the top disk sits on the leaning centreline, the base disk on the axis
    assert np.allclose(face_points(mesh, "top")[:, :2].mean(axis=0), [bend, 0.0], atol=0.02)
    assert np.allclose(face_points(mesh, "base")[:, :2].mean(axis=0), [0.0, 0.0], atol=0.02)
    # faceting of the circles loses a few percent of the frustum's volume, never more than 7 %
    assert trunk_volume() == pytest.approx(np.pi * 10.0 * (0.25 + 0.075 + 0.0225) / 3.0)
    assert 0.93 * trunk_volume() < mesh.volume() < trunk_volume()


def test_size_and_parameters() -> None:
    coarse, fine = trunk(height=4.0, base_radius=0.4, top_radius=0.2, bend=0.0, size=0.4), \
        trunk(height=4.0, base_radius=0.4, top_radius=0.2, bend=0.0, size=0.1)
    assert fine.num_cells > 2 * coarse.num_cells
    for m in (coarse, fine):
        assert_valid(m)
        assert m.volume() == pytest.approx(trunk_volume(4.0, 0.4, 0.2), rel=0.07)
        assert np.allclose(face_points(m, "top")[:, :2].mean(axis=0), 0.0, atol=0.02)  # bend = 0: straight


def test_deterministic() -> None:
    a, b = trunk(size=0.6), trunk(size=0.6)
    for field in ("points", "cells", "facets", "facet_tags"):
        assert np.array_equal(getattr(a, field), getattr(b, field)), field


@pytest.mark.parametrize(("params", "message"), [
    ({"height": -1.0}, "trunk: height must be > 0"),
    ({"size": 0.0}, "trunk: size must be > 0"),
    ({"top_radius": "thin"}, "trunk: top_radius must be a real number > 0"),
    ({"bend": 20.0}, "trunk: bend must be a finite number with |bend| < height"),
    ({"base_radius": 6.0}, "trunk: base_radius and top_radius must be < height / 2"),
    ({"radius": 1.0}, "trunk: unknown parameter 'radius'"),
])
def test_errors(params: dict[str, object], message: str) -> None:
    with pytest.raises(ParameterError) as info:
        generate("trunk", **params)
    assert message in str(info.value)
