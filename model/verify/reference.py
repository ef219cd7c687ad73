"""The ``verify`` tool: UFL reference values of psi, P = dpsi/dF and A = dP/dF, and checks against them.

Contract: shared/design/verification.md.

    python -m model verify emit  --material NAME [--param KEY=VALUE ...] --samples N --seed SEED --out FILE.npz
    python -m model verify check FILE.npz [--rtol 1e-8]
    python -m model verify seeds [--json FILE]

Reference values come from the project's own laws (forms/) through dolfinx: each
sample is one cell of a mesh of N disjoint tetrahedra, F (and S) are per-cell
fields, and psi, P and A = diff(P, F) are dolfinx Expressions evaluated at the
cell's one quadrature point. Laws with a polar rotation use the same
quadrature-point machinery as the simulations (model.fields.polar.PolarField).

Errors in ``check`` are per sample, in the Frobenius norm of the quantity:
abs = ||user_n - ref_n||, rel = abs / max(||ref_n||, floor), floor = 1e-6 max_m ||ref_m|| (so that a
sample whose reference is zero up to rounding, e.g. P at a rotation, is judged against the scale of the set).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from scipy.spatial.transform import Rotation

import forms
from forms.law import Law
from forms.metadata import FIELD_SHAPES
from model import compat
from model.fields.polar import PolarField

QUANTITIES = ("psi", "P", "A")


def _law_fields(material: str) -> tuple[str, ...]:
    """The fields a law takes: a built-in's name, or "FILE.py:FUNCTION" for a law of the user's own."""
    return forms.resolve_law(material).fields


class ReferenceEvaluator:
    """psi, P, A of a law at many F (and per-sample fields), through UFL and dolfinx."""

    def __init__(self, material: str, params: dict[str, float], num_samples: int) -> None:
        entry = forms.resolve_law(material)  # ParameterError naming the law when unknown
        self.material = material
        self.num_samples = num_samples
        n = num_samples
        reference_tet = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
        x = np.tile(reference_tet, (n, 1))
        cells = np.arange(4 * n, dtype=np.int64).reshape(n, 4)
        self.mesh = compat.create_mesh(MPI.COMM_SELF, cells, x)
        # dolfinx may renumber cells: the sample of local cell c is original_cell_index[c]
        self.order = np.asarray(self.mesh.topology.original_cell_index, dtype=np.int64)
        space = compat.function_space(self.mesh, "DG", 0, (3, 3))
        self.F = fem.Function(space, name="F")
        self.fields: dict[str, fem.Function] = {}
        for name in _law_fields(material):  # a DG0 Function per field, of its shape in FIELD_SHAPES
            shape = FIELD_SHAPES[name]
            field_space = compat.function_space(self.mesh, "DG", 0, shape) if shape else \
                compat.function_space(self.mesh, "DG", 0)
            self.fields[name] = fem.Function(field_space, name=name)
        extra: dict[str, Any] = dict(self.fields)
        self.law: Law = entry.make(**extra, **params)
        Fv = ufl.variable(self.F)
        R = None
        self.polar = None
        if self.law.needs_rotation:
            self.polar = PolarField(self.mesh, self.law.rotation_argument(Fv), 1)
            R = self.polar.rotation
        psi = self.law.energy(Fv, R)
        P = self.law.stress(Fv, R)
        A = ufl.diff(P, Fv)
        points = compat.quadrature_points(self.mesh, 1)
        self.expressions = {"psi": fem.Expression(psi, points), "P": fem.Expression(P, points),
                            "A": fem.Expression(A, points)}
        self.cells = np.arange(n, dtype=np.int32)

    def _set(self, function: fem.Function, values: np.ndarray) -> None:
        size = function.function_space.dofmap.index_map_bs
        values = np.asarray(values, dtype=np.float64).reshape(self.num_samples, size)
        function.x.array[:] = values[self.order].reshape(-1)

    def evaluate(self, F: np.ndarray, **fields: np.ndarray) -> dict[str, np.ndarray]:
        """{'psi': (N,), 'P': (N,3,3), 'A': (N,3,3,3,3)} at the given F (N,3,3) and fields."""
        self._set(self.F, F)
        for name, function in self.fields.items():
            if name not in fields:
                raise ValueError(f"{self.material} needs the field {name}")
            self._set(function, fields[name])
        if self.polar is not None:
            self.polar.update()
        inverse = np.empty_like(self.order)
        inverse[self.order] = np.arange(self.num_samples)
        out = {}
        for name, shape in (("psi", ()), ("P", (3, 3)), ("A", (3, 3, 3, 3))):
            values = compat.evaluate(self.expressions[name], self.mesh, self.cells)
            out[name] = values.reshape(self.num_samples, *shape)[inverse]
        return out

    def parameters(self) -> dict[str, float]:
        return self.law.parameters()


def reference(material: str, params: dict[str, float], F: np.ndarray, **fields: np.ndarray) -> dict[str, np.ndarray]:
    """psi, P, A of ``material`` at F (N,3,3) with its fields (e.g. S), through the UFL forms."""
    F = np.asarray(F, dtype=np.float64).reshape(-1, 3, 3)
    return ReferenceEvaluator(material, params, len(F)).evaluate(F, **fields)


# --- samples ----------------------------------------------------------------------------------------

def _rotations(rng: np.random.Generator, n: int) -> np.ndarray:
    return Rotation.random(n, random_state=rng.integers(2**31)).as_matrix() if n else np.zeros((0, 3, 3))


def _from_singular_values(rng: np.random.Generator, sigma: np.ndarray) -> np.ndarray:
    return _rotations(rng, len(sigma)) @ (sigma[:, :, None] * np.eye(3)) @ _rotations(rng, len(sigma))


def deformation_samples(n: int, seed: int, inverted: bool = False,
                        targets: np.ndarray | None = None) -> tuple[np.ndarray, list[str]]:
    """n deformation gradients covering the hard cases, and a label for each.

    identity; pure rotations; repeated singular values (uniaxial: (a, b, b); isotropic: (a, a, a));
    large stretches (singular values in [0.3, 3]); nearly flat elements (smallest singular value
    1e-4 to 1e-2); random F near I. With ``inverted``, a quarter of them get det F < 0 (F times a
    reflection), chosen among samples where the two smallest singular values of the matrix whose
    rotation the law uses (F D, or F D S with the shape targets ``targets``) differ by more than 5%:
    for det < 0 the rotation variant of the polar decomposition has no derivative where they
    coincide (K = tr(Sigma) I - Sigma is singular, the nearest rotation is not unique).
    """
    if n < 1:
        raise ValueError("--samples must be >= 1")
    rng = np.random.default_rng(seed)
    kinds = ["identity", "rotation", "uniaxial", "isotropic", "large_stretch", "nearly_flat", "random"]
    labels = [kinds[i % len(kinds)] for i in range(n)]
    F = np.empty((n, 3, 3))
    for i, kind in enumerate(labels):
        if kind == "identity":
            F[i] = np.eye(3)
        elif kind == "rotation":
            F[i] = _rotations(rng, 1)[0]
        elif kind == "uniaxial":
            a, b = rng.uniform(0.5, 2.0, 2)
            F[i] = _from_singular_values(rng, np.array([[a, b, b]]))[0]
        elif kind == "isotropic":
            F[i] = rng.uniform(0.6, 1.6) * _rotations(rng, 1)[0]
        elif kind == "large_stretch":
            F[i] = _from_singular_values(rng, rng.uniform(0.3, 3.0, (1, 3)))[0]
        elif kind == "nearly_flat":
            sigma = np.array([[rng.uniform(0.8, 1.5), rng.uniform(0.8, 1.5), 10 ** rng.uniform(-4, -2)]])
            F[i] = _from_singular_values(rng, sigma)[0]
        else:
            G = np.eye(3) + 0.3 * rng.standard_normal((3, 3))
            F[i] = G if np.linalg.det(G) > 0 else G @ np.diag([1.0, 1.0, -1.0])
    if inverted:
        reflection = np.diag([1.0, 1.0, -1.0])
        M = F @ reflection if targets is None else F @ reflection @ targets
        sigma = np.linalg.svd(M, compute_uv=False)
        distinct = np.flatnonzero(sigma[:, 1] - sigma[:, 2] > 0.05 * sigma[:, 1])
        if len(distinct) == 0:
            raise ValueError("--inverted needs more samples (none with distinct singular values)")
        flip = rng.permutation(distinct)[: max(1, n // 4)]
        F[flip] = F[flip] @ reflection
        for i in flip:
            labels[i] = f"inverted_{labels[i]}"
    return F, labels


def field_samples(material: str, n: int, seed: int) -> dict[str, np.ndarray]:
    """Per-sample fields of a law: S symmetric positive definite (identity, repeated and distinct
    eigenvalues); a0 unit fibre directions (axis-aligned and random); alpha in [0, 1] (0, 1 and between)."""
    rng = np.random.default_rng(seed + 7919)
    out = {}
    if "a0" in _law_fields(material):
        a0 = rng.standard_normal((n, 3))
        a0[0::4] = [1.0, 0.0, 0.0]
        out["a0"] = a0 / np.linalg.norm(a0, axis=1)[:, None]
    if "s0" in _law_fields(material):  # unit sheet directions orthogonal to a0 (axis-aligned where a0 is)
        s0 = rng.standard_normal((n, 3))
        s0[0::4] = [0.0, 1.0, 0.0]
        a0 = out.get("a0", np.tile([1.0, 0.0, 0.0], (n, 1)))
        s0 -= np.einsum("ni,ni->n", s0, a0)[:, None] * a0
        out["s0"] = s0 / np.linalg.norm(s0, axis=1)[:, None]
    if "alpha" in _law_fields(material):
        alpha = rng.uniform(0.0, 1.0, n)
        alpha[0::3], alpha[1::3] = 0.0, 1.0
        out["alpha"] = alpha
    if "S" in _law_fields(material):
        eig = rng.uniform(0.5, 2.0, (n, 3))
        eig[0::3] = 1.0  # identity targets
        eig[1::3, 1] = eig[1::3, 2]  # repeated eigenvalues
        Q = _rotations(rng, n)
        out["S"] = Q @ (eig[:, :, None] * np.eye(3)) @ np.transpose(Q, (0, 2, 1))
    return out


# --- emit / check -----------------------------------------------------------------------------------

def emit(material: str, params: dict[str, float], samples: int, seed: int, out: Path,
         inverted: bool = False) -> dict[str, np.ndarray]:
    """Write FILE.npz with F, psi, P, A, the law's fields, material and params_json (defaults included)."""
    fields = field_samples(material, samples, seed)
    F, labels = deformation_samples(samples, seed, inverted, fields.get("S"))
    evaluator = ReferenceEvaluator(material, params, samples)
    values = evaluator.evaluate(F, **fields)
    data = {"F": F, **values, **fields, "labels": np.array(labels), "material": np.array(material),
            "params_json": np.array(json.dumps(evaluator.parameters(), sort_keys=True))}
    np.savez(out, **data)
    return data


