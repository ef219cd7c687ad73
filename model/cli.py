"""Command line: ``python -m model run CONFIG [--out DIR]``, ``python -m model verify emit|check|seeds`` and
``python -m model schema [--out FILE] [--markdown FILE]``.

Exit codes: run: 0 success, 1 solve failed (SNES reason printed, results kept), 2 bad input.
verify check: 0 all quantities within tolerance, 1 otherwise, 2 bad input. verify seeds: 0 when
the table was produced (a disagreement is a finding, not a failure).
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
    verify = sub.add_parser("verify", help="reference values of psi, P, A and checks of hand-derived formulas")
    vsub = verify.add_subparsers(dest="verify_command", required=True)
    emit_parser = vsub.add_parser("emit", help="write reference psi, P, A computed through the UFL forms")
    emit_parser.add_argument("--material", required=True)
    emit_parser.add_argument("--param", action="append", default=[], metavar="KEY=VALUE")
    emit_parser.add_argument("--samples", type=int, required=True)
    emit_parser.add_argument("--seed", type=int, required=True)
    emit_parser.add_argument("--out", type=Path, required=True)
    emit_parser.add_argument("--inverted", action="store_true", help="also emit inverted F (det F < 0)")
    check_parser = vsub.add_parser("check", help="compare a file's psi, P and/or A with the reference")
    check_parser.add_argument("file", type=Path)
    check_parser.add_argument("--rtol", type=float, default=1e-8)
    seeds_parser = vsub.add_parser("seeds", help="check the formulas printed in the seed documents")
    seeds_parser.add_argument("--json", type=Path, default=None)
    schema_parser = sub.add_parser("schema", help="the JSON Schema of the configuration file and its key reference, "
                                   "generated from model.config")
    schema_parser.add_argument("--out", type=Path, default=None,
                               help="write the JSON Schema here (docs/config.schema.json; default: standard output "
                                    "unless --markdown is given)")
    schema_parser.add_argument("--markdown", type=Path, default=None,
                               help="write the Markdown reference of every key here (docs/config.md)")
    args = parser.parse_args(argv)
    if args.command == "schema":
        return _schema(args)
    _configure_logging()
    if args.command == "verify":
        return _verify(args)
    from model.config import load
    from model.errors import ConfigError, SolveFailed
    from model.pipeline import run

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


def _schema(args: argparse.Namespace) -> int:
    from model.config.reference import render_markdown, schema_text

    if args.out is not None:
        args.out.write_text(schema_text())
    elif args.markdown is None:
        sys.stdout.write(schema_text())
    if args.markdown is not None:
        args.markdown.write_text(render_markdown())
    return 0


def _parse_params(items: list[str]) -> dict[str, float]:
    params = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise ValueError(f"--param {item!r}: write KEY=VALUE")
        try:
            params[key] = float(value)
        except ValueError:
            raise ValueError(f"--param {key}: {value!r} is not a number") from None
    return params


def _verify(args: argparse.Namespace) -> int:
    import forms
    from model import verify

    if args.verify_command == "seeds":
        from model.verify.seeds import run_seeds

        return run_seeds(args.json)
    try:
        if args.verify_command == "emit":
            data = verify.emit(args.material, _parse_params(args.param), args.samples, args.seed, args.out,
                               args.inverted)
            print(f"wrote {args.out}: {len(data['F'])} samples of {args.material} ({data['params_json']})")
            return 0
        rows = verify.check(args.file, args.rtol)
    except (ValueError, OSError, forms.ParameterError) as err:
        _error(str(err))
        return 2
    print(verify.format_rows(rows))
    return 0 if all(r.ok for r in rows) else 1
