"""Newton's line search over every example and an L-bracket cantilever: Newton iterations, failed steps, wall time.

    PYTHONPATH=. OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/line_search.py [--cases a,b] [--timeout 120]

For each case (examples/*.toml, coarsened where they are slow: COARSE, and benchmarks/l_bracket.toml, a soft
P1 Mooney-Rivlin L-bracket from a gmsh script bent by a tip traction) and each line search:

    bt (Pi)    bt backtracking on the total potential (SNES objective; only where the problem has one)
    bt (norm R) bt on the residual norm |R| (the objective switched off: the former default)
    basic      full Newton steps (the load stepping's cut-back is the only globalisation)
    cp         critical-point secant search on R . dx
    l2         secant search on the total potential where there is one, else on |R|^2

the run goes through model.pipeline.run as a user's would (the example's own snes_linesearch_type replaced,
output files off), in a child process with a time limit, and the table lists per case and line search:
Newton iterations over all attempted steps / failed steps (cut-backs) / wall time of the run in seconds
(mesh, compilation and solves), "gave up at s" when the load stepping gave up at load factor (or time) s,
"> T s" when the run did not end within the limit. The default line search (model.solvers.newton.
default_line_search) is marked with *. Prints a Markdown table (docs/solvers.md holds the measured one).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
BENCHMARKS = ROOT / "benchmarks"

#: line search name -> (snes_linesearch_type, objective for model.pipeline.run)
VARIANTS: dict[str, tuple[str, bool | None]] = {
    "bt (Pi)": ("bt", True),
    "bt (norm R)": ("bt", False),
    "basic": ("basic", False),
    "cp": ("cp", False),
    "l2": ("l2", None),
}

#: overrides (dotted keys) that make the slow examples quick enough for five runs each
COARSE: dict[str, dict[str, Any]] = {
    "arm_flexion": {"mesh.size": 0.012, "loading.steps": 6},
    "arm_segment": {"mesh.size": 0.012},
    "cook": {"mesh.cells": 8},
    "force_length_cylinder": {"mesh.size": 0.006},
    "force_length_fusiform": {"mesh.size": 0.01},
    "guccione_beam": {"mesh.cells": [10, 2, 2]},
    "isometric": {"mesh.size": 0.01},
    "isometric_mm": {"mesh.size": 10.0},
    "muscle_targets": {"mesh.cells": [3, 3, 8]},
    "rotating_muscle": {"mesh.size": 0.012, "dynamics.end_time": 0.05},
    "spindle": {"mesh.parameters.size": 0.01},
    "trunk": {"mesh.size": 0.45},
}


#: cases beyond the examples: name -> (configuration file, overrides)
EXTRA: dict[str, tuple[Path, dict[str, Any]]] = {
    "l_bracket": (BENCHMARKS / "l_bracket.toml", {}),
    # Cook's membrane in the pure displacement formulation, P1, nu = 0.4999: nearly incompressible, locked
    "cook_p1": (EXAMPLES / "cook.toml", {"mesh.cells": 8, "discretization.degree": 1,
                                         "discretization.quadrature_degree": 2,
                                         "discretization.formulation": "displacement"}),
    # the contact example with a penalty (an energy: bt on Pi) instead of VI bounds
    "contact_block_penalty": (EXAMPLES / "contact_block.toml", {"contact.method": "penalty",
                                                                "contact.penalty": 1.0e6}),
}


def cases() -> dict[str, Path]:
    out = {path.stem: path for path in sorted(EXAMPLES.glob("*.toml"))}
    out.update({name: path for name, (path, _) in EXTRA.items()})
    return out


def configuration(name: str, path: Path, line_search: str | None) -> dict[str, Any]:
    """The case's configuration, coarsened, with ``line_search`` (None: the default) and no output files."""
    raw = tomllib.loads(path.read_text())
    overrides = EXTRA[name][1] if name in EXTRA else COARSE.get(name, {})
    for key, value in overrides.items():
        *parents, last = key.split(".")
        table = raw
        for part in parents:
            table = table.setdefault(part, {})
            table = table[0] if isinstance(table, list) else table  # [[contact]]: the first
        table[last] = value
    solver = raw.setdefault("solver", {})
    options = {k: v for k, v in solver.get("petsc_options", {}).items() if k != "snes_linesearch_type"}
    solver["petsc_options"] = {**options, **({"snes_linesearch_type": line_search} if line_search else {})}
    raw["output"] = {**raw.get("output", {}), "xdmf": False, "vtu": False, "png": False}
    return raw


#: per case, from --facts: whether its problem has a potential and its default line search
FACTS: dict[str, dict[str, Any]] = {}


