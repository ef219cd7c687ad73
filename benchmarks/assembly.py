"""Assembly rates and Newton iterations of every law (figures only, no assertions).

(a) Residual and Jacobian assembly rate, in cells per second, of every law at
    displacement degree 1 and 2 (quadrature "auto": the materials' energy with one point
    at P1, where it is exact, and degree 4 at P2; --quadrature 2p: 2 x P for every term) on a
    structured box at a smooth deformed state (a twist about the box's axis plus a
    stretch). Each law gets its own parameters (law_parameters: its registry defaults,
    the rest from E = 1 MPa, nu = 0.3) and fields (law_fields: per-cell a0, alpha, S).
    Each timing includes what the SNES callbacks do for a new iterate before assembling:
    the polar update of corotated and shape_target (recomputed in every repetition: the
    cached state is invalidated, since the solution does not change between repetitions),
    zeroing, assembly into a pre-created vector/matrix and the ghost exchange / final
    matrix assembly. Best of --repeats; in parallel each repetition counts with the
    slowest rank, and the rate uses the global number of cells. Form compilation
    (fem.form of residual and Jacobian, FFCx + C compiler) is timed separately, in a
    fresh JIT cache so it is a real compilation.
(b) Newton iterations per load step of examples/twisting_bar.toml with its material
    swapped for each law (the same parameters; fibres along the bar, muscle activated
    from 0 to 1, shape targets the identity), output files disabled.
    The forms are compiled by an untimed warm-up first; the wall time is that of
    model.pipeline.run (set-up with a warm JIT cache, load steps, probes, reactions).

    python benchmarks/assembly.py [--quick] [--laws stvk corotated] [--json out.json]
    mpirun -n 2 python benchmarks/assembly.py --quick

Both parts print a Markdown table (rank 0 only).
"""

from __future__ import annotations

import argparse
import copy
import json
import logging
import math
import shutil
import sys
import tempfile
import time
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from mpi4py import MPI

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import ufl  # noqa: E402
from dolfinx import fem  # noqa: E402
from dolfinx.fem import petsc as fem_petsc  # noqa: E402
from petsc4py import PETSc  # noqa: E402

import forms  # noqa: E402
import meshes  # noqa: E402
from model import compat  # noqa: E402
from model.config import parse  # noqa: E402
from model.domain import build_domain  # noqa: E402
from model.errors import SolveFailed  # noqa: E402
from model.pipeline import build, run  # noqa: E402
from model.problem import ElasticityProblem  # noqa: E402

TWISTING_BAR = ROOT / "examples" / "twisting_bar.toml"
E, NU = 1.0e6, 0.3
#: (degree, quadrature degree, box cells per side [full, quick]); "auto": the materials' energy with one
#: point at P1 (exact there) and 2 degree at P2, loads 2 degree (model.problem.elasticity.quadrature_degrees)
DISCRETIZATIONS: tuple[tuple[int, int | str, tuple[int, int]], ...] = ((1, "auto", (20, 6)), (2, "auto", (12, 4)))
#: the fields of the laws that take some (a0 along the box's axis, tilted per cell; alpha; S)
FIBRE_AXIS = np.array([1.0, 0.0, 0.0])