@dataclass(frozen=True)
class CheckRow:
    quantity: str
    max_abs_error: float
    max_rel_error: float
    worst_sample: int
    ok: bool


def compare(user: dict[str, np.ndarray], ref: dict[str, np.ndarray], rtol: float) -> list[CheckRow]:
    """Per-sample Frobenius errors of every quantity the user gave (see module docstring)."""
    rows = []
    for q in QUANTITIES:
        if q not in user:
            continue
        u = np.asarray(user[q], dtype=np.float64).reshape(len(ref[q]), -1)
        r = ref[q].reshape(len(ref[q]), -1)
        if u.shape != r.shape:
            raise ValueError(f"{q}: shape {np.shape(user[q])} does not match the reference {ref[q].shape}")
        err = np.linalg.norm(u - r, axis=1)
        norm = np.linalg.norm(r, axis=1)
        floor = 1e-6 * max(float(norm.max(initial=0.0)), 1e-300)
        rel = err / np.maximum(norm, floor)
        rel[~np.isfinite(rel)] = np.inf
        worst = int(np.argmax(rel)) if len(rel) else -1
        rows.append(CheckRow(q, float(err.max(initial=0.0)), float(rel.max(initial=0.0)), worst,
                             bool(np.all(rel <= rtol))))
    return rows


