"""What a check found: per quantity the errors and the worst samples, per sample kind the errors, the
samples left out and why, and hints; ``str(report)`` is the table ``verify check`` prints.

Errors are per sample, in the Frobenius norm of the quantity: abs = ||user_n - ref_n||,
rel = abs / max(||ref_n||, M), M the law's modulus (the largest |A_ijkl| at F = I); a sample agrees
when abs <= rtol max(||ref_n||, M) + atol (model.verify.checker.compare).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class CheckRow:
    """One quantity's result: the largest errors over the compared samples, the worst one's index
    (-1 when none was compared), ok when every relative error is <= rtol; ``worst_samples`` the indices
    of the (up to three) worst samples out of tolerance, ``compared`` and ``excluded`` ((reason, count), ...)
    the samples used and left out, ``per_kind`` ((label, max rel error), ...) by sample label."""

    quantity: str
    max_abs_error: float
    max_rel_error: float
    worst_sample: int
    ok: bool
    worst_samples: tuple[int, ...] = ()
    compared: int = 0
    excluded: tuple[tuple[str, int], ...] = ()
    per_kind: tuple[tuple[str, float], ...] = ()


def format_rows(rows: list[CheckRow]) -> str:
    """The table: quantity, max abs error, max rel error, worst sample, result."""
    lines = [f"{'quantity':8} {'max abs error':>14} {'max rel error':>14} {'worst sample':>12}  result"]
    for r in rows:
        lines.append(f"{r.quantity:8} {r.max_abs_error:14.3e} {r.max_rel_error:14.3e} {r.worst_sample:12d}  "
                     f"{'ok' if r.ok else 'FAIL'}")
    return "\n".join(lines)


def signed_singular_values(F: np.ndarray) -> np.ndarray:
    """Singular values of F, the smallest negated when det F < 0 (the rotation variant's Sigma)."""
    sigma = np.linalg.svd(F, compute_uv=False)
    if np.linalg.det(F) < 0:
        sigma[-1] = -sigma[-1]
    return sigma


def _matrix(F: np.ndarray) -> str:
    return "[" + "; ".join(" ".join(f"{x:.6g}" for x in row) for row in F) + "]"


@dataclass
class Report:
    """The result of ``check``: ``rows`` (CheckRow per quantity), ``ok``, ``hints``, and the data the text needs."""

    rows: list[CheckRow]
    rtol: float
    law: str
    F: np.ndarray
    labels: list[str] | None = None
    hints: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    projected: bool = False
    #: the tangent's layout (model.verify.layouts)
    layout: str = "ijkl"
    #: the hints with their quantity and kind (model.verify.diagnosis.Diagnosis); ``hints`` holds their texts
    diagnoses: list = field(default_factory=list)
    #: yours beside the reference at the identity and at the worst sample of each failing quantity
    details: list[str] = field(default_factory=list)
    #: what was compared and what never was (model.verify.diagnosis.coverage)
    coverage: list[str] = field(default_factory=list)
    atol: float = 0.0
    #: M, the floor of the reference norms (the law's largest |A_ijkl(I)|), None: 1e-6 of the largest norm
    modulus: float | None = None

    @property
    def ok(self) -> bool:
        """True when every quantity is within rtol (and at least one was compared)."""
        return bool(self.rows) and all(r.ok for r in self.rows)

    def __iter__(self):  # type: ignore[no-untyped-def]
        return iter(self.rows)

    def __len__(self) -> int:
        return len(self.rows)

    def __getitem__(self, index: int) -> CheckRow:
        return self.rows[index]

    def row(self, quantity: str) -> CheckRow:
        for r in self.rows:
            if r.quantity == quantity:
                return r
        raise KeyError(f"no row for {quantity!r} (rows: {', '.join(r.quantity for r in self.rows)})")

    def label(self, n: int) -> str:
        return self.labels[n] if self.labels is not None else f"sample {n}"

    def raise_if_failed(self) -> None:
        """AssertionError with the report's text unless ok."""
        if not self.ok:
            raise AssertionError("\n" + str(self))

    def __str__(self) -> str:
        tangent = "A (PSD-projected, both sides)" if self.projected else "A"
        head = f"verify check: {self.law}, {len(self.F)} samples, rtol {self.rtol:g}"
        if self.atol:
            head += f", atol {self.atol:g}"
        head += f", tangent layout {self.layout}"
        lines = [head, format_rows(self.rows)]
        if self.modulus is not None:
            lines.append(f"(errors per sample: rel = |yours - ref| / max(|ref|, M), M = {self.modulus:.4g} the law's "
                         f"largest |A_ijkl| at F = I; a sample agrees when |yours - ref| <= rtol max(|ref|, M)"
                         + (" + atol)" if self.atol else ")"))
        if self.projected:
            lines.append(f"(A is compared as {tangent})")
        for r in self.rows:
            for reason, count in r.excluded:
                lines.append(f"{r.quantity}: {count} sample(s) excluded: {reason}")
        failing = [r for r in self.rows if not r.ok and r.worst_samples]
        for r in failing:
            lines.append(f"worst samples of {r.quantity}:")
            for n in r.worst_samples:
                sigma = ", ".join(f"{s:.6g}" for s in signed_singular_values(self.F[n]))
                lines.append(f"  #{n} {self.label(n)}: singular values ({sigma}), F = {_matrix(self.F[n])}")
        if self.labels is not None and failing:
            lines.append("max rel error per sample kind:")
            kinds = [k for k, _ in failing[0].per_kind]
            for r in failing[1:]:
                kinds += [k for k, _ in r.per_kind if k not in kinds]
            lines.append(f"  {'kind':28}" + "".join(f" {r.quantity:>10}" for r in failing))
            for kind in kinds:
                cells = []
                for r in failing:
                    value = dict(r.per_kind).get(kind)
                    cells.append(f" {value:10.2e}" if value is not None else f" {'-':>10}")
                lines.append(f"  {kind:28}" + "".join(cells))
        lines += self.details
        lines += [f"note: {n}" for n in self.notes]
        lines += [f"hint: {h}" for h in self.hints]
        lines += self.coverage
        lines.append("result: ok" if self.ok else "result: FAIL")
        return "\n".join(lines)
