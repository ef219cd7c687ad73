"""The batched polar rotation: agrees with scipy's polar decomposition, and is a rotation for inverted F."""

from __future__ import annotations

import numpy as np
from scipy.linalg import polar
from scipy.spatial.transform import Rotation

from forms.polar import polar_rotation


def test_matches_scipy_polar_for_positive_determinant() -> None:
    rng = np.random.default_rng(1)
    F = np.eye(3) + 0.4 * rng.standard_normal((200, 3, 3))
    F = F[np.linalg.det(F) > 0.05]
    R = polar_rotation(F)
    for Fi, Ri in zip(F, R):
        expected, _ = polar(Fi)
        np.testing.assert_allclose(Ri, expected, atol=1e-12)


def test_identity_rotations_and_repeated_singular_values() -> None:
    Q = Rotation.from_rotvec([[0.3, -1.2, 0.7], [0.0, 0.0, np.pi - 1e-3], [0, 0, 0]]).as_matrix()
    stretch = np.diag([1.3, 1.3, 0.7])  # repeated singular values
    np.testing.assert_allclose(polar_rotation(Q), Q, atol=1e-13)
    np.testing.assert_allclose(polar_rotation(Q @ stretch), Q, atol=1e-13)
    np.testing.assert_allclose(polar_rotation(2.0 * Q), Q, atol=1e-13)  # isotropic stretch


def test_inverted_gets_rotation_not_reflection() -> None:
    rng = np.random.default_rng(2)
    F = np.eye(3) + 0.5 * rng.standard_normal((300, 3, 3))
    F[:, :, 0] *= np.sign(np.linalg.det(F))[:, None] * -1.0  # make every det negative
    assert np.all(np.linalg.det(F) < 0)
    R = polar_rotation(F)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    np.testing.assert_allclose(R @ np.transpose(R, (0, 2, 1)), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    # R* minimises ||F - R|| over SO(3): no random rotation does better
    best = np.linalg.norm(F - R, axis=(1, 2))
    trial = Rotation.random(2000, random_state=3).as_matrix()
    for Fi, bi in zip(F[:20], best[:20]):
        assert bi <= np.linalg.norm(Fi - trial, axis=(1, 2)).min() + 1e-12


def test_compiled_kernel_equals_svd_definition() -> None:
    from forms import _polar_kernel
    from forms.polar import polar_rotation_svd

    assert _polar_kernel.load() is not None, "the C kernel did not build"
    rng = np.random.default_rng(4)
    F = np.eye(3) + 0.4 * rng.standard_normal((5000, 3, 3))
    F[:500] = rng.standard_normal((500, 3, 3))  # about half with det < 0: SVD path
    U, s, Vt = np.linalg.svd(F[500:1000])
    s[:, 2] = 10.0 ** rng.uniform(-6, -2, 500)  # nearly flat
    F[500:1000] = U @ (s[:, :, None] * np.eye(3)) @ Vt
    F[1000:1010] = np.eye(3)
    F[1010:1020] = 1e-8 * np.eye(3)  # tiny scale
    np.testing.assert_allclose(polar_rotation(F), polar_rotation_svd(F), atol=1e-12)
