"""Guided simulation (Klar et al. 2020, section 3): record shape targets from a driven run, replay them.

Stage 1 runs a configuration whose motion is imposed by attachments (Dirichlet data, usually
functions of the load factor t = the frame time) with shape targets S = I. After every
converged frame it stores, for every cell, the rotation-free stretch U of the polar
decomposition F = R U of the cell's deformation gradient (for P1, F is constant per cell; for
higher degrees the cell average of F is used), as an array (num_cells, 3, 3) in mesh cell
order, gathered over ranks.

Stage 2 re-simulates the same body from those targets alone: every attachment is dropped and
replaced by 3-2-1 point pins, which remove the six rigid-body modes and nothing else. The
targets of a frame are set per cell (TargetField.set_cell_array, through a load hook); between
stored frames they are interpolated linearly in t (a convex combination of SPD matrices is
SPD), which is only used when a frame has to be reached in sub-steps.

Why stage 2 reproduces stage 1: stage 1's deformation is compatible (it comes from a
displacement), and with S = U in every cell it is a state of zero energy,
F - R* S = R U - R U = 0 and J - det S = 0. The energy is non-negative, so that state is a global
minimiser, unique up to a rigid motion. 3-2-1 pins (A fixed; B, on a coordinate axis through
A, held in the two directions across that axis; C, in a coordinate plane through A and B,
held normal to that plane) can be met by every shape after a suitable rigid motion, so they do
not strain it: stage 2 lands on stage 1's shapes moved rigidly. The check aligns the two by the
best rigid motion (Kabsch) and reports max |x2 - x1| over the vertices relative to max |u1|.

    python -m model.experiments.guided examples/guided_stage1.toml --out results/guided [--pins "A; B; C"]
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

import forms
from model import compat
from model.config import RunConfig
from model.domain import Domain
from model.errors import ConfigError
from model.fields.targets import TargetField
from model.output.writer import ResultWriter, write_json_atomic
from model.pipeline import build
from model.problem import DirichletBoundary, ElasticityProblem
from model.solvers.loadstepping import StepRecord, step_loads
from model.solvers.newton import NewtonSolver

log = logging.getLogger(__name__)

Point = tuple[float, float, float]


# --- per-cell stretches and per-vertex positions, gathered on every rank ----------------------------

def polar_stretch(F: np.ndarray) -> np.ndarray:
    """U = sqrt(F^T F) of a batch F (..., 3, 3), symmetric positive definite when det F != 0."""
    C = np.swapaxes(F, -1, -2) @ F
    w, V = np.linalg.eigh(0.5 * (C + np.swapaxes(C, -1, -2)))
    U = (V * np.sqrt(np.clip(w, 0.0, None))[..., None, :]) @ np.swapaxes(V, -1, -2)
    return 0.5 * (U + np.swapaxes(U, -1, -2))


class CellDeformation:
    """Cell averages of F for a problem, gathered into mesh cell order on every rank."""

    def __init__(self, problem: ElasticityProblem) -> None:
        msh = problem.domain.mesh
        tdim = msh.topology.dim
        self.comm = msh.comm
        self.num_owned = msh.topology.index_map(tdim).size_local
        self.num_global = msh.topology.index_map(tdim).size_global
        self.original = np.asarray(msh.topology.original_cell_index, dtype=np.int64)[: self.num_owned]
        scalar = compat.function_space(msh, "DG", 0)
        tensor = compat.function_space(msh, "DG", 0, (3, 3))
        volume = fem_petsc.assemble_vector(fem.form(ufl.TestFunction(scalar) * problem.dx))
        self.volume = volume.array.copy()
        volume.destroy()
        self.scalar_dofs = compat.cell_dofs(scalar.dofmap).reshape(-1)[: self.num_owned]
        self.tensor_dofs = compat.cell_dofs(tensor.dofmap).reshape(-1)[: self.num_owned]
        self.form = fem.form(ufl.inner(problem.F, ufl.TestFunction(tensor)) * problem.dx)

    def gather(self, local: np.ndarray) -> np.ndarray:
        """Per owned cell values (num_owned, ...) -> (num_cells_global, ...) in mesh cell order, every rank."""
        parts = self.comm.allgather((self.original, local))
        out = np.empty((self.num_global, *local.shape[1:]))
        for index, values in parts:
            out[index] = values
        return out

    def average_F(self) -> np.ndarray:
        """(num_cells_global, 3, 3): integral of F over each cell divided by its volume."""
        b = fem_petsc.assemble_vector(self.form)
        values = b.array.reshape(-1, 9)[self.tensor_dofs] / self.volume[self.scalar_dofs, None]
        b.destroy()
        return self.gather(values.reshape(-1, 3, 3))

    def stretches(self) -> np.ndarray:
        """(num_cells_global, 3, 3): U of F = R U for the cell-average F of every cell."""
        return polar_stretch(self.average_F())


class VertexPositions:
    """Deformed positions X + u of the mesh vertices in input point order, gathered on every rank."""

    def __init__(self, problem: ElasticityProblem) -> None:
        msh = problem.domain.mesh
        tdim = msh.topology.dim
        self.problem = problem
        self.comm = msh.comm
        num_cells = msh.topology.index_map(tdim).size_local
        self.u = fem.Function(compat.function_space(msh, "Lagrange", 1, (3,)))
        geometry = compat.geometry_dofs(msh)[:num_cells]
        self.ids = np.asarray(msh.geometry.input_global_indices, dtype=np.int64)[geometry].reshape(-1)
        self.reference_local = msh.geometry.x[geometry].reshape(-1, 3)
        self.u_dofs = compat.cell_dofs(self.u.function_space.dofmap)[:num_cells].reshape(-1)
        self.num_points = self.comm.allreduce(int(self.ids.max(initial=-1)), op=MPI.MAX) + 1
        self.reference = self._gather(self.reference_local)

    def _gather(self, local: np.ndarray) -> np.ndarray:
        out = np.zeros((self.num_points, 3))
        for ids, values in self.comm.allgather((self.ids, local)):
            out[ids] = values
        return out

    def displacement(self) -> np.ndarray:
        """(num_points, 3) displacement of every vertex (the solution interpolated into P1)."""
        self.u.interpolate(self.problem.displacement())
        return self._gather(self.u.x.array.reshape(-1, 3)[self.u_dofs])


# --- rigid alignment ------------------------------------------------------------------------------

def kabsch(moving: np.ndarray, fixed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation Q and translation d minimising sum |Q p + d - q|^2 over rows p of moving, q of fixed."""
    cm, cf = moving.mean(axis=0), fixed.mean(axis=0)
    H = (moving - cm).T @ (fixed - cf)
    U, _, Vt = np.linalg.svd(H)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0])
    Q = Vt.T @ D @ U.T
    return Q, cf - Q @ cm


