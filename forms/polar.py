"""Polar rotation R* of M = F S with an exact first derivative, at quadrature points.

A closed-form polar decomposition through eigenvalues has NaN derivatives at
repeated singular values (the rest state included). Instead R0 = polar(M) is
computed per quadrature point by a batched SVD (``polar_rotation``) before each
assembly and stored in a quadrature-element function; the UFL expression

    R = R0 (I + [w]x),   w = 2 K^-1 axial(skew(R0^T M)),
    K = tr(H) I - H,     H = sym(R0^T M)

has the value R0 (at R0 = polar(M), R0^T M is symmetric, so w = 0) and the
exact first derivative: with M = R U, dM = dR U + R dU and dR = R [dw]x one has
skew(R^T dM) = ([dw]x U + U [dw]x)/2 = [K dw / 2]x, so dw = 2 K^-1 axial(skew(R^T dM)).

Rotation variant: for det M < 0 (inverted elements) R* = U diag(1, 1, -1) V^T
from M = U Sigma V^T with ascending-order last (smallest) singular value negated,
so R* is always a proper rotation (det R* = +1), never a reflection.
"""

from __future__ import annotations

import numpy as np
import ufl

_kernel = None


def polar_rotation(M: np.ndarray) -> np.ndarray:
    """Rotation R* = argmin_{R in SO(3)} ||M - R||_F of a batch M of shape (..., 3, 3).

    R* = U diag(1, 1, sign det(U V^T)) V^T from the SVD M = U Sigma V^T (singular
    values in descending order, so the flipped one is the smallest). Matrices with
    det M > 0 go through a compiled scaled Newton iteration (forms._polar_kernel; the
    same R to rounding, ~10x faster than LAPACK's batched SVD); the others, and all of
    them when no C compiler is available, through ``polar_rotation_svd``.
    """
    global _kernel
    if _kernel is None:
        from forms import _polar_kernel

        _kernel = _polar_kernel.load() or False
    if not _kernel:
        return polar_rotation_svd(M)
    M = np.ascontiguousarray(M, dtype=np.float64)
    flat = M.reshape(-1, 3, 3)
    R = np.empty_like(flat)
    flag = np.empty(len(flat), dtype=np.int8)
    ffi, lib = _kernel.ffi, _kernel.lib
    failures = lib.polar_batch(len(flat), ffi.from_buffer("double[]", flat), ffi.from_buffer("double[]", R),
                               ffi.from_buffer("signed char[]", flag))
    if failures:
        bad = flag.astype(bool)
        R[bad] = polar_rotation_svd(flat[bad])
    return R.reshape(M.shape)


def polar_rotation_svd(M: np.ndarray) -> np.ndarray:
    """polar_rotation through numpy's batched SVD (the definition; any det M)."""
    U, _, Vt = np.linalg.svd(M)
    sign = np.sign(np.linalg.det(U @ Vt))
    sign[sign == 0] = 1.0
    U[..., :, 2] *= sign[..., None]
    return U @ Vt


def rotation_not_unique(M: np.ndarray, rtol: float = 1e-8) -> np.ndarray:
    """(N,) bool: True where the nearest rotation of M (N,3,3) is not unique, so R*(M), P and A jump.

    That is where det M < 0 and the two smallest singular values are equal within rtol
    (s2 - s3 <= rtol s2; M = diag(1, 1, -1) is one), and where M has rank <= 1 (s2 <= rtol s1; any
    sign of det M). At det M = 0 with s2 > 0 the rotation is unique and smooth (the signed smallest
    singular value det M / (s1 s2) is smooth there): not flagged. A zero M is flagged.
    """
    M = np.asarray(M, dtype=np.float64).reshape(-1, 3, 3)
    s = np.linalg.svd(M, compute_uv=False)
    det = np.linalg.det(M)
    scale = np.maximum(s[:, 0], 1e-300)
    equal = (s[:, 1] - s[:, 2]) <= rtol * s[:, 1]
    inverted = det < -1e-14 * scale**3
    rank_one = s[:, 1] <= rtol * scale
    return (inverted & equal) | rank_one | (s[:, 0] == 0)


