"""Newton on the trunk demo (examples/trunk.toml): exact vs projected tangent, bt vs full steps.

    python benchmarks/trunk_solvers.py [--max-it 50]

Prints a Markdown table: steps attempted, failed attempts, total and largest Newton iterations per
frame, wall time, and whether all frames were reached (figures only; no assertions).
"""

from __future__ import annotations

import argparse
import copy
import sys
import tempfile
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from model.config import parse  # noqa: E402
from model.errors import SolveFailed  # noqa: E402
from model.pipeline import run  # noqa: E402

CASES = [
    ("exact, bt", "exact", {"snes_linesearch_type": "bt"}),
    ("exact, full steps", "exact", {"snes_linesearch_type": "basic"}),
    ("projected, full steps", "projected", {"snes_linesearch_type": "basic"}),
]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--max-it", type=int, default=50, help="snes_max_it per frame")
    args = parser.parse_args()
    base = tomllib.loads((ROOT / "examples" / "trunk.toml").read_text())
    print("| tangent, line search | attempts | failed | Newton its | max per frame | wall (s) | completed |")
    print("|---|---|---|---|---|---|---|")
    for label, tangent, options in CASES:
        raw = copy.deepcopy(base)
        raw["solver"] = {**raw.get("solver", {}), "tangent": tangent,
                         "petsc_options": {**raw.get("solver", {}).get("petsc_options", {}), **options,
                                           "snes_max_it": args.max_it}}
        raw["output"] = {"xdmf": False, "vtu": False, "png": False}
        out = Path(tempfile.mkdtemp())
        start = time.perf_counter()
        try:
            summary, completed = run(parse(raw, ROOT / "examples"), out), "yes"
        except SolveFailed:
            import json

            summary, completed = json.loads((out / "summary.json").read_text()), "no"
        steps = summary["steps"]
        its = [s["newton_iterations"] for s in steps]
        failed = sum(not s["converged"] for s in steps)
        print(f"| {label} | {len(steps)} | {failed} | {sum(its)} | {max(its)} | "
              f"{time.perf_counter() - start:.1f} | {completed} |", flush=True)


if __name__ == "__main__":
    main()