def facts(name: str) -> dict[str, Any]:
    """Whether the case's solver has the potential as its objective, and its default line search; compiles every
    form a run will, so that the timed runs find the JIT cache warm."""
    import logging

    from model.config import parse
    from model.pipeline import build, make_solver
    logging.basicConfig(level=logging.ERROR)
    path = cases()[name]
    config = parse(configuration(name, path, None), path.parent)
    setup = build(config)
    problem = setup.problem
    if config.dynamics is not None and config.dynamics.is_dynamic:
        from model.pipeline import _dynamics

        make_solver(problem, config, setup.contacts).destroy()  # the initial equilibrium's forms
        problem._forms = None
        _dynamics(setup, config)
    solver = make_solver(problem, config, setup.contacts)
    line_search = solver.line_search
    problem.energies()
    if line_search["merit"] == "total_potential":
        problem.total_potential()
    solver.destroy()
    return {"potential": line_search["merit"] == "total_potential", "default": line_search["type"]}


def run_one(name: str, variant: str) -> dict[str, Any]:
    """One run (in this process): the figures of the table as a dict."""
    import logging

    from model.config import parse
    from model.errors import SolveFailed
    from model.pipeline import run

    logging.basicConfig(level=logging.ERROR)
    path = cases()[name]
    kind, objective = VARIANTS[variant]
    config = parse(configuration(name, path, kind), path.parent)
    if objective and not FACTS[name]["potential"]:
        return {"skipped": True}
    with tempfile.TemporaryDirectory() as out:
        began = time.perf_counter()
        try:
            summary = run(config, Path(out), objective=objective)
        except SolveFailed:
            summary = json.loads((Path(out) / "summary.json").read_text())
        wall = time.perf_counter() - began
    steps = summary["steps"]
    converged = [s for s in steps if s["converged"]]
    last = converged[-1]["time"] if converged and "time" in converged[-1] else (
        converged[-1]["load_factor"] if converged else 0.0)
    return {"dofs": summary["dofs"],
            "line_search": summary["solver"].get("line_search"), "completed": summary["status"] == "completed",
            "newton": sum(s["newton_iterations"] for s in steps), "failed": len(steps) - len(converged),
            "attempts": len(steps), "wall": wall, "reached": last}


def cell(result: dict[str, Any] | None, timeout: float) -> str:
    if result is None:
        return f"> {timeout:.0f} s"
    if result.get("skipped"):
        return "-"
    if "error" in result:
        return "error"
    text = f"{result['newton']} / {result['failed']} / {result['wall']:.1f}"
    return text if result["completed"] else f"gave up at {result['reached']:.3g} ({text})"


def child(arguments: list[str], env: dict[str, str], timeout: float) -> dict[str, Any] | None:
    """This script in a child process: its JSON line, an error record when it failed, None after ``timeout``."""
    try:
        done = subprocess.run([sys.executable, __file__, *arguments], env=env, cwd=ROOT, capture_output=True,
                              text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return None
    lines = done.stdout.strip().splitlines()
    if done.returncode == 0 and lines:
        return json.loads(lines[-1])
    return {"completed": False, "newton": 0, "failed": 0, "wall": 0.0, "reached": 0.0,
            "error": done.stderr.strip().splitlines()[-1:]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", help="comma-separated case names (default: all)")
    parser.add_argument("--timeout", type=float, default=120.0, help="seconds per run")
    parser.add_argument("--one", nargs=2, metavar=("CASE", "VARIANT"), help=argparse.SUPPRESS)
    parser.add_argument("--facts", help=argparse.SUPPRESS)
    parser.add_argument("--known", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.facts:
        print(json.dumps(facts(args.facts)))
        return
    if args.one:
        FACTS[args.one[0]] = json.loads(args.known)
        print(json.dumps(run_one(*args.one)))
        return
    names = args.cases.split(",") if args.cases else list(cases())
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])),
           "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    header = "| case | dofs | objective Pi | " + " | ".join(VARIANTS) + " |"
    print(header)
    print("|" + "---|" * (3 + len(VARIANTS)))
    started = time.perf_counter()
    for name in names:
        known = child(["--facts", name], env, args.timeout) or {}
        results: dict[str, dict[str, Any] | None] = {}
        for variant in VARIANTS:
            if not known:
                results[variant] = None
                continue
            results[variant] = child(["--one", name, variant, "--known", json.dumps(known)], env, args.timeout)
            if results[variant] is not None and "error" in results[variant]:
                print(f"  {name} {variant}: {results[variant]['error']}", file=sys.stderr)
        dofs = next((r["dofs"] for r in results.values() if r is not None and "dofs" in r), "?")
        cells = []
        for variant, result in results.items():
            text = cell(result, args.timeout)
            kind, objective = VARIANTS[variant]
            if kind == known.get("default") and (objective is True) == bool(known.get("potential")) and text != "-":
                text += " *"
            cells.append(text)
        potential = {True: "yes", False: "no", None: "?"}[known.get("potential")]
        print(f"| {name} | {dofs} | {potential} | " + " | ".join(cells) + " |", flush=True)
    print(f"\n({time.perf_counter() - started:.0f} s in all; cells: Newton iterations / failed steps / wall s; "
          "* the default)", flush=True)


if __name__ == "__main__":
    main()