def law_parameters(name: str, E: float = E, nu: float = NU) -> dict[str, Any]:
    """Parameters of law ``name``: its registry defaults (forms.REGISTRY, e.g. muscle's and tendon's
    physiological values), the rest from the small-strain moduli of (E, nu).

    A law with the Lame sets (E, nu) / (mu, lmbda) among its required parameters gets E, nu; other
    required moduli: mu = E / (2 (1 + nu)), kappa = bulk modulus B = E / (3 (1 - 2 nu)); mooney_rivlin
    c1 = c2 = mu / 4 (shear modulus 2 (c1 + c2) = mu), K = B / 2 (2 K = kappa), ogden's m1 = 2; shape_target's kappa
    (default 0) is set to B so that its volume term is timed too.
    """
    entry = forms.REGISTRY[name]
    mu = E / (2.0 * (1.0 + nu))
    bulk = E / (3.0 * (1.0 - 2.0 * nu))
    moduli = {"mu": mu, "kappa": bulk, "c1": mu / 4.0, "c2": mu / 4.0, "K": bulk / 2.0, "m1": 2.0}
    params: dict[str, Any] = dict(entry.defaults)
    required = [p.name for p in entry.parameters if p.required and not p.applies]
    if entry.parameter_sets and set(entry.parameter_sets[0]) <= set(required):
        params.update(E=E, nu=nu)
        required = [k for k in required if not any(k in pair for pair in entry.parameter_sets)]
    for key in required:
        params[key] = moduli[key]
    if name == "shape_target":
        params["kappa"] = bulk
    return params


def law_fields(domain: Any, name: str) -> dict[str, fem.Function]:
    """Per-cell (DG0) fields of law ``name``, as the pipeline builds them: a0 (unit, within 0.3 rad of the
    x axis, varying per cell), s0 (unit, orthogonal to a0), alpha = 0.5, S (symmetric positive definite,
    eigenvalues 0.8..1.2)."""
    fields = forms.REGISTRY[name].fields
    msh = domain.mesh
    tdim = msh.topology.dim
    num_cells = msh.topology.index_map(tdim).size_local + msh.topology.index_map(tdim).num_ghosts
    midpoints = msh.geometry.x[compat.geometry_dofs(msh)[:num_cells]].mean(axis=1)  # cell centroids
    out: dict[str, fem.Function] = {}
    if "a0" in fields:
        tilt = 0.3 * np.sin(2.0 * np.pi * midpoints)  # smooth, per cell
        a0 = FIBRE_AXIS + np.stack([np.zeros(num_cells), tilt[:, 1], tilt[:, 2]], axis=1)
        out["a0"] = fem.Function(compat.function_space(msh, "DG", 0, (3,)), name="a0")
        out["a0"].x.array[: 3 * num_cells] = (a0 / np.linalg.norm(a0, axis=1)[:, None]).reshape(-1)
        if "s0" in fields:
            s0 = np.cross(a0, [0.0, 0.0, 1.0])
            out["s0"] = fem.Function(compat.function_space(msh, "DG", 0, (3,)), name="s0")
            out["s0"].x.array[: 3 * num_cells] = (s0 / np.linalg.norm(s0, axis=1)[:, None]).reshape(-1)
    if "alpha" in fields:
        out["alpha"] = fem.Function(compat.function_space(msh, "DG", 0), name="alpha")
        out["alpha"].x.array[:] = 0.5
    if "S" in fields:
        eig = 1.0 + 0.2 * np.sin(2.0 * np.pi * midpoints)
        out["S"] = fem.Function(compat.function_space(msh, "DG", 0, (3, 3)), name="S")
        out["S"].x.array[: 9 * num_cells] = (eig[:, :, None] * np.eye(3)).reshape(-1)
    return out


def slowest(comm: MPI.Comm, action: Callable[[], Any]) -> float:
    """Wall time of a collective action on the slowest rank."""
    comm.Barrier()
    start = time.perf_counter()
    action()
    return comm.allreduce(time.perf_counter() - start, op=MPI.MAX)


def best_of(comm: MPI.Comm, action: Callable[[], Any], repeats: int, min_time: float = 0.2) -> tuple[float, int]:
    """(seconds per call, calls per sample): best of ``repeats`` samples, each repeating the action
    often enough to take at least ``min_time`` (like timeit); a first, untimed call warms up."""
    first = slowest(comm, action)  # the same on every rank, so is ``number``
    number = max(1, math.ceil(min_time / max(first, 1e-9)))

    def sample() -> None:
        for _ in range(number):
            action()

    return min(slowest(comm, sample) for _ in range(repeats)) / number, number


