"""Time to solution, iterations and peak memory against problem size, direct against iterative (issue 10).

    PYTHONPATH=. OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/scaling.py \
        [--cases p2_compressible,th_0.49,th_0.4999,isometric] [--linear direct,iterative] [--ranks 1 2] \
        [--limit 600] [--max-dofs 1.2e6] [--out results/scaling] [--plot docs/scaling.png]

Cases (each a config of the model, run by ``python -m model run``-equivalent children):

    p2_compressible  neo-Hookean, displacement formulation, P2, nu = 0.3; 2 x 1 x 1 bar of 2n x n x n boxes of six
                     tetrahedra, clamped at x = 0, sheared by a dead traction (0, 100, 30) Pa on x = 2, E = 1e4 Pa,
                     2 load steps
    th_0.49          the same bar, Taylor-Hood P2/P1 (mixed), nu = 0.49
    th_0.4999        the same, nu = 0.4999
    isometric        examples/isometric.toml (the fusiform muscle's isometric contraction, Taylor-Hood, 5 steps)
                     at mesh sizes 6 mm down to 1.2 mm (the generator refines the tendons with the size too)

Each size is one child process (``mpirun -n R`` for R > 1) with a wall-time limit (``--limit``, 600 s): the
series of a case, linear preset and rank count stops at the first size that exceeds it or fails, and at
``--max-dofs``. A child reports the dofs, Newton iterations, linear iterations per Newton iteration, the
largest-probe difference to the direct preset where both ran, the wall time of model.pipeline.run (mesh
generation, set-up, scale check, every load step; forms compiled by an untimed warm-up) and the peak resident
memory (VmHWM, summed over the ranks). Printed: one Markdown row per run, then per series the exponent of
time ~ dofs^k fitted by least squares over the runs from 5e4 dofs (and over all), and the ratio of 1-rank to
2-rank time at the size nearest 5e5 dofs. The rows go to OUT/scaling.json, the log-log plot (time against
dofs, one line per series, with its fitted slope) to ``--plot``. Asserts nothing: the targets of issue 10 are
read off the table (docs/solvers.md has the measured one).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

#: bar cells: 2n x n x n boxes (Taylor-Hood dofs ~ 51 n^3, P2 displacement dofs ~ 48 n^3)
BAR_SIZES = (6, 8, 10, 13, 16, 20, 25, 27)
#: isometric muscle mesh sizes (m): 48k .. about 1.1M Taylor-Hood dofs
MUSCLE_SIZES = (0.006, 0.004, 0.003, 0.0022, 0.0017, 0.0014, 0.0012)
CASES = ("p2_compressible", "th_0.49", "th_0.4999", "isometric")
#: fits of time ~ dofs^k use the runs from this many dofs (below it set-up and Python overheads dominate)
FIT_FROM = 50_000
HEADER = ("| case | linear | ranks | n or size | dofs | Newton its | linear its per Newton it: mean (min-max) "
          "| time to solution (s) | peak memory (MB, all ranks) | probes vs direct | status |\n"
          "|---|---|---|---|---|---|---|---|---|---|---|")


def bar(n: int, formulation: str, nu: float, linear: str) -> dict[str, Any]:
    return {"mesh": {"generator": "box", "size": [2.0, 1.0, 1.0], "cells": [2 * n, n, n]},
            "discretization": {"degree": 2, "formulation": formulation},
            "material": [{"region": "all", "law": "neo_hookean", "E": 1.0e4, "nu": nu}],
            "boundary": [{"on": "xmin", "type": "displacement", "value": [0.0, 0.0, 0.0]},
                         {"on": "xmax", "type": "traction", "value": [0.0, 100.0, 30.0]}],
            "loading": {"steps": 2},
            "probe": [{"name": "tip", "point": [2.0, 0.5, 0.5]}],
            "solver": {"linear": linear},
            "output": {"xdmf": False, "vtu": False, "png": False}}


def muscle(size: float, linear: str) -> dict[str, Any]:
    import tomllib

    raw = tomllib.loads((ROOT / "examples" / "isometric.toml").read_text())
    raw["mesh"]["size"] = size
    raw.setdefault("solver", {})["linear"] = linear
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    return raw


def config(case: str, size: float, linear: str) -> dict[str, Any]:
    if case == "p2_compressible":
        return bar(int(size), "displacement", 0.3, linear)
    if case.startswith("th_"):
        return bar(int(size), "mixed", float(case[3:]), linear)
    if case == "isometric":
        return muscle(size, linear)
    raise SystemExit(f"scaling: unknown case {case!r} (one of {', '.join(CASES)})")


# --- the child: one run -----------------------------------------------------------------------------------------


def child(raw_json: str, out: str) -> None:
    """Run one config (JSON) into ``out``; rank 0 prints one JSON line with the figures."""
    from mpi4py import MPI

    from model.config import parse
    from model.pipeline import run

    comm = MPI.COMM_WORLD
    raw = json.loads(raw_json)
    warm = {**raw, "loading": {"steps": 1}}
    if "cells" in raw["mesh"]:
        warm["mesh"] = {**raw["mesh"], "cells": [2, 1, 1]}
    else:
        warm["mesh"] = {**raw["mesh"], "size": 0.01}
    run(parse(warm, ROOT / "examples"), Path(out) / "warm-up", comm)  # compile the forms, untimed
    comm.Barrier()
    start = time.perf_counter()
    summary = run(parse(raw, ROOT / "examples"), Path(out) / "run", comm)
    wall = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    peak = comm.allreduce(_peak_memory(), op=MPI.SUM)
    if comm.rank == 0:
        counts = [c for s in summary["steps"] for c in s.get("linear_iterations_per_newton", [])]
        last = summary["steps"][-1] if summary["steps"] else {}
        print("RESULT " + json.dumps({
            "dofs": summary["dofs"], "status": summary["status"], "wall": wall, "peak_mb": peak / 1e6,
            "newton": sum(s["newton_iterations"] for s in summary["steps"]),
            "linear_per_newton": counts, "probes": last.get("probes", {}),
            "linear": summary["solver"].get("linear"), "matrix": summary["solver"].get("matrix"),
            "schur": summary["solver"].get("petsc_options", {}).get("pc_fieldsplit_schur_fact_type")}), flush=True)


def _peak_memory() -> float:
    """This process's peak resident memory (bytes), VmHWM of /proc/self/status."""
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmHWM:"):
                return float(line.split()[1]) * 1024.0
    return math.nan


