"""Every example gives the same summary.json as an earlier revision of the project (a refactoring check).

    python benchmarks/same_as_main.py --base REV [--only NAME,NAME] [--out DIR] [--rtol 1e-12]

Checks out REV (e.g. the main branch before a restructure) into a temporary git worktree, runs
``python -m model run examples/NAME.toml`` there and in this checkout, in the same process
environment, one after the other, and compares the two summary.json files of every example: every
number of every step (probes, reactions, energies, volumes, contact, activation, Newton iterations,
SNES reasons, load factors) and of the header (dofs, cells, volumes, areas), relative to the largest
magnitude of the same quantity in the run (so a reaction that is zero up to rounding is judged
against the largest reaction). Wall and solve times are not compared, nor keys that only one side
writes (they are listed). Exit 0 when every example agrees to --rtol; both sides' summaries stay in
--out. guided_stage1.toml (two stages, its own command) is left out.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
SKIP = {"guided_stage1"}
TIMES = {"wall_time_s", "solve_time_s"}


def run_example(tree: Path, example: Path, out: Path) -> tuple[bool, float]:
    env = dict(os.environ, PYTHONPATH=str(tree), OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "model", "run", str(example), "--out", str(out)], cwd=tree, env=env,
                          capture_output=True, text=True)
    if proc.returncode not in (0, 1):
        print(proc.stdout[-2000:], proc.stderr[-2000:], file=sys.stderr)
    return proc.returncode == 0, time.perf_counter() - start


def leaves(value: Any, path: tuple[str, ...] = ()) -> dict[tuple[str, ...], float]:
    """Numeric leaves of a JSON value by path (list indices are path entries too)."""
    out: dict[tuple[str, ...], float] = {}
    if isinstance(value, bool):
        out[path] = float(value)
    elif isinstance(value, (int, float)):
        out[path] = float(value)
    elif isinstance(value, dict):
        for k, v in value.items():
            if k not in TIMES:
                out.update(leaves(v, (*path, str(k))))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            out.update(leaves(v, (*path, str(i))))
    return out


def quantity(path: tuple[str, ...]) -> tuple[str, ...]:
    """The quantity a leaf belongs to: its path without step indices, names and components
    (steps.3.reactions.xmin.0 -> (steps, reactions))."""
    if path and path[0] == "steps" and len(path) > 2:
        return ("steps", path[2])
    return path[:1]


def compare(base: dict[str, Any], new: dict[str, Any], rtol: float) -> tuple[float, str, list[str]]:
    a, b = leaves(base), leaves(new)
    scale: dict[tuple[str, ...], float] = {}
    for path, v in a.items():
        q = quantity(path)
        scale[q] = max(scale.get(q, 0.0), abs(v))
    worst, where = 0.0, ""
    for path in sorted(set(a) & set(b)):
        s = scale[quantity(path)]
        error = abs(a[path] - b[path]) / s if s > 0 else abs(a[path] - b[path])
        if error > worst:
            worst, where = error, ".".join(path)
    only = sorted({".".join(quantity(p)) for p in set(a) ^ set(b)})
    return worst, where, only


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", required=True, help="the git revision to compare with")
    parser.add_argument("--only", default="", help="comma-separated example names (default: all)")
    parser.add_argument("--out", type=Path, default=ROOT / "results" / "same_as_main")
    parser.add_argument("--rtol", type=float, default=1e-12)
    args = parser.parse_args(argv)
    names = [p.stem for p in sorted((ROOT / "examples").glob("*.toml")) if p.stem not in SKIP]
    if args.only:
        names = [n for n in args.only.split(",") if n in names]
    failed = False
    with tempfile.TemporaryDirectory() as tmp:
        base_tree = Path(tmp) / "base"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-q", str(base_tree), args.base],
                       check=True)
        try:
            print("| example | base (s) | this (s) | max relative difference | where | keys on one side only |")
            print("|---|---|---|---|---|---|")
            for name in names:
                if not (base_tree / "examples" / f"{name}.toml").is_file():
                    print(f"| {name} | - | - | - | new example, not in {args.base} | - |", flush=True)
                    continue
                outs = {}
                seconds = {}
                for side, tree in (("base", base_tree), ("this", ROOT)):
                    outs[side] = args.out / side / name
                    ok, seconds[side] = run_example(tree, tree / "examples" / f"{name}.toml", outs[side])
                summaries = {s: json.loads((outs[s] / "summary.json").read_text()) for s in outs}
                worst, where, only = compare(summaries["base"], summaries["this"], args.rtol)
                failed |= worst > args.rtol
                print(f"| {name} | {seconds['base']:.1f} | {seconds['this']:.1f} | {worst:.2e} | {where or '-'} | "
                      f"{', '.join(only) or '-'} |", flush=True)
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(base_tree)], check=False)
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