def deformed_state(x: np.ndarray) -> np.ndarray:
    """A smooth displacement of the unit cube: twist of 0.6 rad per unit length about the
    axis y = z = 0.5, a 10 % stretch along x and a bending term; J stays near 1."""
    angle = 0.6 * x[0]
    y, z = x[1] - 0.5, x[2] - 0.5
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([0.1 * x[0] + 0.05 * np.sin(np.pi * x[1]) * x[2],
                     c * y - s * z - y + 0.05 * x[0] ** 2,
                     s * y + c * z - z])


def assembly_case(comm: MPI.Comm, law_name: str, degree: int, quadrature_degree: int | str, n: int,
                  repeats: int, min_time: float, cache_dir: str | None) -> dict[str, Any]:
    data = meshes.box((1.0, 1.0, 1.0), (n, n, n)) if comm.rank == 0 else None
    domain = build_domain(comm, data)
    msh = domain.mesh
    cells = msh.topology.index_map(msh.topology.dim).size_global
    law = forms.make_law(law_name, **law_parameters(law_name), **law_fields(domain, law_name))
    problem: ElasticityProblem | None = None

    def make_problem() -> None:
        nonlocal problem
        problem = ElasticityProblem(domain, [("all", law)], degree, quadrature_degree)

    setup_time = slowest(comm, make_problem)  # includes the polar Expression's JIT for corotated
    assert problem is not None
    problem.solution.interpolate(deformed_state)
    problem.solution.x.scatter_forward()
    residual_ufl = problem.residual_form
    jacobian_ufl = ufl.derivative(residual_ufl, problem.solution, ufl.TrialFunction(problem.space))
    compiled: dict[str, compat.Form] = {}
    compile_residual = slowest(comm, lambda: compiled.update(r=compat.compile_form(residual_ufl, cache_dir)))
    compile_jacobian = slowest(comm, lambda: compiled.update(j=compat.compile_form(jacobian_ufl, cache_dir)))
    residual, jacobian = compiled["r"], compiled["j"]
    b = fem_petsc.create_vector(residual)
    A = fem_petsc.create_matrix(jacobian)

    def new_state() -> None:
        """What a new Newton iterate costs before assembly: the polar update (corotated, shape_target).

        The solution does not change between repetitions, so the cached state is invalidated: each
        timed call recomputes R0, as SNES does once per iterate."""
        problem.invalidate_state()
        problem.update_state()

    def assemble_residual() -> None:
        new_state()
        with b.localForm() as b_local:
            b_local.set(0.0)
        fem_petsc.assemble_vector(b, residual)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)

    def assemble_jacobian() -> None:
        new_state()
        A.zeroEntries()
        fem_petsc.assemble_matrix(A, jacobian)
        A.assemble()

    t_update = best_of(comm, new_state, repeats, min_time)[0] if problem.polar_fields else 0.0
    t_residual, n_residual = best_of(comm, assemble_residual, repeats, min_time)
    t_jacobian, n_jacobian = best_of(comm, assemble_jacobian, repeats, min_time)
    result = {
        "law": law_name, "degree": degree, "quadrature_degree": problem.quadrature_degree,
        "energy_quadrature_degree": getattr(problem, "energy_quadrature_degree", problem.quadrature_degree),
        "box": n, "cells": cells,
        "dofs": problem.space.dofmap.index_map.size_global * problem.space.dofmap.index_map_bs,
        "ranks": comm.size, "setup_s": setup_time, "compile_residual_s": compile_residual,
        "compile_jacobian_s": compile_jacobian, "polar_update_s": t_update,
        "residual_s": t_residual, "jacobian_s": t_jacobian, "calls_per_sample": [n_residual, n_jacobian],
        "residual_cells_per_s": cells / t_residual, "jacobian_cells_per_s": cells / t_jacobian,
        # printed norms let a reader compare serial and parallel runs
        "residual_norm": b.norm(), "jacobian_norm": A.norm(PETSc.NormType.FROBENIUS),
    }
    b.destroy()
    A.destroy()
    return result


