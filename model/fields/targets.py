"""Shape-target fields S: constant per region, per cell (array or .npy file), or procedural.

S lives in a DG0 tensor Function (one symmetric positive definite 3x3 matrix per
cell), so changing it never recompiles a form. Sources:

- constant: one 3x3 matrix for the region;
- per cell: an array (num_cells, 3, 3) in the mesh's cell order (MeshData.cells for
  built-in generators and mesh files), from Python or a .npy file;
- procedural: f(x, t) -> (n, 3, 3) with x (n, 3) the reference centroids of the
  region's cells and t the load factor, re-evaluated before every load step.

Every value is checked (forms.check_shape_targets) when it is set.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from dolfinx import fem
from dolfinx import mesh as dmesh

from forms.law import ParameterError
from forms.shape_target import check_shape_targets
from model import compat

TargetFunction = Callable[[np.ndarray, float], np.ndarray]
TargetSource = np.ndarray | TargetFunction


class TargetField:
    """S on the cells of a region, as a DG0 tensor Function (identity elsewhere)."""

    def __init__(self, domain: dmesh.Mesh, cells: np.ndarray, source: TargetSource | None = None,
                 name: str = "S") -> None:
        self.mesh = domain
        self.cells = np.asarray(cells, dtype=np.int32)
        self.name = name
        space = compat.function_space(domain, "DG", 0, (3, 3))
        self.function = fem.Function(space, name=name)
        num_local = self.function.x.array.size // 9
        self.function.x.array[:] = np.tile(np.eye(3).reshape(-1), num_local)
        dofs = compat.cell_dofs(space.dofmap).reshape(-1)
        self._index = (dofs[self.cells][:, None] * 9 + np.arange(9)).reshape(-1)
        self.source = source
        self.procedural = callable(source)
        tdim = domain.topology.dim
        self.centroids = dmesh.compute_midpoints(domain, tdim, self.cells) if self.procedural else None
        if source is None:
            return
        if self.procedural:
            self.update(0.0)
        else:
            values = np.asarray(source, dtype=np.float64)
            if values.shape == (3, 3):
                self.set_values(np.broadcast_to(values, (len(self.cells), 3, 3)))
            else:
                self.set_cell_array(values)

    def set_values(self, values: np.ndarray) -> None:
        """S of each of the region's cells (len(cells), 3, 3), checked on every rank (collective)."""
        comm = self.mesh.comm
        message = None
        try:
            values = check_shape_targets(values, self.name)
        except ValueError as err:
            message = str(err)
        failed = comm.allgather(message)
        first = next((m for m in failed if m is not None), None)
        if first is not None:
            raise ParameterError(first)
        self.function.x.array[self._index] = values.reshape(-1)

    def set_cell_array(self, array: np.ndarray) -> None:
        """S from an array over all cells of the mesh (num_cells_global, 3, 3) in mesh cell order."""
        array = np.asarray(array, dtype=np.float64)
        num_global = self.mesh.topology.index_map(self.mesh.topology.dim).size_global
        if array.ndim != 3 or array.shape != (num_global, 3, 3):
            raise ValueError(f"{self.name}: per-cell targets must have shape ({num_global}, 3, 3), got {array.shape}")
        original = np.asarray(self.mesh.topology.original_cell_index, dtype=np.int64)
        self.set_values(array[original[self.cells]])

    def update(self, t: float) -> None:
        """Re-evaluate a procedural target at load factor t (no-op for fixed targets)."""
        if not self.procedural:
            return
        values = np.asarray(self.source(self.centroids, float(t)), dtype=np.float64)  # type: ignore[operator]
        if values.shape != (len(self.cells), 3, 3):
            raise ValueError(f"{self.name}: the target function returned shape {values.shape}, "
                             f"expected ({len(self.cells)}, 3, 3)")
        self.set_values(values)
