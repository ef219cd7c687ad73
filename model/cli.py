"""Command line: ``python -m model run CONFIG [--out DIR]``.

Exit codes: 0 success, 1 solve failed (SNES reason printed, results kept), 2 bad input.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from mpi4py import MPI


def _configure_logging() -> None:
    # The JIT (ffcx -> setuptools) lowers the root logger to INFO and would print its compiler
    # command lines; a root handler of our own that passes only warnings keeps the screen clean.
    quiet = logging.StreamHandler(sys.stderr)
    quiet.setLevel(logging.WARNING)
    logging.root.handlers[:] = [quiet]
    handler = logging.StreamHandler(sys.stdout)
    handler.setFormatter(logging.Formatter("%(message)s"))
    logger = logging.getLogger("model")
    logger.handlers[:] = [handler]
    logger.setLevel(logging.INFO if MPI.COMM_WORLD.rank == 0 else logging.ERROR)
    logger.propagate = False


def _error(message: str) -> None:
    if MPI.COMM_WORLD.rank == 0:
        print(f"error: {message}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m model", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    run_parser = sub.add_parser("run", help="run a TOML configuration")
    run_parser.add_argument("config", type=Path)
    run_parser.add_argument("--out", type=Path, default=None, help="output directory (overrides output.dir)")
    args = parser.parse_args(argv)
    _configure_logging()
    from model.config import ConfigError, load
    from model.run import SolveFailed, run

    if args.command == "run":
        try:
            config = load(args.config)
            summary = run(config, args.out)
        except ConfigError as err:
            _error(str(err))
            return 2
        except SolveFailed as err:
            _error(str(err))
            return 1
        if MPI.COMM_WORLD.rank == 0:
            last = summary["steps"][-1]
            print(f"done: {len(summary['steps'])} steps, {summary['dofs']} dofs, {summary['wall_time_s']:.1f} s; "
                  f"probes {last.get('probes', {})}")
    return 0