Arrays = dict[str, np.ndarray]


def load_for_check(path: Path) -> tuple[str, dict[str, float], np.ndarray, Arrays, Arrays]:
    """(material, params, F, fields, user quantities) from a file in the emit layout."""
    with np.load(path, allow_pickle=False) as data:
        content = {k: data[k] for k in data.files}
    for key in ("F", "material", "params_json"):
        if key not in content:
            raise ValueError(f"{path}: missing array {key!r} (the layout is that of verify emit)")
    material = str(content["material"])
    params = json.loads(str(content["params_json"]))
    F = np.asarray(content["F"], dtype=np.float64).reshape(-1, 3, 3)
    fields = {k: content[k] for k in _law_fields(material) if k in content}
    missing = [k for k in _law_fields(material) if k not in fields]
    if missing:
        raise ValueError(f"{path}: {material} needs the field {missing[0]!r}")
    user = {q: content[q] for q in QUANTITIES if q in content}
    if not user:
        raise ValueError(f"{path}: none of psi, P, A to check")
    return material, params, F, fields, user


def check(path: Path, rtol: float = 1e-8) -> list[CheckRow]:
    """Recompute the reference for the file's F and fields and compare what it holds."""
    material, params, F, fields, user = load_for_check(path)
    ref = ReferenceEvaluator(material, params, len(F)).evaluate(F, **fields)
    return compare(user, ref, rtol)


def format_rows(rows: list[CheckRow]) -> str:
    lines = [f"{'quantity':8} {'max abs error':>14} {'max rel error':>14} {'worst sample':>12}  result"]
    for r in rows:
        lines.append(f"{r.quantity:8} {r.max_abs_error:14.3e} {r.max_rel_error:14.3e} {r.worst_sample:12d}  "
                     f"{'ok' if r.ok else 'FAIL'}")
    return "\n".join(lines)
