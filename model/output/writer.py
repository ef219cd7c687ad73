"""Results on disk: summary.json after every step, an XDMF time series, VTU files, and a PNG.

Fields written each converged step:
- ``u``: displacement, interpolated into P1 (the mesh's vertices) for output; on a curved (degree-2)
  mesh into P2 in the XDMF file (its nodes), the VTU files and the PNG showing the vertices only
  (straight-sided cells);
- ``J``, ``cauchy_stress`` (sigma = J^-1 P F^T), ``von_mises`` (sqrt(3/2 s:s)): cell
  averages (integrals over each cell with the run's quadrature rule divided by its
  volume, which works for quadrature-point state such as polar rotations too). J is
  kinematic, over every cell; the stresses are those of the problem's stress terms (its
  laws and the cell integrals of energies added with add_energy), zero on cells that
  have none (a body with no energy density there carries no stress);
- the problem's per-cell input fields (``fibre_direction`` a0, ``activation`` alpha) when present.
The VTU files (meshio) are written on rank 0 from the whole mesh gathered there;
the PNG is rendered from the last VTU (model.output.render, in a subprocess).
"""

from __future__ import annotations

import json
import logging
import os
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from dolfinx.io import XDMFFile
from petsc4py import PETSc

from model import compat
from model.output.render import render_in_subprocess
from model.problem import ElasticityProblem

log = logging.getLogger(__name__)


def write_json_atomic(path: Path, data: dict[str, Any]) -> None:
    """Write JSON through a temporary file and a rename, so a reader never sees half a file."""
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(data, indent=1))
    os.replace(tmp, path)


class CellAverages:
    """Cell averages of UFL expressions given per region, as DG0 Functions."""

    def __init__(self, problem: ElasticityProblem) -> None:
        msh = problem.domain.mesh
        self.problem = problem
        dx_all = problem.dx
        self.scalar_space = compat.function_space(msh, "DG", 0)
        self.tensor_space = compat.function_space(msh, "DG", 0, (3, 3))
        s, t = ufl.TestFunction(self.scalar_space), ufl.TestFunction(self.tensor_space)
        volume = fem_petsc.assemble_vector(fem.form(s * dx_all))
        volume.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        self.volume = volume.array.copy()
        volume.destroy()
        F = problem.F
        J_form = ufl.det(F) * s * dx_all
        sigma_form = sum((ufl.inner(sig, t) * dx for sig, dx in problem.cauchy_stress_terms()), start=0)
        vm_form = sum((vm * s * dx for vm, dx in problem.von_mises_terms()), start=0)
        #: name: (compiled form, or None when there is no stress term: the field stays zero; Function; block size)
        self.fields: dict[str, tuple[compat.Form | None, fem.Function, int]] = {
            "J": (fem.form(J_form), fem.Function(self.scalar_space, name="J"), 1),
            "cauchy_stress": (_form_or_none(sigma_form), fem.Function(self.tensor_space, name="cauchy_stress"), 9),
            "von_mises": (_form_or_none(vm_form), fem.Function(self.scalar_space, name="von_mises"), 1),
        }

    def update(self) -> dict[str, fem.Function]:
        self.problem.update_state()
        out = {}
        for name, (form, function, bs) in self.fields.items():
            out[name] = function
            if form is None:
                continue
            b = fem_petsc.assemble_vector(form)
            b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            n = self.volume.size
            function.x.array[: n * bs] = (b.array.reshape(n, bs) / self.volume[:, None]).reshape(-1)
            function.x.scatter_forward()
            b.destroy()
        return out


def _form_or_none(form: ufl.Form | int) -> compat.Form | None:
    """The compiled form, or None for the integer 0 (a sum with no terms)."""
    return None if isinstance(form, int) else fem.form(form)