def newton_case(comm: MPI.Comm, law_name: str, quick: bool) -> dict[str, Any]:
    raw = tomllib.loads(TWISTING_BAR.read_text())
    raw = copy.deepcopy(raw)
    material: dict[str, Any] = {"region": "all", "law": law_name, **law_parameters(law_name)}
    fields = forms.REGISTRY[law_name].fields
    if "a0" in fields:
        material["fibres"] = {"type": "constant", "origin": [0.0, 0.0, 0.0], "insertion": [1.0, 0.0, 0.0]}
    if "s0" in fields:
        material["sheets"] = {"type": "constant", "origin": [0.0, 0.0, 0.0], "insertion": [0.0, 1.0, 0.0]}
    if "alpha" in fields:
        material["activation"] = [[0.0, 0.0], [1.0, 1.0]]
    if "S" in fields:
        material["S"] = np.eye(3).tolist()
    raw["material"] = [material]
    if quick:
        raw["mesh"]["cells"] = [10, 2, 2]
    directory = Path(comm.bcast(tempfile.mkdtemp(prefix="bench_newton_") if comm.rank == 0 else None, root=0))
    raw["output"] = {"dir": str(directory), "xdmf": False, "vtu": False, "png": False}
    config = parse(raw, TWISTING_BAR.parent)
    # warm-up: set the problem up once and compile its forms, so the timed run finds them in the JIT cache
    warmup = slowest(comm, lambda: build(config, comm).problem.forms)
    comm.Barrier()
    start = time.perf_counter()
    try:
        summary = run(config, directory, comm)
    except SolveFailed:
        summary = json.loads((directory / "summary.json").read_text()) if comm.rank == 0 else None
        summary = comm.bcast(summary, root=0)
    wall = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    comm.Barrier()
    if comm.rank == 0:
        shutil.rmtree(directory, ignore_errors=True)
    steps = summary["steps"]
    return {
        "law": law_name, "cells": summary["cells"], "dofs": summary["dofs"], "ranks": comm.size,
        "newton_iterations": [s["newton_iterations"] for s in steps],
        "converged": [s["converged"] for s in steps],
        "load_factors": [s["load_factor"] for s in steps],
        "total_newton_iterations": sum(s["newton_iterations"] for s in steps),
        "failed_attempts": sum(not s["converged"] for s in steps),
        "warmup_s": warmup, "wall_time_s": wall, "completed": summary.get("status") == "completed",
    }


