"""Compiles and wall time of a 10-point sweep over law parameters, with the parameters held as runtime values
(model/problem/parameters.py) and as literals of the kernels (SOFTTISSUE_NUMBER_PARAMETERS=1, as before).

    PYTHONPATH=. OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/compile_once.py [--points 10]

The sweep: the uniaxial bar of examples/uniaxial.toml as an activated muscle (P1, 4 x 4 x 4 cells, one load
step), each point with new values of E, nu, sigma_max and the passive fibre's P1 (values never used before,
so that the literal mode cannot find them in the JIT cache). Each point runs in this process; the compiles
are FFCx's cache misses (ffcx.codegeneration.jit._compile_objects). Prints figures; asserts nothing.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import ffcx.codegeneration.jit as ffcx_jit  # noqa: E402

from model import pipeline  # noqa: E402
from model.config import load  # noqa: E402

MUSCLE = {"material.0.law": "muscle", "material.0.isotropic": "stvk", "loading.steps": 1,
          "material.0.fibres": {"type": "constant", "origin": [0.0, 0.0, 0.0], "insertion": [1.0, 0.0, 0.0]},
          "material.0.activation": [[0.0, 0.0], [1.0, 1.0]]}
COMPILED: list[str] = []


def _counting(original):  # noqa: ANN001, ANN202
    def counting(decl, ufl_objects, object_names, module_name, *args, **kwargs):  # noqa: ANN001, ANN002, ANN003, ANN202
        COMPILED.append(module_name)
        return original(decl, ufl_objects, object_names, module_name, *args, **kwargs)
    return counting


def sweep(points: int, literal: bool, out: Path) -> list[tuple[int, float]]:
    """(compiles, wall seconds) per point."""
    os.environ["SOFTTISSUE_NUMBER_PARAMETERS"] = "1" if literal else "0"
    salt = time.time() % 1.0  # new numbers every time this runs
    rows = []
    for i in range(points):
        f = 1.0 + 0.01 * i + 1e-6 * salt + (0.5 if literal else 0.0)
        overrides = {**MUSCLE, "material.0.E": 1.0e4 * f, "material.0.nu": 0.3 + 0.001 * i,
                     "material.0.sigma_max": 2.0e3 * f, "material.0.P1": 0.05 * f}
        COMPILED.clear()
        start = time.perf_counter()
        summary = pipeline.run(load(ROOT / "examples" / "uniaxial.toml", overrides), out / f"{literal}_{i}")
        assert summary["status"] == "completed", summary["status"]
        rows.append((len(COMPILED), time.perf_counter() - start))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=10)
    args = parser.parse_args()
    ffcx_jit._compile_objects = _counting(ffcx_jit._compile_objects)
    with tempfile.TemporaryDirectory() as tmp:
        held = sweep(args.points, False, Path(tmp))
        literal = sweep(args.points, True, Path(tmp))
    print("| point | compiles (held) | wall (held) s | compiles (literal) | wall (literal) s |")
    print("|---|---|---|---|---|")
    for i, ((c1, w1), (c2, w2)) in enumerate(zip(held, literal)):
        print(f"| {i} | {c1} | {w1:.1f} | {c2} | {w2:.1f} |")
    total_held, total_literal = sum(w for _, w in held), sum(w for _, w in literal)
    print(f"sweep of {args.points} points: held {total_held:.1f} s ({sum(c for c, _ in held)} compiles), literal "
          f"{total_literal:.1f} s ({sum(c for c, _ in literal)} compiles): {total_literal / total_held:.2f} x")


if __name__ == "__main__":
    main()