def aligned_error(moving: np.ndarray, fixed: np.ndarray) -> tuple[float, float]:
    """(max over points of |Q p + d - q| after the Kabsch alignment, rotation angle of Q in radians)."""
    Q, d = kabsch(moving, fixed)
    error = float(np.max(np.linalg.norm(moving @ Q.T + d - fixed, axis=1), initial=0.0))
    angle = float(np.arccos(np.clip(0.5 * (np.trace(Q) - 1.0), -1.0, 1.0)))
    return error, angle


# --- 3-2-1 pins -----------------------------------------------------------------------------------

def _axis_of(vector: np.ndarray, tol: float) -> int | None:
    """The coordinate axis a vector is parallel to, or None."""
    i = int(np.argmax(np.abs(vector)))
    others = np.delete(np.abs(vector), i)
    return i if np.all(others <= tol * abs(vector[i])) else None


def pin_components(A: Point, B: Point, C: Point, tol: float = 1e-9) -> list[tuple[Point, tuple[int, ...]]]:
    """[(A, (0, 1, 2)), (B, the two components across AB), (C, the component normal to plane ABC)].

    Requires AB parallel to a coordinate axis i and the plane ABC normal to a coordinate axis k
    (k != i): then every shape can be moved rigidly to satisfy the pins (translate A back, turn AB
    onto its axis, turn about it until C is back in its plane), so they remove exactly the six
    rigid-body modes and strain nothing.
    """
    a, b, c = (np.asarray(p, dtype=float) for p in (A, B, C))
    i = _axis_of(b - a, tol)
    if i is None:
        raise ValueError(f"pins: A {list(A)} and B {list(B)} must lie on a line parallel to a coordinate axis")
    normal = np.cross(b - a, c - a)
    if np.linalg.norm(normal) <= tol * np.linalg.norm(b - a) * np.linalg.norm(c - a):
        raise ValueError(f"pins: A, B, C {list(A)}, {list(B)}, {list(C)} are collinear")
    k = _axis_of(normal, tol)
    if k is None:
        raise ValueError(f"pins: A, B, C {list(A)}, {list(B)}, {list(C)} must span a coordinate plane")
    return [(A, (0, 1, 2)), (B, tuple(j for j in range(3) if j != i)), (C, (k,))]


