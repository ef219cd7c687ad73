"""Wall time of the checker of hand-derived formulas (``emit`` then ``check``) against the number of samples.

    PYTHONPATH=. OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/verify_speed.py \
        [--laws neo_hookean,corotated,muscle] [--sizes 1000 10000 100000] [--json out.json]

Per law (neo_hookean with E = 1e4 Pa, nu = 0.3; corotated, a polar law, with the same E and nu; muscle
with its defaults and the fields a0 and alpha) and number of samples N: ``emit`` (samples of F and of the
fields, the UFL reference psi, P, A, the tangent layout, the .npz file) and ``check`` of the emitted psi,
P and A (with the labels) against a fresh reference, in this process. The forms are compiled by an
untimed emit of 10 samples first. Columns: emit, of it the sampling (``deformation_samples``) and the
reference (``ReferenceEvaluator``: mesh, Expressions, evaluation), check, total (emit + check), the
total per sample, and per law the ratio of total times at the two largest sizes over the ratio of the
sizes (1 for a time linear in N, larger when it grows faster). Prints figures; asserts nothing.
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from model.verify import check, emit  # noqa: E402
from model.verify import emitter as _emitter  # noqa: E402
from model.verify import evaluator as _evaluator  # noqa: E402

LAWS: dict[str, dict[str, Any]] = {
    "neo_hookean": {"E": 1e4, "nu": 0.3},
    "corotated": {"E": 1e4, "nu": 0.3},
    "muscle": {},
}
SIZES = (1_000, 10_000, 100_000)
HEADER = ("| law | samples | emit (s) | of it sampling (s) | of it reference (s) | check (s) | total (s) "
          "| total per sample (us) |\n|---|---|---|---|---|---|---|---|")

#: seconds spent in the timed functions since the last reset, by label
SPENT: dict[str, float] = {}


def _timed(function: Callable[..., Any], label: str) -> Callable[..., Any]:
    @functools.wraps(function)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        start = time.perf_counter()
        try:
            return function(*args, **kwargs)
        finally:
            SPENT[label] = SPENT.get(label, 0.0) + time.perf_counter() - start
    return wrapper


def install_timers() -> None:
    """Time the sampling (emitter's deformation_samples) and the reference (ReferenceEvaluator's constructor
    and evaluate) wherever they run."""
    if hasattr(_emitter, "deformation_samples"):
        _emitter.deformation_samples = _timed(_emitter.deformation_samples, "sampling")
    cls = _evaluator.ReferenceEvaluator
    cls.__init__ = _timed(cls.__init__, "reference")  # type: ignore[method-assign]
    cls.evaluate = _timed(cls.evaluate, "reference")  # type: ignore[method-assign]


def measure(law: str, params: dict[str, Any], n: int, folder: Path) -> dict[str, Any]:
    """One emit and one check of ``n`` samples: their wall times and the timed parts of emit."""
    SPENT.clear()
    start = time.perf_counter()
    data = emit(law, params, n, 1, folder / f"{law}_{n}.npz")
    emitted = time.perf_counter() - start
    parts = dict(SPENT)
    fields = {name: data[name] for name in _evaluator.law_fields(law)}
    start = time.perf_counter()
    report = check(data["F"], psi=data["psi"], P=data["P"], tangent=data["A"], law=law, params=params,
                   fields=fields, labels=list(data["labels"]))
    checked = time.perf_counter() - start
    return {"law": law, "samples": n, "written": len(data["F"]), "emit": emitted,
            "sampling": parts.get("sampling", float("nan")), "reference": parts.get("reference", float("nan")),
            "check": checked, "total": emitted + checked, "per_sample_us": 1e6 * (emitted + checked) / n,
            "ok": report.ok}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--laws", default=",".join(LAWS), help="comma-separated, among " + ", ".join(LAWS))
    parser.add_argument("--sizes", type=int, nargs="+", default=list(SIZES))
    parser.add_argument("--json", type=Path, help="write the rows here")
    args = parser.parse_args(argv)
    laws = [name.strip() for name in args.laws.split(",") if name.strip()]
    unknown = [name for name in laws if name not in LAWS]
    if unknown:
        parser.error(f"--laws: unknown {', '.join(unknown)} (choose from {', '.join(LAWS)})")
    sizes = sorted(args.sizes)
    install_timers()
    print(f"chunk of ReferenceEvaluator: {_evaluator.CHUNK} samples")
    print(HEADER)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for law in laws:
            emit(law, LAWS[law], 10, 1, folder / "warm-up.npz")  # compiles the forms, untimed
            series = []
            for n in sizes:
                r = measure(law, LAWS[law], n, folder)
                series.append(r)
                flag = "" if r["ok"] else " (check FAILED)"
                print(f"| {law} | {n} | {r['emit']:.2f} | {r['sampling']:.2f} | {r['reference']:.2f} "
                      f"| {r['check']:.2f} | {r['total']:.2f} | {r['per_sample_us']:.1f}{flag} |", flush=True)
            rows += series
            if len(series) >= 2:
                a, b = series[-2], series[-1]
                ratio = b["total"] / a["total"]
                print(f"  {law}: total({b['samples']}) / total({a['samples']}) = {ratio:.2f} for "
                      f"{b['samples'] / a['samples']:.0f} times the samples (ratio / size ratio "
                      f"{ratio / (b['samples'] / a['samples']):.2f}; reference alone "
                      f"{b['reference'] / a['reference']:.2f})", flush=True)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
