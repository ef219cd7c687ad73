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
the PNG is rendered from the last VTU (model.output.render, in a subprocess), its colour bar titled
with the stress unit and its title line giving the largest displacement with the length unit.

The XDMF time series survives a killed process (SIGKILL included): each converged step goes to a file of
its own, results_NNNN.h5 (dolfinx's XDMFFile, opened and closed in that step), and results.xdmf is an
index rewritten after the step's file is closed (written to results.xdmf.tmp, fsync'ed, os.replace'd,
so a reader sees the old index or the new one, never half of one). The mesh is in results.h5, written
once. results.xdmf keeps dolfinx's layout (a Uniform grid "mesh" and one temporal collection per field,
whose grids xi:include the mesh), so ParaView, pyvista (VTK's XDMF reader) and meshio's
TimeSeriesReader read it; a step whose .h5 is half written when the process dies is not in the index.
A restarted run (``ResultWriter(..., resume=N)``) keeps the first N steps of the index and writes on.

One run per folder: ``ResultWriter.files`` lists every file the writer put into the folder (names
relative to it, the same list on every rank), which the pipeline records as summary.json's "files";
``remove_earlier_run`` deletes, before a new run writes anything, the files an earlier run's
summary.json accounts for, and nothing else.
"""

from __future__ import annotations

import errno
import json
import logging
import os
import subprocess
import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from dolfinx.io import XDMFFile
from mpi4py import MPI
from petsc4py import PETSc

from model import compat
from model.output.render import render_in_subprocess
from model.problem import ElasticityProblem

log = logging.getLogger(__name__)


SUMMARY = "summary.json"


def earlier_run_files(directory: Path) -> tuple[list[str], str] | None:
    """(names of the files an earlier run wrote into ``directory`` that still exist, its status), or None
    when ``directory``/summary.json is missing, unreadable or not a summary of this model.

    A summary of this model has "steps" (a list) and "status". Its files are its "files" list; a
    summary written before "files" existed accounts for step_0001.vtu ... step_NNNN.vtu (N its
    converged steps), results.xdmf and results.h5 (when it has a converged step) and deformed.png (when
    it has "png"). Only plain names of regular files directly in ``directory`` are returned, summary.json
    last; a file the summary does not account for is never among them.
    """
    path = Path(directory) / SUMMARY
    if not path.is_file():
        return None
    try:
        earlier = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        log.warning("%s is not a summary of this model (%s): left alone", path, err)
        return None
    if not (isinstance(earlier, dict) and isinstance(earlier.get("steps"), list) and "status" in earlier):
        log.warning("%s is not a summary of this model (no \"steps\" and \"status\"): left alone", path)
        return None
    if isinstance(earlier.get("files"), list):
        names = [n for n in earlier["files"] if isinstance(n, str)]
    else:
        converged = sum(1 for s in earlier["steps"] if isinstance(s, dict) and s.get("converged"))
        names = [f"step_{i:04d}.vtu" for i in range(1, converged + 1)]
        if converged:
            names += ["results.xdmf", "results.h5"]
        if earlier.get("png") == "deformed.png":
            names.append("deformed.png")
    names = [n for n in dict.fromkeys(names) if n != SUMMARY] + [SUMMARY]
    folder = Path(directory)
    keep = [n for n in names if Path(n).name == n and n not in (".", "..") and (folder / n).is_file()
            and not (folder / n).is_symlink()]
    return keep, str(earlier.get("status"))


def remove_earlier_run(directory: Path, comm: MPI.Comm = MPI.COMM_WORLD) -> int:
    """Delete the files of an earlier run in ``directory`` (earlier_run_files), on rank 0, then a barrier.

    Called by the pipeline before a run writes anything into the folder, so that the folder holds
    exactly one run: the files the new summary.json lists. Files the earlier summary does not account
    for (a user's own) are left alone. Logs "removed N files of an earlier run in DIR (summary.json of
    STATUS)". Returns N on every rank. (There is no restart: a future --restart would keep them.)
    """
    removed = 0
    if comm.rank == 0:
        found = earlier_run_files(Path(directory))
        if found is not None:
            names, status = found
            for name in names:
                try:
                    (Path(directory) / name).unlink()
                    removed += 1
                except FileNotFoundError:
                    pass
            log.warning("removed %d files of an earlier run in %s (summary.json of %s)", removed, directory,
                        f"a {status} run")
    removed = comm.bcast(removed, root=0)
    comm.barrier()
    return removed


def write_json_atomic(path: Path, data: dict[str, Any]) -> None:
    """Write JSON through a temporary file and a rename, so a reader never sees half a file."""
    write_text_atomic(path, json.dumps(data, indent=1))


def write_text_atomic(path: Path, text: str, sync: bool = False) -> None:
    """Write ``text`` to path.tmp, (``sync``: fsync it), then os.replace it onto ``path``: a reader (or a
    process killed at any point) sees the old file or the new one, never half of one. An OSError (a full disk)
    removes path.tmp and names ``path``."""
    path = Path(path)
    tmp = path.with_suffix(path.suffix + ".tmp")
    try:
        with open(tmp, "w") as f:
            f.write(text)
            if sync:
                f.flush()
                os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError as err:
        discard(tmp)
        raise named(err, path) from None


def named(err: OSError, path: Path) -> OSError:
    """``err`` with ``path`` as its file name where it has none (a write that fails on a full disk names none)."""
    return err if err.filename is not None else OSError(err.errno, err.strerror or str(err), str(path))


def discard(path: Path) -> None:
    """Remove a half-written file, if the system lets us (it frees the space a full disk needs for summary.json)."""
    try:
        Path(path).unlink(missing_ok=True)
    except OSError:
        pass


def on_rank0(comm: MPI.Comm, action: Callable[..., Any], *args: Any) -> Any:
    """``action(*args)`` on rank 0 (its result there, None elsewhere); an OSError it raises is raised on every
    rank (collective: a rank that went on to the next collective call while rank 0 failed would wait for ever)."""
    error: OSError | None = None
    result = None
    if comm.rank == 0:
        try:
            result = action(*args)
        except OSError as err:
            error = err
    error = comm.bcast(error, root=0)
    if error is not None:
        raise error
    return result


def _fsync(path: Path) -> None:
    """Flush a closed file's data to the disk (a power cut after this keeps it)."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


XINCLUDE = "http://www.w3.org/2001/XInclude"
#: what dolfinx's step grids include from the index: the Topology and Geometry of the first Uniform grid
MESH_POINTER = "xpointer(/Xdmf/Domain/Grid[@GridType='Uniform'][1]/*[self::Topology or self::Geometry])"


class XdmfSeries:
    """A crash-safe XDMF time series: the mesh in STEM.h5, step k in STEM_kkkk.h5, and STEM.xdmf an index
    rewritten atomically after each step (write_text_atomic). Collective (every rank writes its part of the
    .h5 files through dolfinx; rank 0 writes the index).

    ``resume``: keep the first ``resume`` steps of an existing index (a restart) instead of starting anew.
    """

    def __init__(self, msh: Any, directory: Path, stem: str = "results", resume: int = 0) -> None:
        self.comm = msh.comm
        self.mesh = msh
        self.directory = Path(directory)
        self.stem = stem
        self.index = self.directory / f"{stem}.xdmf"
        #: per field name: the XML of its step grids, in order
        self.series: dict[str, list[str]] = {}
        self.steps = 0
        mesh_grid = None
        if resume:
            if self.comm.rank == 0:
                mesh_grid, self.series = _read_index(self.index, resume)
            mesh_grid, self.series = self.comm.bcast((mesh_grid, self.series), root=0)
            self.steps = resume
        else:
            with XDMFFile(self.comm, str(self.index), "w") as f:
                f.write_mesh(msh)
            if self.comm.rank == 0:
                mesh_grid, _ = _read_index(self.index, 0)
        self.mesh_grid = mesh_grid
        self._write_index()

    def step_file(self, k: int) -> str:
        return f"{self.stem}_{k:04d}.h5"

    def write(self, functions: list[fem.Function], time: float) -> str:
        """Write one step (collective); returns the name of its .h5 file. The index lists the step once the
        file is closed and synced."""
        k = self.steps + 1
        part = self.directory / f"{self.stem}_{k:04d}.xdmf"
        from dolfinx import log as dolfinx_log

        level = dolfinx_log.get_log_level()
        dolfinx_log.set_log_level(dolfinx_log.LogLevel.ERROR)  # "No mesh found": it is in STEM.h5
        try:
            with XDMFFile(self.comm, str(part), "w") as f:
                for function in functions:
                    f.write_function(function, time)
        except RuntimeError as err:  # HDF5's (a full disk): this step's files go, the index stays as it was
            if self.comm.rank == 0:
                discard(part)
                discard(self.directory / self.step_file(k))
            raise OSError(errno.EIO, f"the HDF5 write failed: {err}", str(self.directory / self.step_file(k))) from None
        finally:
            dolfinx_log.set_log_level(level)
        def index() -> None:
            _fsync(self.directory / self.step_file(k))
            root = ET.parse(part).getroot()
            for collection in root.iter("Grid"):
                if collection.get("GridType") != "Collection":
                    continue
                for grid in collection.findall("Grid"):
                    self.series.setdefault(collection.get("Name", ""), []).append(_step_grid(grid))
            self.steps = k
            self._write_index()
            part.unlink()

        on_rank0(self.comm, index)  # an OSError (a full disk) on every rank
        self.steps = k
        return self.step_file(k)

    def _write_index(self) -> None:
        if self.comm.rank != 0:
            return
        collections = "".join(
            f'    <Grid Name="{name}" GridType="Collection" CollectionType="Temporal">\n{"".join(grids)}    </Grid>\n'
            for name, grids in self.series.items())
        text = ('<?xml version="1.0"?>\n<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>\n'
                f'<Xdmf Version="3.0" xmlns:xi="{XINCLUDE}">\n  <Domain>\n{self.mesh_grid}{collections}'
                '  </Domain>\n</Xdmf>\n')
        write_text_atomic(self.index, text, sync=True)


def _step_grid(grid: ET.Element) -> str:
    """The XML of one step grid of a field's collection: the mesh included, its Time and Attribute(s)."""
    time = grid.find("Time")
    attributes = "".join("        " + ET.tostring(a, encoding="unicode").strip() + "\n"
                         for a in grid.findall("Attribute"))
    return (f'      <Grid Name="{grid.get("Name", "")}" GridType="Uniform">\n'
            f'        <xi:include xpointer="{MESH_POINTER}" />\n'
            f'        <Time Value="{time.get("Value") if time is not None else "0"}" />\n{attributes}      </Grid>\n')


def _read_index(path: Path, steps: int) -> tuple[str, dict[str, list[str]]]:
    """The mesh grid (XML) of an XDMF file and, per field collection, the XML of its first ``steps`` grids."""
    root = ET.parse(path).getroot()
    domain = root.find("Domain")
    if domain is None:
        raise ValueError(f"{path}: no Domain")
    mesh_grid, series = "", {}
    for grid in domain.findall("Grid"):
        if grid.get("GridType") == "Collection":
            grids = grid.findall("Grid")
            if len(grids) < steps:
                raise ValueError(f"{path}: {grid.get('Name')} has {len(grids)} steps, fewer than {steps}")
            series[grid.get("Name", "")] = [_step_grid(g) for g in grids[:steps]]
        elif not mesh_grid:
            mesh_grid = "    " + ET.tostring(grid, encoding="unicode").strip() + "\n"
    if not mesh_grid:
        raise ValueError(f"{path}: no mesh grid")
    return mesh_grid, series


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
    """Writes the outputs of one run into ``directory`` (created if needed).

    ``files``: the names (relative to ``directory``) of every file written so far, in order, the same on
    every rank; ``stress_unit`` and ``length_unit`` label the PNG (colour bar and title line).
    """

    def __init__(self, problem: ElasticityProblem, directory: Path, xdmf: bool = True, vtu: bool = True,
                 png: bool = True, stress_unit: str = "", length_unit: str = "", resume: int = 0,
                 files: list[str] | None = None, render: Any = None) -> None:
        self.problem = problem
        self.stress_unit, self.length_unit = stress_unit, length_unit
        self.files: list[str] = list(files or [])
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
        self.xdmf: XdmfSeries | None = None
        if xdmf:
            self.xdmf = XdmfSeries(msh, self.directory, "results", resume=resume)
            self._add("results.xdmf", "results.h5")
        self.count = resume
        self.last_gathered: dict[str, np.ndarray] | None = None
        #: a model.fields.embedding.Embedding written deformed at every step (render/<name>_NNNN.<suffix>)
        self.render = render

    def write_step(self, time: float) -> None:
        """Write the current state as time ``time`` (the load factor)."""
        if self.render is not None:
            name = f"render/{self.render.path.stem}_{self.count + 1:04d}{self.render.path.suffix}"
            self.render.write(self.directory / name, self.problem.displacement())
            self._add(name)
        if self.xdmf is None and not (self.want_vtu or self.want_png):
            self.count += 1
            return
        self.u_out.interpolate(self.problem.displacement())
        fields = {**self.averages.update(), **self.problem.cell_fields}
        if self.xdmf is not None:
            self._add(self.xdmf.write([self.u_out, *fields.values()], time))
        self.count += 1
        if self.want_vtu or self.want_png:
            self.last_gathered = self.gather(fields)
            if self.want_vtu:
                on_rank0(self.comm, write_vtu, self.directory / f"step_{self.count:04d}.vtu", self.last_gathered)
                self._add(f"step_{self.count:04d}.vtu")

    def _add(self, *names: str) -> None:
        """Record files written into the folder (on every rank, whichever rank wrote them)."""
        self.files += [n for n in names if n not in self.files]

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
        """The deformed body coloured by von Mises stress, from the last written step (rendered on rank 0;
        collective: every rank returns the path, or None when there is no PNG).

        The colour bar is titled "von Mises stress [stress_unit]", the title line is ``title`` and the
        largest displacement in length_unit (model.output.render).
        """
        if not self.want_png or self.count == 0:
            return None
        path = self.directory / "deformed.png"
        written: list[str] = []
        if self.comm.rank == 0 and self.last_gathered is not None:
            vtu = self.directory / f"step_{self.count:04d}.vtu"
            if not self.want_vtu:
                vtu = self.directory / "deformed.vtu"
                write_vtu(vtu, self.last_gathered)
                written.append(vtu.name)
            try:
                render_in_subprocess(vtu, path, title, self.stress_unit, self.length_unit)
                written.append(path.name)
            except (RuntimeError, OSError, subprocess.TimeoutExpired) as err:
                log.warning("no PNG written: %s", err)
        written = self.comm.bcast(written, root=0)
        self._add(*written)
        return path if path.name in written else None

    def close(self) -> None:
        """Nothing stays open between steps (XdmfSeries); kept for the callers."""
        self.xdmf = None


def write_vtu(path: Path, data: dict[str, np.ndarray]) -> None:
    """A VTU file (meshio) with the reference points, point data u and the cell averages."""
    import meshio

    cell_data = {k: [np.asarray(v)] for k, v in data.items() if k not in ("points", "cells", "u")}
    mesh = meshio.Mesh(data["points"], [("tetra", data["cells"])], point_data={"u": data["u"]},
                       cell_data=cell_data)
    try:
        mesh.write(path)
    except OSError as err:  # a full disk: no half file, and the error names it
        discard(path)
        raise named(err, path) from None
