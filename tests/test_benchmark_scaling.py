"""benchmarks/scaling.py on the smallest sizes: its children run, the table has every figure, the direct and
iterative presets agree, and the log-log plot is written (the script asserts nothing itself; its measured
table is in docs/solvers.md). It starts its own processes (mpirun for 2 ranks), so it runs serially only.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

from conftest import ROOT, environment, serial_only


@serial_only
def test_scaling_benchmark_smallest_sizes(tmp_path: Path) -> None:
    env = {**environment(), "OPENBLAS_NUM_THREADS": "1"}
    done = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "scaling.py"), "--cases", "th_0.4999",
         "--bar-sizes", "2", "3", "--ranks", "1", "2", "--limit", "300", "--out", str(tmp_path)],
        capture_output=True, text=True, timeout=900, env=env, cwd=ROOT)
    assert done.returncode == 0, done.stderr[-2000:]
    rows = json.loads((tmp_path / "scaling.json").read_text())
    # the Taylor-Hood case only (its iterative preset is the Schur one; the P2 displacement presets run in
    # tests/test_linear_presets): 8 runs instead of 16, about 150 s of CI
    assert len(rows) == 1 * 2 * 2 * 2  # cases x ranks x presets x sizes
    for r in rows:
        assert r["status"] == "completed", r
        assert r["dofs"] > 0 and r["wall"] > 0 and r["peak_mb"] > 100 and r["newton"] >= 2, r
        counts = r["linear_per_newton"]
        assert len(counts) == r["newton"], r  # one count per Newton iteration
        if r["linear"] == "iterative":
            assert min(counts) > 1, r  # a Krylov method, not LU
            assert r["vs_direct"] < 1e-8, r
        else:
            assert set(counts) == {1}, r
    # the same problem on 1 and 2 ranks: the same dofs
    by_key = {(r["case"], r["linear"], r["size"], r["ranks"]): r["dofs"] for r in rows}
    assert all(by_key[c, lin, s, 1] == by_key[c, lin, s, 2] for c, lin, s, _ in by_key)
    out = done.stdout
    # the mixed iterative rows record the Schur factorisation in effect (its own series in the fits), no other row
    assert all(r["schur"] == ("full" if (r["case"], r["linear"]) == ("th_0.4999", "iterative") else None) for r in rows)
    assert "| th_0.4999 | iterative | 1 rank(s), schur full |" in out and "time 1 rank / 2 ranks" in out
    assert (tmp_path / "scaling.png").stat().st_size > 10_000
    assert not any(math.isnan(r["peak_mb"]) for r in rows)


@serial_only
def test_scaling_report_of_the_documented_runs(tmp_path: Path) -> None:
    """docs/scaling.json (every row of docs/solvers.md's scaling table) redraws the plot and gives the fits the
    docs quote: time ~ dofs^1.12 (1 rank) and 1.09 (2 ranks) for the iterative Taylor-Hood bar from 5e4 dofs with the
    lower Schur factor (the preset until 2026-11-29), 1.10 on 2 ranks with the full factorisation (the preset since),
    each factorisation its own series."""
    plot = tmp_path / "scaling.png"
    done = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "scaling.py"), "--report", str(ROOT / "docs" / "scaling.json"),
         "--plot", str(plot)], capture_output=True, text=True, timeout=300, env=environment(), cwd=ROOT)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "| th_0.4999 | iterative | 1 rank(s), schur lower | 1.12 |" in done.stdout, done.stdout
    assert "| th_0.4999 | iterative | 2 rank(s), schur lower | 1.09 |" in done.stdout, done.stdout
    assert "| th_0.4999 | iterative | 2 rank(s), schur full | 1.10 |" in done.stdout, done.stdout
    assert "| th_0.4999 | iterative, schur lower | 426564 | 2.08 |" in done.stdout, done.stdout
    assert plot.stat().st_size > 10_000


def _variant(*args: str) -> dict[float, tuple[list[int], float, int]]:
    """benchmarks/schur_variants.py 3 ARGS: {nu: (linear iterations per Newton iteration, GFlop, peak MB)}."""
    done = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "schur_variants.py"), "3", *args],
                          capture_output=True, text=True, timeout=300,
                          env={**environment(), "OPENBLAS_NUM_THREADS": "1"}, cwd=ROOT)
    assert done.returncode == 0, done.stderr[-2000:]
    found = {}
    for line in done.stdout.splitlines():
        if line.startswith("n = 3, "):
            assert ": completed; linear its [" in line, line
            nu = float(line.split("nu = ")[1].split(",")[0])
            counts = json.loads(line.split("linear its ")[1].split("]")[0] + "]")
            found[nu] = (counts, float(line.split(" s, ")[-1].split(" GFlop")[0]),
                         int(line.split(", peak ")[1].split(" MB")[0]))
    assert set(found) == {0.3, 0.4999}, done.stdout
    return found


@serial_only
def test_schur_variants_script() -> None:
    """benchmarks/schur_variants.py (docs/solvers.md's table of preset variants) on the 2 023-dof bar: the preset
    (the full Schur factorisation), the lower factor (the preset until 2026-11-29) and a scaled weight all converge
    with one count per Newton iteration (2 steps: more than 2 iterations); the full factorisation takes fewer
    iterations than the lower factor at both nu, each costing more flops (two u-block V-cycles against one);
    --shear reaches the Schur weight (other counts than the preset's); --conformal reaches the near null space
    (ten modes: other counts); the printed peak (VmHWM, MB) is that of a Python process with
    PETSc loaded (over 50 MB)."""
    preset = _variant()
    lower = _variant("--options", json.dumps({"pc_fieldsplit_schur_fact_type": "lower"}))
    scaled = _variant("--shear", "1.5")
    conformal = _variant("--conformal")
    assert preset[0.3][2] > 50 and preset[0.4999][2] > 50, preset
    assert conformal[0.4999][0] != preset[0.4999][0], (conformal, preset)
    for nu in (0.3, 0.4999):
        counts, flops, _ = preset[nu]
        assert len(counts) > 2 and min(counts) > 1, preset
        assert len(lower[nu][0]) == len(counts), lower
        assert sum(counts) < sum(lower[nu][0]), (preset, lower)
        assert flops / sum(counts) > lower[nu][1] / sum(lower[nu][0]), (preset, lower)
    assert scaled[0.4999][0] != preset[0.4999][0], (scaled, preset)


@serial_only
def test_memory_trace_script(tmp_path: Path) -> None:
    """benchmarks/memory_trace.py (docs/solvers.md's per-stage memory table) on the 2 x 1 x 1 bar: every stage
    is marked once per call in run order (build, scale check, solver, one solve per load step), VmHWM never
    falls and bounds VmRSS at each mark, and the sampler's peak lies between the largest marked VmRSS and the
    final VmHWM."""
    env = {**environment(), "OPENBLAS_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "memory_trace.py"), "--n", "1",
                           "--out", str(tmp_path)], capture_output=True, text=True, timeout=300, env=env, cwd=ROOT)
    assert done.returncode == 0, done.stderr[-2000:]
    line = next(x for x in done.stdout.splitlines() if x.startswith("TRACE "))
    trace = json.loads(line[len("TRACE "):])
    assert trace["dofs"] > 0 and len(trace["ranks"]) == 1, trace
    marks = trace["ranks"][0]["marks"]
    stages = [m[1] for m in marks]
    assert stages == ["after warm-up", "build start", "build end", "scale_check start", "scale_check end",
                      "make_solver start", "make_solver end", "solve start", "solve end", "solve start",
                      "solve end", "end"], stages
    hwm = [m[3] for m in marks]
    assert hwm == sorted(hwm) and all(m[3] >= m[2] > 50 for m in marks), marks
    assert max(m[2] for m in marks) <= trace["ranks"][0]["sampled_peak"] <= hwm[-1] == trace["sum_hwm"], trace
