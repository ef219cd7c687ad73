"""Muscle activation alpha as a DG0 field: per region, a piecewise-linear curve of time.

alpha(t) is linear between the table's points (t_i, alpha_i) and constant before the
first and after the last; t is the load factor of a quasi-static run (the time of a
dynamic one). Changing alpha only rewrites the Function's values: the forms that use it
are never recompiled.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from dolfinx import fem

from model import compat
from model.domain import Domain

Table = Sequence[tuple[float, float]]


def activation_at(table: Table, t: float) -> float:
    """alpha(t): piecewise linear through the table, constant before the first and after the last time."""
    times, values = zip(*table)
    return float(np.interp(t, times, values))


class ActivationField:
    """alpha per cell (DG0); each region added with its own time curve; zero on cells of no region."""

    def __init__(self, domain: Domain, name: str = "activation") -> None:
        self.domain = domain
        self.function = fem.Function(compat.function_space(domain.mesh, "DG", 0), name=name)
        self.curves: list[tuple[str, np.ndarray, tuple[tuple[float, float], ...]]] = []

    def add(self, region: str, table: Table) -> None:
        """Region ``region`` follows alpha(t) of ``table`` (values in [0, 1], times increasing)."""
        table = tuple((float(t), float(a)) for t, a in table)
        if not table or any(not 0.0 <= a <= 1.0 for _, a in table):
            raise ValueError(f"activation of {region!r}: values must be in [0, 1], got {table}")
        if any(t1 <= t0 for (t0, _), (t1, _) in zip(table, table[1:])):
            raise ValueError(f"activation of {region!r}: times must increase, got {table}")
        cells = self.domain.region_cells(region)
        dofs = compat.cell_dofs(self.function.function_space.dofmap).reshape(-1)[cells]
        self.curves.append((region, dofs, table))
        self.update(0.0)

    def update(self, t: float) -> None:
        """alpha <- alpha(t) on every region (a load hook)."""
        for _, dofs, table in self.curves:
            self.function.x.array[dofs] = activation_at(table, t)

    def values(self, t: float) -> dict[str, float]:
        """alpha(t) per region (for the run summary)."""
        return {region: activation_at(table, t) for region, _, table in self.curves}


__all__ = ["ActivationField", "activation_at"]
