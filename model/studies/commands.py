"""The ``sweep`` command line: ``python -m model sweep CONFIG --set KEY=V1,V2,... [--set ...] [--grid | --zip]
[--jobs N] --out DIR`` (model.studies.sweep).

Exit codes: 0 every run completed, 1 some runs failed (the table is written, with their status and
reason), 2 bad input (one line "error: ...", nothing run). Serial: under mpirun with more than one rank it
refuses (exit 2); each run is a serial child process, ``--jobs`` of them at a time.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from model.errors import ConfigError

EPILOG = ("values are TOML (1e4, true, \"text\", [0.1, 0]); a comma inside brackets belongs to an array: "
          "--set boundary.0.value=[0.1,0],[0.2,0]. Runs go to DIR/runs/HASH/, the table to DIR/sweep.csv "
          "(and sweep.parquet with pyarrow); sweeping again skips completed runs.\n"
          "exit codes: 0 all runs completed, 1 some failed (table written), 2 bad input (nothing run)\n\n"
          "examples:\n  softtissue sweep examples/uniaxial.toml --set material.0.E=1e4,2e4,4e4 --out results/sweep_E\n"
          "  softtissue sweep examples/uniaxial.toml --set material.0.E=1e4,2e4 --set material.0.nu=0.3,0.45 --zip "
          "--jobs 2 --out results/sweep_zip")


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """The ``sweep`` sub-command."""
    from model.helptext import Formatter

    parser = subparsers.add_parser("sweep", help="run a configuration for many values of some keys, one table",
                                   description="run a configuration for many values of some keys (child processes, one "
                                   "per run) and "
                                   "collect their results in one table (docs/studies.md)", epilog=EPILOG,
                                   formatter_class=Formatter)
    parser.add_argument("config", type=Path)
    parser.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=V1,V2,...",
                        help="a dotted key and its values (repeat for more keys)")
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--grid", dest="mode", action="store_const", const="grid",
                      help="every combination of the values (the default)")
    mode.add_argument("--zip", dest="mode", action="store_const", const="zip",
                      help="the i-th values of every key together (equal numbers of values)")
    parser.set_defaults(mode="grid")
    parser.add_argument("--jobs", type=int, default=1, help="runs at a time")
    parser.add_argument("--out", type=Path, required=True, help="the sweep's folder")
    return parser


def main(args: argparse.Namespace) -> int:
    """Run the sweep of ``args``; the exit code."""
    from mpi4py import MPI

    from model.studies.sweep import parse_sets, sweep

    try:
        if MPI.COMM_WORLD.size > 1:
            raise ConfigError(f"sweep: runs on one rank and starts its runs as child processes; start it "
                              f"without mpirun (it has {MPI.COMM_WORLD.size} ranks)")
        frame = sweep(args.config, parse_sets(args.sets), jobs=args.jobs, mode=args.mode, out=args.out)
    except ConfigError as err:
        if MPI.COMM_WORLD.rank == 0:
            print(f"error: {err}", file=sys.stderr)
        return 2
    return 1 if frame.attrs.get("failed") else 0
