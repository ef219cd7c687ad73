"""Rotation-based user energies (issue 11, item 1): a user law file that takes the polar rotation R.

References: the built-in corotated / shape_target / neo_hookean (user laws written the same way must
agree to rounding), and for an energy R does not minimise, numpy's own polar rotation (SVD) and central
differences of the numpy energy.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from forms.law import ParameterError
from forms.registry import resolve_law
from model.verify import ReferenceEvaluator, deformation_samples

COROTATED = '''
import ufl
ROTATION = "F"
def psi(F, *, R, mu=1.0):
    return mu * ufl.inner(F - R, F - R)
'''

NEO_HOOKEAN = '''
import ufl
VOLUMETRIC = "ln J"
def psi(F, *, mu=1.0):
    return 0.5 * mu * (ufl.tr(F.T * F) - 3.0) - mu * ufl.ln(ufl.det(F))
'''

SHAPE = '''
import ufl
FIELDS = ("S",)
ROTATION = "F S"
def psi(F, *, R, mu=1.0, S=None):
    return mu * ufl.inner(F - R * S, F - R * S)
'''

B = np.array([[0.3, -0.2, 0.5], [0.1, 0.4, -0.3], [0.2, 0.0, 0.6]])
NOT_A_MINIMISER = f'''
import ufl
def psi(F, *, R, c=1.0):
    B = ufl.as_matrix({B.tolist()})
    return c * ufl.inner(R, B) + ufl.inner(F - R, F - R) + 0.5 * ufl.inner(R * F.T, B * F)
'''


def _write(folder: Path, name: str, text: str) -> str:
    path = folder / name
    path.write_text(text)
    return f"{path}:psi"


def _close(a: np.ndarray, b: np.ndarray, rtol: float) -> None:
    """Per-sample Frobenius error relative to the largest reference norm of the set."""
    a, b = a.reshape(len(a), -1), b.reshape(len(b), -1)
    scale = np.linalg.norm(b, axis=1).max()
    err = np.linalg.norm(a - b, axis=1).max()
    assert err <= rtol * scale, (err, scale)


def test_user_corotated_equals_builtin(tmp_path: Path) -> None:
    spec = _write(tmp_path, "corot.py", COROTATED)
    F, _ = deformation_samples(14, seed=5, inverted=True)
    user = ReferenceEvaluator(spec, {"mu": 1.7, "kappa": 0.9}, len(F)).evaluate(F)
    built = ReferenceEvaluator("corotated", {"mu": 1.7, "lmbda": 0.9}, len(F)).evaluate(F)
    for q in ("psi", "P", "A"):
        _close(user[q], built[q], 1e-12)
    assert resolve_law(spec).make(mu=1.0).needs_rotation


def test_user_neo_hookean_equals_builtin(tmp_path: Path) -> None:
    spec = _write(tmp_path, "nh.py", NEO_HOOKEAN)
    F, _ = deformation_samples(14, seed=6, inverted=False)
    user = ReferenceEvaluator(spec, {"mu": 2.5, "kappa": 4.0}, len(F)).evaluate(F)
    built = ReferenceEvaluator("neo_hookean", {"mu": 2.5, "lmbda": 4.0}, len(F)).evaluate(F)
    for q in ("psi", "P", "A"):
        _close(user[q], built[q], 1e-14)


def test_user_shape_target_rotation_of_F_S(tmp_path: Path) -> None:
    spec = _write(tmp_path, "shape.py", SHAPE)
    rng = np.random.default_rng(8)
    F, _ = deformation_samples(7, seed=8, inverted=False)
    Q = np.linalg.qr(rng.standard_normal((7, 3, 3)))[0]
    S = Q @ (rng.uniform(0.6, 1.5, (7, 3))[:, :, None] * np.eye(3)) @ np.transpose(Q, (0, 2, 1))
    user = ReferenceEvaluator(spec, {"mu": 1.3}, len(F)).evaluate(F, S=S)
    built = ReferenceEvaluator("shape_target", {"mu": 1.3, "kappa": 0.0}, len(F)).evaluate(F, S=S)
    for q in ("psi", "P", "A"):
        _close(user[q], built[q], 1e-12)
    law = resolve_law(spec).make(mu=1.3)
    flat = np.array([np.diag([1.0, 1.0, -1.0]) @ np.linalg.inv(S[0]), np.eye(3)])  # F S = diag(1, 1, -1); S
    np.testing.assert_array_equal(law.tangent_undefined(flat, S=S[:2]), [True, False])


def _numpy_energy(F: np.ndarray, c: float) -> float:
    U, _, Vt = np.linalg.svd(F)
    if np.linalg.det(U @ Vt) < 0:
        U[:, 2] *= -1.0
    R = U @ Vt
    return c * np.sum(R * B) + np.sum((F - R) ** 2) + 0.5 * np.sum((R @ F.T) * (B @ F))


def test_energy_that_R_does_not_minimise_has_the_exact_stress_and_tangent(tmp_path: Path) -> None:
    """P is the derivative of W(F, polar(F)) (no envelope theorem): numpy central differences of the
    numpy energy; A is the derivative of that P: central differences of the reference P."""
    spec = _write(tmp_path, "other.py", NOT_A_MINIMISER)
    rng = np.random.default_rng(9)
    F = np.eye(3) + 0.3 * rng.standard_normal((4, 3, 3))
    F[3] = F[3] @ np.diag([1.0, 1.0, -1.0])  # inverted, distinct singular values
    F[0] = np.eye(3)
    assert np.all(np.diff(np.linalg.svd(F[1:], compute_uv=False), axis=1) < -0.05)
    ev = ReferenceEvaluator(spec, {"c": 0.8}, len(F))
    out = ev.evaluate(F)
    h = 1e-5
    for n in range(len(F)):
        assert abs(out["psi"][n] - _numpy_energy(F[n], 0.8)) <= 1e-13 * max(1.0, abs(out["psi"][n]))
        P = np.zeros((3, 3))
        for i in range(3):
            for j in range(3):
                E = np.zeros((3, 3))
                E[i, j] = h
                P[i, j] = (_numpy_energy(F[n] + E, 0.8) - _numpy_energy(F[n] - E, 0.8)) / (2 * h)
        np.testing.assert_allclose(out["P"][n], P, atol=1e-8 * np.abs(P).max())
    # the rotation term matters here: leaving it out (dW/dF at fixed R) is far off
    big = ReferenceEvaluator(spec, {"c": 0.8}, 18)
    E = np.eye(9).reshape(9, 3, 3)
    for n in range(len(F)):
        hP = 1e-6
        P = big.evaluate(np.concatenate([F[n] + hP * E, F[n] - hP * E]))["P"]
        A = np.transpose((P[:9] - P[9:]) / (2 * hP), (1, 2, 0)).reshape(3, 3, 3, 3)
        np.testing.assert_allclose(out["A"][n], A, atol=1e-7 * np.abs(A).max())


def test_user_rotation_law_tangent_undefined(tmp_path: Path) -> None:
    law = resolve_law(_write(tmp_path, "corot2.py", COROTATED)).make(mu=1.0)
    F = np.array([np.diag([1.0, 1.0, -1.0]), np.diag([1.5, 0.8, -0.8]), np.diag([1.5, 0.8, -0.3]), np.eye(3)])
    np.testing.assert_array_equal(law.tangent_undefined(F), [True, True, False, False])
    plain = resolve_law(_write(tmp_path, "nh2.py", NEO_HOOKEAN)).make(mu=1.0)
    assert not plain.tangent_undefined(F).any()


@pytest.mark.parametrize("text, fragment", [
    ("import ufl\ndef psi(F, *, mu=1.0):\n    return mu * F\n",
     "must return a scalar UFL expression of F, got shape (3, 3)"),
    ("import ufl\ndef psi(F, *, mu=1.0):\n    return 'energy'\n",
     "must return a scalar UFL expression of F, got builtins.str"),
    ("import numpy as np\ndef psi(F, *, mu=1.0):\n    return np.ones(3)\n",
     "must return a scalar UFL expression of F, got numpy.ndarray"),
    ("import ufl\ndef psi(F, *, mu=1.0, a0=None):\n    return ufl.inner(F * a0, F * a0)\n",
     "argument 'a0' is a field: list it in FIELDS = ('a0',)"),
    ("import ufl\ndef psi(F, *, mu=1.0):\n    return ufl.inner(F * a0, F * a0)\n",
     "calling the function with a UFL F failed in psi() (bad.py line 3): NameError: name 'a0' is not defined"),
    ("import ufl\ndef psi(F, *, mu=1.0):\n    x = {}\n    return x['k'] * ufl.tr(F)\n",
     "calling the function with a UFL F failed in psi() (bad.py line 4): KeyError: 'k'"),
    ("import ufl\ndef psi(F, *, mu=1.0):\n    return ufl.tr(F) * (1 / 0)\n",
     "bad.py line 3): ZeroDivisionError"),
    ("import ufl\nROTATION = 'F'\ndef psi(F, *, mu=1.0):\n    return ufl.tr(F)\n",
     "ROTATION = 'F': the function must take the rotation, def psi(F, *, R, ...)"),
    ("import ufl\nROTATION = 'G'\ndef psi(F, *, R, mu=1.0):\n    return ufl.tr(F)\n",
     "ROTATION = 'G', must be one of 'F', 'F S'"),
    ("import ufl\nROTATION = 'F S'\ndef psi(F, *, R, mu=1.0):\n    return ufl.tr(F)\n",
     "ROTATION = 'F S' needs the shape target: FIELDS = ('S',)"),
    ("import ufl\ndef psi(F, *, R=1.0, mu=1.0):\n    return ufl.tr(R * F)\n",
     "the rotation R takes no default"),
])
def test_user_law_errors(tmp_path: Path, text: str, fragment: str) -> None:
    spec = _write(tmp_path, "bad.py", text)
    with pytest.raises(ParameterError) as info:
        resolve_law(spec)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(spec), message
    assert fragment in message, message


def test_energy_that_does_not_compile_is_one_line(tmp_path: Path) -> None:
    """A scalar UFL energy FFCx cannot translate to C (the modified Bessel function K has no C rule) was a
    traceback from deep inside FFCx; now verify (emit, check through ReferenceEvaluator) and verify element
    say in one line which law does not compile and why."""
    from model.verify.element import assemble_element

    spec = _write(tmp_path, "bessel.py", "import ufl\ndef psi(F, *, mu=1.0):\n"
                                          "    return mu * ufl.bessel_K(1, ufl.tr(F.T * F))\n")
    resolve_law(spec)  # the file itself is fine: a scalar UFL expression of F
    with pytest.raises(ParameterError) as info:
        ReferenceEvaluator(spec, {}, 2)
    message = str(info.value)
    assert message.startswith(f"{spec}: the energy does not compile (UFL/FFCx ") and "\n" not in message, message
    X = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    with pytest.raises(ValueError, match="the energy does not compile"):
        assemble_element(spec, {}, X, np.zeros((4, 3)))