def assembly_table(results: list[dict[str, Any]]) -> str:
    """One row per case; "/ nh" is the rate over neo_hookean's at the same degree (when it was run)."""
    lines = ["| law | P | q | cells | compile R + J (s) | polar update (s) | residual (s) | residual (cells/s) "
             "| Jacobian (s) | Jacobian (cells/s) | Jacobian / nh |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    reference = {r["degree"]: r["jacobian_cells_per_s"] for r in results if r["law"] == "neo_hookean"}
    for r in results:
        polar = f"{r['polar_update_s']:.3g}" if r["polar_update_s"] else "-"
        ratio = f"{r['jacobian_cells_per_s'] / reference[r['degree']]:.2f}" if r["degree"] in reference else "-"
        lines.append(f"| {r['law']} | {r['degree']} | {r['energy_quadrature_degree']} | {r['cells']} "
                     f"| {r['compile_residual_s']:.1f} + {r['compile_jacobian_s']:.1f} | {polar} "
                     f"| {r['residual_s']:.3g} | {r['residual_cells_per_s']:.3g} "
                     f"| {r['jacobian_s']:.3g} | {r['jacobian_cells_per_s']:.3g} | {ratio} |")
    return "\n".join(lines)


def newton_table(results: list[dict[str, Any]]) -> str:
    lines = ["| law | Newton iterations per step (x = failed attempt, cut back) | total | wall (s) | completed |",
             "|---|---|---|---|---|"]
    for r in results:
        its = " ".join(f"{n}{'' if ok else 'x'}" for n, ok in zip(r["newton_iterations"], r["converged"], strict=True))
        lines.append(f"| {r['law']} | {its} | {r['total_newton_iterations']} | {r['wall_time_s']:.1f} "
                     f"| {'yes' if r['completed'] else 'NO'} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small meshes (smoke test)")
    parser.add_argument("--laws", nargs="+", default=list(forms.LAWS), choices=list(forms.LAWS))
    parser.add_argument("--repeats", type=int, default=3, help="timed repetitions (best is kept)")
    parser.add_argument("--min-time", type=float, default=None,
                        help="seconds each timed sample lasts at least (default 0.2, 0.02 with --quick)")
    parser.add_argument("--json", type=Path, default=None, help="also write the figures to this JSON file")
    parser.add_argument("--skip", choices=("assembly", "newton"), default=None, help="leave out one part")
    parser.add_argument("--warm-cache", action="store_true",
                        help="compile into dolfinx's usual JIT cache (compile times are then not real; for tests)")
    parser.add_argument("--quadrature", choices=("auto", "2p"), default="auto",
                        help="\"auto\" (the materials' energy with one point at P1, exact) or \"2p\": degree "
                             "2 x P for every term (the default before \"auto\")")
    args = parser.parse_args(argv)
    comm = MPI.COMM_WORLD
    root = comm.rank == 0
    logging.getLogger("model").setLevel(logging.WARNING if root else logging.ERROR)

    def say(text: str = "") -> None:
        if root:
            print(text, flush=True)

    min_time = args.min_time if args.min_time is not None else (0.02 if args.quick else 0.2)
    start = time.perf_counter()
    figures: dict[str, Any] = {"ranks": comm.size, "quick": args.quick, "repeats": args.repeats}
    if args.skip != "assembly":
        fresh = not args.warm_cache
        cache_dir = comm.bcast(tempfile.mkdtemp(prefix="bench_jit_") if root and fresh else None, root=0)
        assembly = []
        for degree, quadrature_degree, sizes in DISCRETIZATIONS:
            if args.quadrature == "2p":
                quadrature_degree = 2 * degree
            n = sizes[1] if args.quick else sizes[0]
            for law_name in args.laws:
                r = assembly_case(comm, law_name, degree, quadrature_degree, n, args.repeats, min_time,
                                  cache_dir)
                say(f"assembly {law_name:13s} P{degree} q{r['energy_quadrature_degree']} {r['cells']} cells: "
                    f"residual {r['residual_s']:.3f} s, Jacobian {r['jacobian_s']:.3f} s, "
                    f"|b| {r['residual_norm']:.10e} |A|_F {r['jacobian_norm']:.10e}")
                assembly.append(r)
        comm.Barrier()
        if root and cache_dir is not None:
            shutil.rmtree(cache_dir, ignore_errors=True)
        figures["assembly"] = assembly
    if args.skip != "newton":
        newton = []
        for law_name in args.laws:
            r = newton_case(comm, law_name, args.quick)
            say(f"twisting bar {law_name:13s} newton {r['newton_iterations']} "
                f"{'completed' if r['completed'] else 'FAILED'} in {r['wall_time_s']:.1f} s")
            newton.append(r)
        figures["newton"] = newton
    figures["total_time_s"] = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    if "assembly" in figures:
        say(f"\n## Assembly ({comm.size} rank{'s' if comm.size > 1 else ''}, best of {args.repeats})\n")
        say(assembly_table(figures["assembly"]))
    if "newton" in figures:
        n = figures["newton"][0]
        say(f"\n## Newton iterations, twisting bar ({n['cells']} cells, {n['dofs']} dofs, "
            f"{comm.size} rank{'s' if comm.size > 1 else ''})\n")
        say(newton_table(figures["newton"]))
    say(f"\ntotal time {figures['total_time_s']:.0f} s")
    if args.json is not None and root:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(figures, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