def add_pins(problem: ElasticityProblem, pins: Sequence[tuple[Point, Sequence[int]]], tol: float = 1e-8) -> None:
    """u_j = 0 at each pin point (a mesh vertex) for its listed components; raises if a point is no vertex."""
    msh = problem.domain.mesh
    scale = float(np.max(np.ptp(msh.geometry.x, axis=0))) if msh.geometry.x.size else 1.0
    scale = msh.comm.allreduce(scale, op=MPI.MAX)
    for n, (point, components) in enumerate(pins):
        p = np.asarray(point, dtype=float)
        entry = DirichletBoundary(f"pin_{'ABC'[n] if n < 3 else n}", tuple(components))
        for comp in components:
            sub = problem.displacement_space.sub(comp)
            collapsed, _ = sub.collapse()
            dofs = fem.locate_dofs_geometrical(
                (sub, collapsed), lambda x, p=p: np.linalg.norm(x.T - p, axis=1) <= tol * scale)
            owned = problem.space.dofmap.index_map.size_local * problem.space.dofmap.index_map_bs
            found = msh.comm.allreduce(int(np.sum(dofs[0] < owned)), op=MPI.SUM)
            if found != 1:
                raise ValueError(f"pins: {list(point)} is not a vertex of the mesh ({found} dofs found)")
            g = fem.Function(collapsed)
            entry.values.append(g)
            entry.reference.append(g.x.array.copy())
            entry.of_load_factor.append(None)
            entry.dofs.append(dofs[0])
            entry.bcs.append(fem.dirichletbc(g, dofs, sub))
        problem.dirichlet.append(entry)


def bounding_box_pins(domain: Domain) -> list[tuple[Point, tuple[int, ...]]]:
    """3-2-1 pins at three bounding-box corners (box-like meshes): A = (xmin, ymin, zmin), B along x, C along y."""
    x = domain.mesh.geometry.x
    comm = domain.mesh.comm
    low, high = np.empty(3), np.empty(3)
    comm.Allreduce(x.min(axis=0) if x.size else np.full(3, np.inf), low, op=MPI.MIN)
    comm.Allreduce(x.max(axis=0) if x.size else np.full(3, -np.inf), high, op=MPI.MAX)
    A = (float(low[0]), float(low[1]), float(low[2]))
    B = (float(high[0]), float(low[1]), float(low[2]))
    C = (float(low[0]), float(high[1]), float(low[2]))
    return pin_components(A, B, C)


# --- the two stages -------------------------------------------------------------------------------

@dataclass
class Frame:
    load_factor: float
    newton_iterations: int
    targets: np.ndarray          # (num_cells, 3, 3) U per cell, mesh cell order
    displacement: np.ndarray     # (num_points, 3) per vertex, input point order
    energy: float


@dataclass
class Stage1:
    config: RunConfig
    domain: Domain
    reference: np.ndarray        # (num_points, 3) vertex positions
    frames: list[Frame] = field(default_factory=list)
    wall_time_s: float = 0.0

    @property
    def load_factors(self) -> np.ndarray:
        return np.array([f.load_factor for f in self.frames])

    @property
    def targets(self) -> np.ndarray:
        return np.stack([f.targets for f in self.frames])

    def save(self, path: Path) -> None:
        """The recorded performance as .npz (rank 0): load_factors (n,), targets (n, cells, 3, 3),
        displacements (n, points, 3) and the reference vertex positions."""
        if self.domain.mesh.comm.rank == 0:
            np.savez_compressed(path, load_factors=self.load_factors, targets=self.targets,
                                displacements=np.stack([f.displacement for f in self.frames]),
                                reference=self.reference)


def _writer(problem: ElasticityProblem, out: Path | None, config: RunConfig) -> ResultWriter | None:
    if out is None:
        return None
    o = config.output
    return ResultWriter(problem, out, o.xdmf, o.vtu, o.png, stress_unit=config.units.unit("stress"),
                        length_unit=config.units.unit("length"))


