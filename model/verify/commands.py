"""The ``verify`` command line: ``python -m model verify emit|check|seeds`` (and ``element`` once
model/verify/element.py exists). Exit codes: 0 ok, 1 out of tolerance, 2 bad input (one line "error: ...").

The help texts list the laws with their parameters and defaults (forms.registry), the tangent
layouts (model.verify.layouts) and the file formats (model.verify.files).
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import sys
from pathlib import Path
from typing import Any

from mpi4py import MPI

from model.verify import files, layouts

SUBCOMMANDS = ("emit", "check", "seeds", "element")


def laws_help(header: str = "laws (--material NAME; or --energy FILE.py:FUNCTION, a UFL energy of your own):") -> str:
    """One line per built-in law after ``header``: name, fields, parameters with their defaults (required ones
    bare)."""
    import forms
    from forms.metadata import format_number

    lines = [header]
    for entry in forms.REGISTRY.values():
        in_sets = {name for group in entry.parameter_sets for name in group}
        params = [f"{p.name}={format_number(p.default)}" if p.default is not None else f"{p.name} (required)"
                  for p in entry.parameters if p.name not in in_sets]
        if entry.parameter_sets:
            sets = " or ".join("(" + ", ".join(s) + ")" for s in entry.parameter_sets)
            params.append(f"{sets} required" + (f" {entry.sets_condition}" if entry.sets_condition else ""))
        fields = f"; fields {', '.join(entry.fields)}" if entry.fields else ""
        lines.append(f"  {entry.name}: {', '.join(params)}{fields}")
    return "\n".join(lines)


def formats_help() -> str:
    """The tangent layouts, stress measures and file formats, for the help texts."""
    return ("tangent layouts (--layout; check: the file's own 'layout' when it has one):\n" + layouts.layouts_help()
            + "\nfile formats (chosen by the path: .npz, a directory of .npy files, CSV, JSON):\n"
            + files.formats_help())


def epilog() -> str:
    return laws_help() + "\n" + formats_help() + "\nexit codes: 0 ok, 1 out of tolerance, 2 bad input"


def parse_value(text: str) -> float | str:
    """A --param value: a number (float; "inf" included) or else the word itself (isotropic=stvk)."""
    try:
        return float(text)
    except ValueError:
        return text


def parse_params(items: list[str]) -> dict[str, Any]:
    """{key: value} from KEY=VALUE items (ValueError naming the item otherwise)."""
    params: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        key, value = key.strip(), value.strip()
        if not sep or not key or not value:
            raise ValueError(f"--param {item!r}: write KEY=VALUE")
        if key in params:
            raise ValueError(f"--param {key}: given twice")
        parsed = parse_value(value)
        if isinstance(parsed, float) and math.isnan(parsed):
            raise ValueError(f"--param {key}: nan is not a value")
        params[key] = parsed
    return params


def _law_options(parser: argparse.ArgumentParser, required: bool) -> None:
    group = parser.add_mutually_exclusive_group(required=required)
    group.add_argument("--material", help="a built-in law (listed below)")
    group.add_argument("--energy", metavar="FILE.py:FUNCTION", help="a UFL energy of your own (forms/user_law.py)")
    parser.add_argument("--param", action="append", default=[], metavar="KEY=VALUE",
                        help="a parameter: a number (inf allowed) or a word (isotropic=stvk)")
    parser.add_argument("--layout", choices=layouts.TANGENT_LAYOUTS, default=None,
                        help="the tangent's layout (default: the file's, else ijkl)")


def add_parser(sub: Any) -> argparse.ArgumentParser:
    """The ``verify`` parser and its subcommands, added to the top-level subparsers ``sub``."""
    from model.helptext import Formatter as formatter
    verify = sub.add_parser("verify", help="reference values of psi, P, A and checks of hand-derived formulas",
                            description="Reference values of psi, P = dpsi/dF and A = dP/dF through the UFL forms, "
                                        "and checks of your own.",
                            epilog="examples:\n  softtissue verify emit --material neo_hookean --param mu=1 --param "
                                   "lmbda=10 --out ref.npz\n  softtissue verify check mine.npz\n  softtissue verify "
                                   "element my_tet10.json\n\n" + epilog(), formatter_class=formatter)
    vsub = verify.add_subparsers(dest="verify_command", required=True)
    emit_parser = vsub.add_parser("emit", help="write reference psi, P, A computed through the UFL forms",
                                  description="Writes reference values of psi, P and A at sampled deformation "
                                              "gradients (a quarter of them inverted where the law allows), for "
                                              "your own code to evaluate at the same F and fields.",
                                  epilog="examples:\n  softtissue verify emit --material neo_hookean --param mu=1 "
                                         "--param lmbda=10 --out ref.npz\n  softtissue verify emit --energy "
                                         "my_law.py:psi --param C=2 --samples 5000 --out ref.csv\n\n" + epilog(),
                                  formatter_class=formatter)
    _law_options(emit_parser, required=True)
    emit_parser.add_argument("--samples", type=int, default=1000, help="number of deformation gradients")
    emit_parser.add_argument("--seed", type=int, default=0, help="random seed of the samples (the same seed, the same "
                                                                 "samples)")
    emit_parser.add_argument("--out", type=Path, required=True,
                             help="the file written: this path when it is a directory (.npy files) or ends in "
                                  ".npz, .csv or .json (the format), else this path with .npz appended (printed)")
    emit_parser.add_argument("--inverted", action=argparse.BooleanOptionalAction, default=None,
                             help="a quarter of the samples with det F < 0 (default: drawn unless the law's reference "
                                  "is not finite there, e.g. ln J; --no-inverted: never)")
    emit_parser.add_argument("--field", action="append", default=[], metavar="NAME=VALUE",
                             help="one field value for every sample: S=identity, a0=1,0,0, alpha=0.5")
    emit_parser.add_argument("--at-breakpoints", action="store_true",
                             help="keep samples where the tangent is undefined (fibre stretch 1, ...)")
    check_parser = vsub.add_parser("check", help="compare a file's psi, P and/or A with the reference",
                                   description="Compares your psi, P and/or A in FILE (with its F and fields) with "
                                               "the reference, says where they differ and names the cause when one "
                                               "explains every failing sample.",
                                   epilog="examples:\n  softtissue verify check mine.npz\n  softtissue verify check "
                                          "mine.csv --material neo_hookean --param mu=1 --param lmbda=10 --rtol 1e-4"
                                          "\n\n" + epilog(), formatter_class=formatter)
    check_parser.add_argument("file", type=Path)
    check_parser.add_argument("--rtol", type=float, default=1e-8,
                              help="relative tolerance per sample: |yours - ref| <= rtol max(|ref|, M) + atol, M the "
                                   "law's largest |A_ijkl| at F = I (default 1e-8; single precision: 1e-4)")
    check_parser.add_argument("--atol", type=float, default=0.0,
                              help="absolute tolerance per sample, in the quantity's unit (default 0)")
    _law_options(check_parser, required=False)
    check_parser.add_argument("--projected", action="store_true",
                              help="your tangent is PSD-projected (9x9 eigenvalues clamped at 0): compare it "
                                   "with the projection of the reference")
    seeds_parser = vsub.add_parser("seeds", help="check the formulas printed in the seed documents",
                                   description="Evaluates the stress and tangent formulas as printed in three source "
                                               "documents (docs/verify.md) against the reference, and their "
                                               "corrections.",
                                   epilog="examples:\n  softtissue verify seeds\n  softtissue verify seeds --json "
                                          "seeds.json\n\nexit code: 0 when the table was produced (a disagreement is "
                                          "a finding)", formatter_class=formatter)
    seeds_parser.add_argument("--json", type=Path, default=None, help="also write the table as JSON here")
    if importlib.util.find_spec("model.verify.element") is not None:  # `verify element FILE`
        from model.verify import element

        element.add_parser(vsub)
    return verify


def _error(message: str) -> None:
    if MPI.COMM_WORLD.rank == 0:
        print(f"error: {message}", file=sys.stderr)


def _print(text: str) -> None:
    if MPI.COMM_WORLD.rank == 0:
        print(text)


def main(args: argparse.Namespace) -> int:
    """Run ``verify`` subcommand ``args.verify_command``; the exit code."""
    import forms
    from model import verify

    if args.verify_command == "seeds":
        from model.verify.seeds import run_seeds

        return run_seeds(args.json)
    if args.verify_command == "element":
        from model.verify import element

        return int(element.main(args))
    try:
        material = args.material or args.energy
        params = parse_params(args.param)
        if args.verify_command == "emit":
            from model.verify.emitter import summary_text
            from model.verify.samples import parse_field

            fields = dict(parse_field(material, item) for item in args.field)
            if len(fields) != len(args.field):
                raise ValueError("--field: a field is given twice")
            data = verify.emit(material, params, args.samples, args.seed, args.out, args.inverted, fields=fields,
                               include_undefined=args.at_breakpoints, layout=args.layout or "ijkl")
            _print(summary_text(data))
            return 0
        report = verify.check_file(args.file, rtol=args.rtol, material=material, params=params, layout=args.layout,
                                   projected=args.projected, atol=args.atol)
    except (ValueError, OSError, forms.ParameterError) as err:
        _error(str(err).splitlines()[0] if str(err) else type(err).__name__)
        return 2
    _print(str(report))
    return 0 if report.ok else 1