# --- the driver -------------------------------------------------------------------------------------------------


def launch(raw: dict[str, Any], ranks: int, out: Path, limit: float) -> dict[str, Any]:
    """One child run; {"status": "time limit"} when it exceeds ``limit`` seconds."""
    command = [sys.executable, str(Path(__file__).resolve()), "--child", json.dumps(raw), str(out)]
    if ranks > 1:
        command = ["mpirun", "-n", str(ranks), "--oversubscribe", *command]
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
           "PYTHONPATH": f"{ROOT}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    if ranks > 1 and os.geteuid() == 0:  # Open MPI refuses root without these
        env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=limit + 120, env=env)
    except subprocess.TimeoutExpired:
        return {"status": "time limit"}
    for line in done.stdout.splitlines():
        if line.startswith("RESULT "):
            result = json.loads(line[len("RESULT "):])
            if result["wall"] > limit:
                result["status"] = f"{result['status']}, over the time limit"
            return result
    lines = [x for x in (done.stderr + done.stdout).splitlines() if "Error" in x or "error" in x]
    return {"status": f"failed: {(lines[-1] if lines else f'exit code {done.returncode}')[:160]}"}


def fit(points: list[tuple[float, float]]) -> float | None:
    """Least-squares slope k of log(time) = k log(dofs) + c; None with fewer than two points."""
    if len(points) < 2:
        return None
    xs = [math.log(d) for d, _ in points]
    ys = [math.log(t) for _, t in points]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    sxx = sum((x - mx) ** 2 for x in xs)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx if sxx > 0 else None


def probe_difference(a: dict[str, Any], b: dict[str, Any]) -> float | None:
    """Largest probe difference, relative to the largest probe value of ``b``."""
    if not a or not b or set(a) != set(b):
        return None
    diff = max(max(abs(x - y) for x, y in zip(a[k], b[k])) for k in a)
    scale = max(max(abs(y) for y in b[k]) for k in b)
    return diff / scale if scale > 0 else diff


def row(r: dict[str, Any]) -> str:
    counts = r.get("linear_per_newton") or []
    per = f"{sum(counts) / len(counts):.1f} ({min(counts)}-{max(counts)})" if counts else "-"
    diff = r.get("vs_direct")
    return (f"| {r['case']} | {r['linear']} | {r['ranks']} | {r['size']:g} | {r.get('dofs', '-')} | "
            f"{r.get('newton', '-')} | {per} | {r['wall']:.1f} | {r.get('peak_mb', math.nan):.0f} | "
            f"{'-' if diff is None else f'{diff:.1e}'} | {r['status']} |" if "wall" in r else
            f"| {r['case']} | {r['linear']} | {r['ranks']} | {r['size']:g} | - | - | - | - | - | - | {r['status']} |")