def skew_matrix(w: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """[w]x, the matrix with [w]x v = w x v."""
    return ufl.as_matrix([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


def axial(W: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """axial(W) = (W21, W02, W10), the inverse of skew_matrix on skew-symmetric W."""
    return ufl.as_vector([W[2, 1], W[0, 2], W[1, 0]])


#: K counts as singular (w = 0, R = R0) where det K <= SINGULAR_K tr(K) I2(K): see linearised_rotation
SINGULAR_K = 1e-8


def linearised_rotation(M: ufl.core.expr.Expr, R0: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """R = R0 (I + [w]x), w = 2 K^-1 axial(skew(R0^T M)), K = tr(H) I - H, H = sym(R0^T M).

    Equal to R0 = polar(M) and with the exact derivative dR*/dM when R0 is current.

    Where K is singular the rotation has no derivative and w would be 0/0 (rounding in skew(R0^T M)
    divided by det K ~ 0: psi was off by O(1), NaN at the inverted identity). At a current R0,
    K = V diag(s2 + s3, s1 + s3, s1 + s2) V^T with the signed singular values s1 >= s2 >= |s3| of M
    (s3 < 0 when det M < 0), so K is positive semidefinite and singular exactly when det M < 0 and
    s2 = -s3 (the two smallest singular values equal; both zero at rank one). Its smallest eigenvalue
    lies between det K / I2(K) and 3 det K / I2(K) (I2 the second invariant), so the test

        det K > SINGULAR_K tr(K) I2(K)   (the smallest eigenvalue of K above ~1e-8 of the largest)
        and I2(K) > SINGULAR_K tr(K)^2   (the middle one too: with two eigenvalues ~ 0, at M = s times an
                                          inverted rotation, I2 is rounding of either sign)

    keeps the exact linearisation, and otherwise w = 0: R = R0 exactly (the minimiser over SO(3) that the
    SVD picked; any choice among equal singular values gives the same ||M - R||), and dR = 0 there
    (no derivative exists). Rounding then perturbs w by at most ~1e-16 / 1e-8 relative, which changes
    ||M - R||^2 only at second order (R0^T M symmetric: the first-order term vanishes).
    """
    A = R0.T * M
    w = 2.0 * _solve_K(A, axial(ufl.skew(A)))
    return R0 * (ufl.Identity(3) + skew_matrix(w))


def _solve_K(A: ufl.core.expr.Expr, b: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """K^-1 b with K = tr(H) I - H, H = sym(A), or 0 where K is singular (linearised_rotation's test)."""
    H = ufl.sym(A)
    K = ufl.tr(H) * ufl.Identity(3) - H
    trK = ufl.tr(K)
    I2 = 0.5 * (trK**2 - ufl.inner(K, K))
    detK = ufl.det(K)
    # two eigenvalues of K ~ 0 (M = an inverted rotation times s, signed singular values (s, s, -s)) leave I2
    # at rounding level, of either sign: I2 < 0 turned the first test into det K > (a negative number) and w
    # into rounding / 1e-33 (psi 125 instead of 4 at an inverted rotation). The second test catches that.
    regular = ufl.And(ufl.gt(detK, SINGULAR_K * trK * I2), ufl.gt(I2, SINGULAR_K * trK**2))
    return ufl.conditional(regular, 1.0 / ufl.conditional(regular, detK, 1.0), 0.0) * (_adjugate(K) * b)


def rotation_stress(M: ufl.core.expr.Expr, R: ufl.core.expr.Expr, G: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """d(G : R*(M))/dM at fixed G: the part of dpsi/dM that comes through the rotation R* = polar(M).

    With dR = R [dw]x, dw = 2 K^-1 axial(skew(R^T dM)) (module docstring) and the identity
    A : [v]x = 2 axial(skew A) . v,

        G : dR = g . dw = 2 (K^-1 g) . axial(skew(R^T dM)) = (R [a]x) : dM,
        g = 2 axial(skew(R^T G)),  a = K^-1 g,   so  d(G : R)/dM = R [a]x.

    ``R`` is the linearised rotation (value polar(M), exact first derivative), so UFL's derivative
    of this expression is exact too (it is an explicit function of M and R). Where K is singular
    (the rotation is not unique: no derivative exists) a = 0, as in linearised_rotation.
    """
    a = _solve_K(R.T * M, 2.0 * axial(ufl.skew(R.T * G)))
    return R * skew_matrix(a)


def _adjugate(K: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """adj(K) = det(K) K^-1 of a symmetric 3x3 K, as cofactors (no division)."""
    return ufl.as_matrix([[K[1, 1] * K[2, 2] - K[1, 2] * K[2, 1], K[0, 2] * K[2, 1] - K[0, 1] * K[2, 2],
                           K[0, 1] * K[1, 2] - K[0, 2] * K[1, 1]],
                          [K[1, 2] * K[2, 0] - K[1, 0] * K[2, 2], K[0, 0] * K[2, 2] - K[0, 2] * K[2, 0],
                           K[0, 2] * K[1, 0] - K[0, 0] * K[1, 2]],
                          [K[1, 0] * K[2, 1] - K[1, 1] * K[2, 0], K[0, 1] * K[2, 0] - K[0, 0] * K[2, 1],
                           K[0, 0] * K[1, 1] - K[0, 1] * K[1, 0]]])
