"""The machinery of the ``verify seeds`` table: rows, checks against the reference, numerics shared by the seeds.

A row (``SeedRow``) is one formula as printed (or its ``-corrected`` variant): its id, where it is printed,
whether it agrees with the reference at rtol ``RTOL`` (``model.verify.compare``: per-sample Frobenius
norms), the worst relative error and a one-line diagnosis.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np

from model.verify import CheckRow, compare

SEED = 2020
SAMPLES = 210  # 30 of each of the 7 kinds of deformation_samples
ELEMENT_SAMPLES = 14  # 2 of each kind, per law, on the one-cell mesh
RTOL = 1e-8

KLAR = "shape-targeting-klar-2020.txt"
THESIS = "turchet-thesis-musculoskeletal.txt"

I3 = np.eye(3)


@dataclass(frozen=True)
class SeedRow:
    id: str
    source: str
    agrees: bool
    max_rel_error: float
    diagnosis: str


def _row(id_: str, source: str, checks: list[CheckRow], diagnosis: str) -> SeedRow:
    worst = max(c.max_rel_error for c in checks)
    return SeedRow(id_, source, all(c.ok for c in checks), worst, diagnosis)


def _T(A: np.ndarray) -> np.ndarray:
    return np.swapaxes(A, -1, -2)


def _fro(A: np.ndarray) -> np.ndarray:
    return np.sqrt(np.einsum("nij,nij->n", A, A))



Quantities = dict[str, np.ndarray]


def _check(user: Quantities, ref: Quantities) -> list[CheckRow]:
    return compare(user, ref, RTOL)


def _central_differences(f: Callable[[np.ndarray], np.ndarray], F: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """d f / d F_kl by central differences, f (n, ...) -> (n, ..., 3, 3)."""
    out = []
    for k in range(3):
        for l in range(3):
            dF = np.zeros_like(F)
            dF[:, k, l] = h
            out.append((f(F + dF) - f(F - dF)) / (2.0 * h))
    stacked = np.stack(out, axis=-1)
    return stacked.reshape(*stacked.shape[:-1], 3, 3)



def format_table(rows: list[SeedRow]) -> str:
    width_id = max(len(r.id) for r in rows)
    width_src = max(len(r.source) for r in rows)
    lines = [f"{'id':{width_id}}  {'where printed':{width_src}}  {'result':10}  {'max rel err':>11}  diagnosis"]
    for r in rows:
        lines.append(f"{r.id:{width_id}}  {r.source:{width_src}}  {'agrees' if r.agrees else 'DISAGREES':10}  "
                     f"{r.max_rel_error:11.2e}  {r.diagnosis}")
    return "\n".join(lines)


def to_json(rows: list[SeedRow]) -> list[dict[str, object]]:
    out = []
    for r in rows:
        d = asdict(r)
        d["agrees"] = bool(r.agrees)
        d["max_rel_error"] = float(r.max_rel_error) if np.isfinite(r.max_rel_error) else None
        out.append(d)
    return out
