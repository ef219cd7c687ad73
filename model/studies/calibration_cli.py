"""``python -m model calibrate CONFIG --data FILE.csv --fit KEY[,KEY...] [--bounds KEY=LO:HI] [--set KEY=VALUE]
[--out DIR]``: fit law parameters to measurements (model.studies.calibration) from the command line.

Exit codes: 0 the fit was written (its warnings are printed: findings about the data), 1 a forward solve failed,
2 bad input (the one-line error names the key, the file and line).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

from mpi4py import MPI

EXAMPLE = ("softtissue calibrate examples/calibration/specimen.toml --data examples/calibration/measured.csv "
           "--fit material.0.E,material.0.nu --out results/calibration")


def add_parser(sub: Any) -> argparse.ArgumentParser:
    """The ``calibrate`` parser, added to the top-level subparsers ``sub``; its handler is ``main``."""
    from model.helptext import Formatter

    parser = sub.add_parser(
        "calibrate", help="fit law parameters to measured forces, displacements and volumes",
        formatter_class=Formatter,
        description="Fits law parameters of CONFIG (keys material.I.NAME) to measurements: minimises 1/2 sum w_i "
                    "(q_i - m_i)^2 over the load factors of the data with a bounded trust-region Gauss-Newton "
                    "(scipy least_squares, method trf), exact derivatives from UFL (one factorisation per measured "
                    "step), the forms compiled once. Writes calibration.json (fitted values, standard errors, "
                    "covariance, history), fit.csv, fit.png and fitted.toml to --out.",
        epilog=f"data file (CSV): columns load_factor, quantity, value and optionally sigma (standard deviation) or "
               f"weight; quantities probe.NAME.x|y|z, reaction.BOUNDARY.x|y|z, volume.REGION.\n\nexamples:\n  "
               f"{EXAMPLE}\n\nexit codes: 0 written, 1 a forward solve failed, 2 bad input. On several ranks: "
               f"mpirun -n 2 softtissue calibrate ...")
    parser.add_argument("config", type=Path, help="the configuration file (its values are the start)")
    parser.add_argument("--data", type=Path, required=True, help="the measurements (CSV, see below)")
    parser.add_argument("--fit", required=True, metavar="KEY[,KEY...]",
                        help="the parameters to fit, e.g. material.0.E,material.0.nu")
    parser.add_argument("--bounds", action="append", default=[], metavar="KEY=LO:HI",
                        help="narrow a parameter's range (default: the law's allowed range), e.g. "
                             "material.0.E=1e3:1e5; an empty end is open (material.0.nu=0:)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override a key of the file first (TOML value), e.g. loading.steps=10")
    parser.add_argument("--max-evaluations", type=int, default=50, help="most forward evaluations")
    parser.add_argument("--out", type=Path, default=None,
                        help="output folder (default: results/calibrate_<config name>)")
    parser.set_defaults(handler=main)
    return parser


def parse_bounds(texts: list[str]) -> dict[str, tuple[float | None, float | None]]:
    """KEY=LO:HI -> {KEY: (LO, HI)} (an empty end: None). ConfigError naming the text otherwise."""
    from model.errors import ConfigError

    out: dict[str, tuple[float | None, float | None]] = {}
    for text in texts:
        key, sep, rest = text.partition("=")
        low, colon, high = rest.partition(":")
        try:
            if not sep or not colon:
                raise ValueError
            ends = tuple(None if not v.strip() else float(v) for v in (low, high))
        except ValueError:
            raise ConfigError(f"--bounds {text!r}: write KEY=LO:HI, e.g. material.0.E=1e3:1e5") from None
        if any(v is not None and not math.isfinite(v) for v in ends):
            raise ConfigError(f"--bounds {text!r}: the ends must be finite numbers (leave one empty for none)")
        out[key.strip()] = ends  # type: ignore[assignment]
    return out


def main(args: argparse.Namespace) -> int:
    """Run the calibration of ``args``; the exit code."""
    from model.config import parse, read
    from model.config.overrides import apply, parse_assignments
    from model.errors import ConfigError, SolveFailed
    from model.studies.calibration import calibrate

    rank0 = MPI.COMM_WORLD.rank == 0
    out = args.out if args.out is not None else Path("results") / f"calibrate_{args.config.stem}"
    try:
        raw = read(args.config)
        if args.set:
            raw = apply(raw, parse_assignments(args.set))
        config = parse(raw, args.config.parent)
        keys = [k.strip() for k in args.fit.split(",") if k.strip()]
        result = calibrate(config, args.data, keys, parse_bounds(args.bounds), out=out,
                           max_evaluations=args.max_evaluations)
    except ConfigError as err:
        if rank0:
            print(f"error: {err}", file=sys.stderr, flush=True)
        return 2
    except SolveFailed as err:
        if rank0:
            print(f"error: {err}", file=sys.stderr, flush=True)
        return 1
    if rank0:
        print(result.text())
        print(f"written to {out}: calibration.json, fit.csv, fit.png, fitted.toml", flush=True)
    return 0
