"""Newton's globalisation on the mixed (Taylor-Hood) formulation: which default reaches the load without folding.

Cases (each run through the normal configuration route, in this process): Cook's membrane (nu = 0.4999) with
24x the benchmark's shear load in one step, the thick-walled incompressible sphere at 0.95 of its pressure
maximum (examples/thick_sphere.toml under load control, 4 steps), the idealised ventricle
(examples/ventricle.toml, incompressible, follower pressure, curved P2 cells) on its two mesh sizes, and three
harder ones: the ventricle near its load maximum in 2 steps, the sphere at 0.98 p_max in one step, Cook's
membrane at 40x its load in one step.

Variants:
  unchecked    full Newton steps, no admissibility check (the behaviour before det F was checked)
  domain       full steps; a trial state with det F <= 0 is a domain error (the step fails, load cut back)
  limited *    full steps shortened (halved) until det F > 0 at every material point (the default)
  bt           limited, then PETSc's bt line search on the residual norm
  tr           PETSc's trust region (newtontr; no line search, so no shortening: domain errors shrink the region)

Printed per case and variant: completed, Newton iterations over all attempted steps / failed steps / wall time
(s), the smallest min det F of the accepted steps (negative: a folded state accepted as converged), and the
admissibility check's share of the run (the time of Admissibility.minimum and step_limit over the wall time).

    PYTHONPATH=. OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/mixed_globalisation.py [--cases a,b]
"""

from __future__ import annotations

import argparse
import json
import logging
import tempfile
import time
from pathlib import Path
from typing import Any

from model.problem.admissibility import Admissibility

ROOT = Path(__file__).resolve().parents[1]
P_MAX = 0.49351893  # the thick sphere's p_max / mu (tests/test_path_following.py)

CASES: dict[str, tuple[str, dict[str, Any]]] = {
    "cook_overload": ("cook", {"mesh.cells": 4, "boundary.3.value": [0.0, 150.0, 0.0], "loading.steps": 1}),
    "thick_sphere": ("thick_sphere", {"loading.control": "load", "loading.steps": 4,
                                      "boundary.3.value": 0.95 * P_MAX * 1000.0}),
    "ventricle": ("ventricle", {}),
    "ventricle_fine": ("ventricle", {"mesh.parameters": {"size": 0.004}}),
    # large steps near the limit: the ventricle at 1.2 kPa (its maximum is near 1.24 kPa) in 2 steps, the sphere
    # at 0.98 p_max in one, Cook's membrane at 40x its load in one
    "ventricle_hard": ("ventricle", {"boundary.3.value": 1200.0, "loading.steps": 2}),
    "thick_sphere_hard": ("thick_sphere", {"loading.control": "load", "loading.steps": 1,
                                           "boundary.3.value": 0.98 * P_MAX * 1000.0}),
    "cook_overload_40": ("cook", {"mesh.cells": 4, "boundary.3.value": [0.0, 250.0, 0.0], "loading.steps": 1}),
    # a follower pressure bending a Guccione beam (a user law), where bt on the residual norm was 5x slower
    "guccione_beam": ("guccione_beam", {}),
}
VARIANTS = ("unchecked", "domain", "limited", "bt", "tr")


class Timed:
    """Patches Admissibility's methods per variant and times the check."""

    def __init__(self, variant: str) -> None:
        self.variant = variant
        self.seconds = 0.0
        self.original = (Admissibility.minimum, Admissibility.step_limit, Admissibility.report)

    def __enter__(self) -> Timed:
        minimum, step_limit, report = self.original
        timed = self

        def unchecked_report(check: Admissibility) -> dict[str, Any]:
            real = report(check)  # the solver sees an admissible state; the table the true minimum
            return {**real, "min_det_F": 1.0, "true_min_det_F": real["min_det_F"]}

        def timed_minimum(check: Admissibility) -> float:
            began = time.perf_counter()
            value = minimum(check)
            timed.seconds += time.perf_counter() - began
            return 1.0 if timed.variant == "unchecked" else value

        def timed_limit(check: Admissibility, direction: Any) -> float:
            if timed.variant in ("unchecked", "domain"):
                return 1.0
            began = time.perf_counter()
            value = step_limit(check, direction)
            timed.seconds += time.perf_counter() - began
            return value

        Admissibility.minimum = timed_minimum
        Admissibility.step_limit = timed_limit
        if self.variant == "unchecked":
            Admissibility.report = unchecked_report
        return self

    def __exit__(self, *exc: Any) -> None:
        Admissibility.minimum, Admissibility.step_limit, Admissibility.report = self.original


def run(case: str, variant: str) -> dict[str, Any]:
    import model
    from model.errors import SolveFailed

    name, overrides = CASES[case]
    overrides = {**overrides, "output.xdmf": False, "output.vtu": False, "output.png": False}
    if variant == "bt":
        overrides["solver.petsc_options.snes_linesearch_type"] = "bt"
    if variant == "tr":
        overrides["solver.petsc_options.snes_type"] = "newtontr"
    config = model.load_config(ROOT / "examples" / f"{name}.toml", overrides=overrides)
    with tempfile.TemporaryDirectory() as out, Timed(variant) as timed:
        began = time.perf_counter()
        try:
            model.run(config, out=out)
        except SolveFailed:
            pass
        wall = time.perf_counter() - began
        summary = json.loads((Path(out) / "summary.json").read_text())
    steps = summary["steps"]
    accepted = [s for s in steps if s["converged"]]
    return {"completed": summary["status"] == "completed", "dofs": summary["dofs"],
            "newton": sum(s["newton_iterations"] for s in steps), "failed": sum(not s["converged"] for s in steps),
            "wall": wall, "check_share": timed.seconds / wall,
            "min_det_F": min((s.get("true_min_det_F", s["min_det_F"]) for s in accepted
                              if isinstance(s.get("true_min_det_F", s["min_det_F"]), float)), default=None)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cases", default=",".join(CASES))
    parser.add_argument("--variants", default=",".join(VARIANTS))
    args = parser.parse_args()
    logging.basicConfig(level=logging.ERROR)
    logging.getLogger().setLevel(logging.ERROR)
    print("| case | dofs | " + " | ".join(f"{v}{' *' if v == 'limited' else ''}" for v in args.variants.split(","))
          + " |")
    print("|---|---|" + "---|" * len(args.variants.split(",")))
    for case in args.cases.split(","):
        cells, dofs = [], 0
        for variant in args.variants.split(","):
            r = run(case, variant)
            dofs = r["dofs"]
            det = "-" if r["min_det_F"] is None else f"{r['min_det_F']:.3g}"
            status = "" if r["completed"] else "gave up: "
            cells.append(f"{status}{r['newton']} / {r['failed']} / {r['wall']:.1f}, J {det}, check "
                         f"{100 * r['check_share']:.1f} %")
        print(f"| {case} | {dofs} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