def run_stage1(config: RunConfig, out: Path | None = None, comm: MPI.Comm = MPI.COMM_WORLD) -> Stage1:
    """Run the driven configuration (shape targets as configured, usually S = I), recording U per frame."""
    start = time.perf_counter()
    setup = build(config, comm)
    if compat.geometry_degree(setup.domain.mesh) != 1:
        raise ConfigError("mesh.file: guided simulation records the vertices of 4-node tetrahedra; this mesh has "
                          "curved (10-node) cells: export it with linear tetrahedra")
    problem = setup.problem
    solver = NewtonSolver(problem, config.petsc_options)
    cells = CellDeformation(problem)
    vertices = VertexPositions(problem)
    writer = _writer(problem, out, config)
    stage = Stage1(config, setup.domain, vertices.reference)

    def on_step(record: StepRecord) -> None:
        if not record.result.converged:
            return
        stage.frames.append(Frame(record.load_factor, record.result.iterations, cells.stretches(),
                                  vertices.displacement(), problem.total_energy()))
        if writer is not None:
            writer.write_step(record.load_factor)

    problem.set_load_factor(0.0)
    ok = step_loads(solver, config.loading.steps, config.loading.max_cutbacks, config.loading.growth, on_step)
    if writer is not None:
        writer.write_png("stage 1 (attachments)")
        writer.close()
    solver.destroy()
    if not ok:
        raise RuntimeError(f"guided stage 1 failed after load factor {problem.time:.6g}")
    stage.wall_time_s = time.perf_counter() - start
    return stage


class FrameTargets:
    """S(t) per cell: the stored frame at a stored load factor, linear in t between frames (I at t = 0)."""

    def __init__(self, load_factors: np.ndarray, targets: np.ndarray) -> None:
        order = np.argsort(load_factors)
        num_cells = targets.shape[1]
        self.t = np.concatenate([[0.0], np.asarray(load_factors, dtype=float)[order]])
        self.S = np.concatenate([np.broadcast_to(np.eye(3), (1, num_cells, 3, 3)), targets[order]])

    def __call__(self, t: float) -> np.ndarray:
        k = int(np.searchsorted(self.t, t, side="left"))
        if k < len(self.t) and abs(self.t[k] - t) <= 1e-12:
            return self.S[k]
        k = min(max(k, 1), len(self.t) - 1)
        w = (t - self.t[k - 1]) / (self.t[k] - self.t[k - 1])
        return (1.0 - w) * self.S[k - 1] + w * self.S[k]


@dataclass
class Stage2Frame:
    load_factor: float
    newton_iterations: int
    substeps: int
    energy: float
    motion: float                # max |u1| over vertices (stage 1)
    error: float                 # max |x2 aligned - x1| over vertices
    relative_error: float        # error / motion
    rotation_deg: float          # the rigid motion that aligns stage 2 onto stage 1


def stage2_problem(config: RunConfig, domain: Domain) -> tuple[ElasticityProblem, list[TargetField]]:
    """The configuration's materials on ``domain`` with per-cell target fields (identity) and no boundary data."""
    materials, fields = [], []
    for i, m in enumerate(config.materials):
        if "S" not in forms.law_fields(m.law):
            raise ConfigError(f"material[{i}].law: guided simulation needs shape_target (or volume) laws, "
                              f"got {m.law.name!r}")
        target = TargetField(domain.mesh, domain.region_cells(m.region))
        materials.append((m.region, dataclasses.replace(m.law, S=target.function)))
        fields.append(target)
    d = config.discretization
    return ElasticityProblem(domain, materials, d.degree, d.quadrature_degree, d.formulation), fields