class ResultWriter:
    """Writes the outputs of one run into ``directory`` (created if needed)."""

    def __init__(self, problem: ElasticityProblem, directory: Path, xdmf: bool = True, vtu: bool = True,
                 png: bool = True) -> None:
        self.problem = problem
        self.comm = problem.domain.mesh.comm
        self.directory = Path(directory)
        if self.comm.rank == 0:
            self.directory.mkdir(parents=True, exist_ok=True)
        self.comm.barrier()
        msh = problem.domain.mesh
        # XDMF needs the output's degree to be the geometry's
        self.u_out = fem.Function(compat.function_space(msh, "Lagrange", compat.geometry_degree(msh), (3,)), name="u")
        self.averages = CellAverages(problem)
        self.want_vtu, self.want_png = vtu, png
        self.xdmf = None
        if xdmf:
            self.xdmf = XDMFFile(self.comm, str(self.directory / "results.xdmf"), "w")
            self.xdmf.write_mesh(msh)
        self.count = 0
        self.last_gathered: dict[str, np.ndarray] | None = None

    def write_step(self, time: float) -> None:
        """Write the current state as time ``time`` (the load factor)."""
        if self.xdmf is None and not (self.want_vtu or self.want_png):
            self.count += 1
            return
        self.u_out.interpolate(self.problem.displacement())
        fields = {**self.averages.update(), **self.problem.cell_fields}
        if self.xdmf is not None:
            self.xdmf.write_function(self.u_out, time)
            for f in fields.values():
                self.xdmf.write_function(f, time)
        self.count += 1
        if self.want_vtu or self.want_png:
            self.last_gathered = self.gather(fields)
            if self.want_vtu and self.comm.rank == 0:
                write_vtu(self.directory / f"step_{self.count:04d}.vtu", self.last_gathered)

    def gather(self, fields: dict[str, fem.Function]) -> dict[str, np.ndarray] | None:
        """The whole mesh and fields on rank 0 (None elsewhere): points, cells, u, cell data."""
        msh = self.problem.domain.mesh
        tdim = msh.topology.dim
        num_cells = msh.topology.index_map(tdim).size_local
        geo_dofs = compat.geometry_dofs(msh)[:num_cells, :4]  # the vertices (first in P1 and P2 alike)
        ids = np.asarray(msh.geometry.input_global_indices, dtype=np.int64)[geo_dofs]
        coords = msh.geometry.x[geo_dofs]
        u_dofs = compat.cell_dofs(self.u_out.function_space.dofmap)[:num_cells, :4]
        u_values = self.u_out.x.array.reshape(-1, 3)[u_dofs]
        cell_values = {}
        for name, f in fields.items():
            bs = f.function_space.dofmap.index_map_bs
            dofs = compat.cell_dofs(f.function_space.dofmap).reshape(-1)[:num_cells]
            cell_values[name] = f.x.array.reshape(-1, bs)[dofs]
        parts = self.comm.gather((ids, coords, u_values, cell_values), root=0)
        if self.comm.rank != 0:
            return None
        all_ids = np.concatenate([p[0] for p in parts])
        n = int(all_ids.max()) + 1
        points = np.zeros((n, 3))
        u = np.zeros((n, 3))
        points[all_ids.reshape(-1)] = np.concatenate([p[1] for p in parts]).reshape(-1, 3)
        u[all_ids.reshape(-1)] = np.concatenate([p[2] for p in parts]).reshape(-1, 3)
        used = np.unique(all_ids)
        remap = np.full(n, -1, dtype=np.int64)
        remap[used] = np.arange(len(used))
        out = {"points": points[used], "cells": remap[all_ids], "u": u[used]}
        for name in fields:
            out[name] = np.concatenate([p[3][name] for p in parts])
        return out

    def write_png(self, title: str = "") -> Path | None:
        """The deformed body coloured by von Mises stress (rank 0), from the last written step."""
        if not self.want_png or self.comm.rank != 0 or self.last_gathered is None:
            return None
        path = self.directory / "deformed.png"
        vtu = self.directory / f"step_{self.count:04d}.vtu"
        if not self.want_vtu:
            vtu = self.directory / "deformed.vtu"
            write_vtu(vtu, self.last_gathered)
        try:
            render_in_subprocess(vtu, path, title)
        except (RuntimeError, OSError, subprocess.TimeoutExpired) as err:
            log.warning("no PNG written: %s", err)
            return None
        return path

    def close(self) -> None:
        if self.xdmf is not None:
            self.xdmf.close()
            self.xdmf = None


def write_vtu(path: Path, data: dict[str, np.ndarray]) -> None:
    """A VTU file (meshio) with the reference points, point data u and the cell averages."""
    import meshio

    cell_data = {k: [np.asarray(v)] for k, v in data.items() if k not in ("points", "cells", "u")}
    mesh = meshio.Mesh(data["points"], [("tetra", data["cells"])], point_data={"u": data["u"]},
                       cell_data=cell_data)
    mesh.write(path)
