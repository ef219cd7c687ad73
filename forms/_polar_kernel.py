"""A compiled batched polar rotation (scaled Newton iteration), built once with cffi and the C compiler.

For det M > 0 the orthogonal polar factor of M is the limit of Higham's iteration
X <- (g X + X^-T / g) / 2, g = |det X|^(-1/3), started at X = M / max|M_ij|; it is a
rotation, equal to U V^T of the SVD. The kernel stops when successive iterates differ by less
than 1e-9 (the convergence is quadratic, so the new iterate's error is about 1e-18), takes one
unscaled step to polish, and flags matrices it does not handle
(det M <= 1e-12 max|M|^3, or no convergence in 60 steps) for the SVD path.
The shared library is cached under ~/.cache/softtissue-reference, keyed by a hash of
its source; concurrent builds (MPI ranks) are safe (atomic rename).
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import sys
import tempfile
from pathlib import Path
from types import ModuleType

C_SOURCE = r"""
#include <math.h>

static double inv_transpose(const double *X, double *Y)
{
    /* Y = cof(X) / det(X) = X^{-T}; rows of cof are r1 x r2, r2 x r0, r0 x r1 */
    const double *r0 = X, *r1 = X + 3, *r2 = X + 6;
    double c[9];
    c[0] = r1[1] * r2[2] - r1[2] * r2[1]; c[1] = r1[2] * r2[0] - r1[0] * r2[2]; c[2] = r1[0] * r2[1] - r1[1] * r2[0];
    c[3] = r2[1] * r0[2] - r2[2] * r0[1]; c[4] = r2[2] * r0[0] - r2[0] * r0[2]; c[5] = r2[0] * r0[1] - r2[1] * r0[0];
    c[6] = r0[1] * r1[2] - r0[2] * r1[1]; c[7] = r0[2] * r1[0] - r0[0] * r1[2]; c[8] = r0[0] * r1[1] - r0[1] * r1[0];
    double det = r0[0] * c[0] + r0[1] * c[1] + r0[2] * c[2], inv = 1.0 / det;
    for (int i = 0; i < 9; ++i) Y[i] = c[i] * inv;
    return det;
}

int polar_batch(long n, const double *M, double *R, signed char *flag)
{
    int failures = 0;
    for (long m = 0; m < n; ++m) {
        const double *A = M + 9 * m;
        double *X = R + 9 * m, Y[9], scale = 0.0;
        for (int i = 0; i < 9; ++i) scale = fmax(scale, fabs(A[i]));
        flag[m] = 1;
        if (!(scale > 0.0)) { failures++; continue; }
        for (int i = 0; i < 9; ++i) X[i] = A[i] / scale;
        double det = inv_transpose(X, Y);
        if (!(det > 1e-12)) { failures++; continue; }
        int converged = 0;
        for (int it = 0; it < 60 && !converged; ++it) {
            double g = 1.0 / cbrt(fabs(det)), delta = 0.0;
            for (int i = 0; i < 9; ++i) {
                double x = 0.5 * (g * X[i] + Y[i] / g);
                delta = fmax(delta, fabs(x - X[i]));
                X[i] = x;
            }
            converged = delta < 1e-9;  /* quadratic: this iterate's error is about delta^2 */
            det = inv_transpose(X, Y);
        }
        if (!converged) { failures++; continue; }
        for (int i = 0; i < 9; ++i) X[i] = 0.5 * (X[i] + Y[i]);
        flag[m] = 0;
    }
    return failures;
}
"""

C_DECLARATIONS = "int polar_batch(long n, const double *M, double *R, signed char *flag);"


def _cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME", str(Path.home() / ".cache"))
    return Path(base) / "softtissue-reference"


def load() -> ModuleType | None:
    """The compiled module (lib, ffi), building it if needed; None if no compiler is available."""
    digest = hashlib.sha1((C_SOURCE + C_DECLARATIONS + sys.version).encode()).hexdigest()[:16]
    name = f"_polar_{digest}"
    cache = _cache_dir()
    existing = sorted(cache.glob(f"{name}*.so")) if cache.is_dir() else []
    if not existing:
        try:
            import cffi

            cache.mkdir(parents=True, exist_ok=True)
            ffi = cffi.FFI()
            ffi.cdef(C_DECLARATIONS)
            ffi.set_source(name, C_SOURCE, extra_compile_args=["-O2"])
            with tempfile.TemporaryDirectory(dir=cache) as tmp:
                built = Path(ffi.compile(tmpdir=tmp, verbose=False))
                target = cache / built.name
                os.replace(built, target)
            existing = [target]
        except Exception:  # noqa: BLE001 - no compiler or cffi: the caller falls back to the SVD
            return None
    spec = importlib.util.spec_from_file_location(name, existing[0])
    if spec is None or spec.loader is None:
        return None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