def run_stage2(stage1: Stage1, pins: Sequence[tuple[Point, Sequence[int]]] | None = None, out: Path | None = None,
               options: dict[str, Any] | None = None, max_depth: int = 6,
               on_frame: Callable[[Stage2Frame], None] | None = None) -> list[Stage2Frame]:
    """Re-simulate stage 1's frames from its stored targets alone, with 3-2-1 pins; the error of every frame."""
    config, domain = stage1.config, stage1.domain
    problem, fields = stage2_problem(config, domain)
    add_pins(problem, pins if pins is not None else bounding_box_pins(domain))
    targets = FrameTargets(stage1.load_factors, stage1.targets)
    for target in fields:
        problem.add_load_hook(lambda t, target=target: target.set_cell_array(targets(t)))
    solver = NewtonSolver(problem, {**config.petsc_options, **(options or {})})
    vertices = VertexPositions(problem)
    writer = _writer(problem, out, config)
    reference = stage1.reference
    results: list[Stage2Frame] = []
    problem.set_load_factor(0.0)
    current = 0.0

    def reach(target: float, depth: int) -> tuple[int, int]:
        """Solve at ``target`` from the state at ``current``, halving the step on failure: (iterations, steps)."""
        nonlocal current
        saved = problem.solution.x.array.copy()
        problem.set_load_factor(target)
        result = solver.solve()
        if result.converged:
            current = target
            return result.iterations, 1
        problem.solution.x.array[:] = saved
        problem.set_load_factor(current)
        if depth >= max_depth:
            raise RuntimeError(f"guided stage 2: no convergence at load factor {target:.6g} ({result.reason_name})")
        its1, n1 = reach(0.5 * (current + target), depth + 1)
        its2, n2 = reach(target, depth + 1)
        return its1 + its2, n1 + n2

    for frame in stage1.frames:
        iterations, substeps = reach(frame.load_factor, 0)
        u2 = vertices.displacement()
        error, angle = aligned_error(reference + u2, reference + frame.displacement)
        motion = float(np.max(np.linalg.norm(frame.displacement, axis=1)))
        record = Stage2Frame(frame.load_factor, iterations, substeps, problem.total_energy(), motion, error,
                             error / motion if motion > 0 else error, float(np.degrees(angle)))
        results.append(record)
        if writer is not None:
            writer.write_step(frame.load_factor)
        if on_frame is not None:
            on_frame(record)
    if writer is not None:
        writer.write_png("stage 2 (targets only)")
        writer.close()
    solver.destroy()
    return results


def error_table(frames: Sequence[Stage2Frame]) -> str:
    """The per-frame round-trip errors as a Markdown table."""
    lines = ["| frame | t | Newton its | max \\|u1\\| | max \\|x2 - x1\\| aligned | relative | energy | "
             "rigid rotation (deg) |", "|---|---|---|---|---|---|---|---|"]
    for n, f in enumerate(frames, start=1):
        lines.append(f"| {n} | {f.load_factor:.3f} | {f.newton_iterations} | {f.motion:.4f} | {f.error:.2e} | "
                     f"{f.relative_error:.2e} | {f.energy:.1e} | {f.rotation_deg:.2f} |")
    return "\n".join(lines)


def _parse_pins(text: str) -> list[tuple[Point, tuple[int, ...]]]:
    points = [tuple(float(v) for v in part.replace(",", " ").split()) for part in text.split(";")]
    if len(points) != 3 or any(len(p) != 3 for p in points):
        raise ValueError(f"--pins: give three points 'ax ay az; bx by bz; cx cy cz', got {text!r}")
    return pin_components(*points)  # type: ignore[arg-type]


def main(argv: Sequence[str] | None = None) -> int:
    from model.config import load

    parser = argparse.ArgumentParser(prog="python -m model.experiments.guided", description=__doc__.splitlines()[0])
    parser.add_argument("config", type=Path, help="stage 1 configuration (attachments, S = I)")
    parser.add_argument("--out", type=Path, default=None, help="output directory (default: output.dir/..)")
    parser.add_argument("--pins", default=None, help="3-2-1 pins 'A; B; C' (default: bounding-box corners)")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    comm = MPI.COMM_WORLD
    try:
        config = load(args.config)
        pins = _parse_pins(args.pins) if args.pins else None
    except (ConfigError, ValueError) as err:
        if comm.rank == 0:
            print(f"error: {err}", file=sys.stderr)
        return 2
    out = args.out if args.out is not None else config.output.dir.parent
    stage1 = run_stage1(config, out / "stage1", comm)
    stage1.save(out / "stage1" / "targets.npz")
    frames = run_stage2(stage1, pins, out / "stage2")
    if comm.rank == 0:
        table = error_table(frames)
        print(table)
        write_json_atomic(out / "guided.json", {"frames": [dataclasses.asdict(f) for f in frames],
                                                "stage1_wall_time_s": stage1.wall_time_s})
        (out / "errors.md").write_text(table + "\n")
    return 0


if __name__ == "__main__":
    PETSc.Sys.popErrorHandler()
    sys.exit(main())