def plot(rows: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 5.0))
    colours = plt.get_cmap("tab20").colors
    for i, (key, series) in enumerate(_series(rows).items()):
        points = [(r["dofs"], r["wall"]) for r in series if _good(r)]
        if not points:
            continue
        slope = fit([p for p in points if p[0] >= FIT_FROM])
        label = " ".join(map(str, key)) + (f" (k = {slope:.2f})" if slope is not None else "")
        ax.loglog(*zip(*points), marker="o", label=label, color=colours[i % len(colours)],
                  linestyle="--" if "schur lower" in key else "-")  # the earlier preset dashed
    ax.set_xlabel("dofs")
    ax.set_ylabel("time to solution (s)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    ax.set_title("benchmarks/scaling.py: time ~ dofs^k")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _good(r: dict[str, Any]) -> bool:
    return r.get("status") == "completed" and "wall" in r


def _series(rows: list[dict[str, Any]]) -> dict[tuple[Any, ...], list[dict[str, Any]]]:
    """Rows by case, linear preset and ranks, and by the Schur factorisation where a row names one (the mixed
    iterative preset's ``pc_fieldsplit_schur_fact_type``: its lower-factor rows and its full-factorisation rows are
    two series)."""
    out: dict[tuple[Any, ...], list[dict[str, Any]]] = {}
    for r in rows:
        key = (r["case"], r["linear"], f"{r['ranks']} rank(s)")
        out.setdefault(key + ((f"schur {r['schur']}",) if r.get("schur") else ()), []).append(r)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--child", nargs=2, metavar=("CONFIG_JSON", "OUT"), help=argparse.SUPPRESS)
    parser.add_argument("--cases", default=",".join(CASES))
    parser.add_argument("--linear", default="direct,iterative")
    parser.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--limit", type=float, default=600.0, help="seconds per run; a series stops beyond it")
    parser.add_argument("--max-dofs", type=float, default=1.2e6)
    parser.add_argument("--bar-sizes", type=int, nargs="+", default=list(BAR_SIZES), help="n of the 2n x n x n bars")
    parser.add_argument("--muscle-sizes", type=float, nargs="+", default=list(MUSCLE_SIZES),
                        help="mesh sizes (m) of the isometric muscle")
    parser.add_argument("--out", type=Path, default=ROOT / "results" / "scaling")
    parser.add_argument("--plot", type=Path, default=None, help="log-log plot (PNG); default OUT/scaling.png")
    parser.add_argument("--report", type=Path, nargs="+", metavar="JSON",
                        help="run nothing: the tables and the plot of earlier runs' scaling.json files")
    args = parser.parse_args()
    if args.child:
        child(*args.child)
        return
    if args.report:
        rows = [r for path in args.report for r in json.loads(path.read_text())]
        print(HEADER)
        print("\n".join(row(r) for r in rows))
        report(rows, args.plot or args.report[0].with_suffix(".png"))
        return
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    print(HEADER, flush=True)
    for case in args.cases.split(","):
        for ranks in args.ranks:
            direct: dict[float, dict[str, Any]] = {}
            for linear in args.linear.split(","):
                for size in (args.muscle_sizes if case == "isometric" else args.bar_sizes):
                    r = {"case": case, "linear": linear, "ranks": ranks, "size": size}
                    r.update(launch(config(case, size, linear), ranks, args.out / f"{case}-{linear}-{ranks}-{size:g}",
                                    args.limit))
                    if linear == "direct" and _good(r):
                        direct[size] = r
                    elif size in direct and _good(r):
                        r["vs_direct"] = probe_difference(r["probes"], direct[size]["probes"])
                    rows.append(r)
                    print(row(r), flush=True)
                    (args.out / "scaling.json").write_text(json.dumps(rows, indent=1))
                    if not _good(r) or r.get("dofs", 0) >= args.max_dofs:
                        break
    report(rows, args.plot or args.out / "scaling.png")


def report(rows: list[dict[str, Any]], plot_path: Path) -> None:
    """The fitted exponents, the 1-rank / 2-rank ratios and the plot."""
    print("\n| case | linear | ranks | k (time ~ dofs^k), from 5e4 dofs | k, all sizes | largest dofs solved |")
    print("|---|---|---|---|---|---|")
    for key, series in _series(rows).items():
        good = [r for r in series if _good(r)]
        k_from = fit([(r["dofs"], r["wall"]) for r in good if r["dofs"] >= FIT_FROM])
        k_all = fit([(r["dofs"], r["wall"]) for r in good])
        largest = max((r["dofs"] for r in good), default=0)
        print(f"| {key[0]} | {key[1]} | {', '.join(key[2:])} | {'-' if k_from is None else f'{k_from:.2f}'} | "
              f"{'-' if k_all is None else f'{k_all:.2f}'} | {largest} |")
    def same(r: dict[str, Any]) -> tuple[Any, ...]:
        return r["case"], r["linear"], r["size"], r.get("schur") or ""

    one = {same(r): r for r in rows if r["ranks"] == 1 and _good(r)}
    two = [r for r in rows if r["ranks"] == 2 and _good(r) and same(r) in one]
    if two:
        print("\n| case | linear | dofs | time 1 rank / 2 ranks |")
        print("|---|---|---|---|")
        for r in two:
            name = r["linear"] + (f", schur {r['schur']}" if r.get("schur") else "")
            print(f"| {r['case']} | {name} | {r['dofs']} | {one[same(r)]['wall'] / r['wall']:.2f} |")
    plot(rows, plot_path)


if __name__ == "__main__":
    main()
