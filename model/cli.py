"""Command line: ``softtissue run CONFIG [--out DIR] [--set KEY=VALUE ...] [--restart DIR]`` (a CONFIG with a
[membrane] table is a membrane run: model.config.membrane, model.experiments.membrane_run),
``softtissue verify emit|check|seeds|element``, ``softtissue sweep CONFIG --set KEY=V1,V2 --out DIR``
(model.studies.commands), ``softtissue converge CONFIG --refine KEY=v1,v2,v3 --qoi ...``
(model.studies.convergence_cli), ``softtissue calibrate CONFIG --data FILE --fit KEYS``
(model.studies.calibration_cli), ``softtissue schema [--out FILE] [--markdown FILE] [--membrane-out FILE]`` and
``softtissue --version``. ``python -m model ...`` is the same (model/__main__.py).

Exit codes: run: 0 success, 1 solve failed (SNES reason printed, results kept), 2 bad input, 130 / 143
interrupted by SIGINT / SIGTERM (results kept, summary.json "interrupted"; continue with --restart DIR).
verify check: 0 all quantities within tolerance, 1 otherwise, 2 bad input. verify seeds: 0 when
the table was produced (a disagreement is a finding, not a failure). sweep: 0 every run completed, 1 some
failed (the table is written), 2 bad input. converge: 0 written, 1 fewer than 3 meshes ran, 2 bad input.
calibrate: 0 written, 1 a forward solve failed, 2 bad input.
Any command stopped by SIGINT / SIGTERM before its work began: 130 / 143 and one line (model.signals). Any
command that meets a bug of this program: 3 and one line naming the file that holds the traceback
(SOFTTISSUE_TRACEBACK=1 shows it instead). A write the system refuses (a full disk): 1 and one line naming the path.

Start-up order, for a quick answer to a bad input: the signal handlers first (model.signals: the imports take
seconds); only the parser of the command given (verify's imports forms, UFL and mpi4py); for ``run`` the
configuration is read, overridden and checked before mpi4py or dolfinx load (model.pipeline is imported after
it), the MPI rank meanwhile taken from the launcher's environment.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import textwrap
from pathlib import Path
from typing import Any

from model import signals

#: the project's distribution (pyproject.toml [project] name): --version
DISTRIBUTION = "softtissue-reference"

DESCRIPTION = textwrap.fill(
    "The soft-tissue reference model: run a configuration (run), check your own stress and tangent formulas against "
    "the reference (verify), sweep parameters (sweep), study mesh convergence (converge), fit law parameters to "
    "measurements (calibrate), write the configuration schema (schema). Each command has its own --help.", 100)
EPILOG = """examples:
  softtissue run examples/uniaxial.toml --out results/uniaxial
  softtissue verify emit --material neo_hookean --param mu=1 --param lmbda=10 --out ref.npz
  softtissue calibrate examples/calibration/specimen.toml --data examples/calibration/measured.csv --fit material.0.E

exit codes: 0 done, 1 a solve failed or a check is out of tolerance, 2 bad input (one line naming the key),
3 a bug of this program (the traceback's file is named), 130 / 143 stopped by SIGINT / SIGTERM"""
RUN_DESCRIPTION = textwrap.fill(
    "Runs a configuration: builds the mesh, the materials and the loads, checks them (one line naming the key on "
    "bad input, before any solve), solves with Newton and load stepping, and writes summary.json, XDMF, VTU and a "
    "PNG to the output folder after every converged step. A file with a [membrane] table is a membrane run.", 100)
RUN_EPILOG = """examples:
  softtissue run examples/uniaxial.toml --out results/uniaxial
  softtissue run examples/uniaxial.toml --set material.0.E=2e5 --set loading.steps=20
  softtissue run examples/isometric.toml --restart results/demo
  mpirun -n 2 softtissue run examples/cook.toml --out results/cook      (on 2 MPI ranks: the same answer)

exit codes: 0 completed, 1 the solve failed (the message says why and what can help; the converged steps are
kept), 2 bad input (one line naming the key), 3 a bug of this program, 130 / 143 interrupted by SIGINT /
SIGTERM (the completed steps are kept; continue with --restart DIR)"""

#: commands whose parsers are cheap to build; the others' import forms, UFL or mpi4py (``_parser``)
_CHEAP = ("run", "schema")


def _rank() -> int:
    """This process's MPI rank: mpi4py's once MPI is up, before that the launcher's (Open MPI, PMIx, MPICH / PMI)
    environment, so that a bad configuration is reported once without initialising MPI; 0 without a launcher."""
    mpi = sys.modules.get("mpi4py.MPI")
    if mpi is not None and mpi.Is_initialized():
        return mpi.COMM_WORLD.rank
    for name in ("OMPI_COMM_WORLD_RANK", "PMIX_RANK", "PMI_RANK"):
        if os.environ.get(name, "").isdigit():
            return int(os.environ[name])
    return 0


def version() -> str:
    """The installed distribution's version (importlib.metadata); from pyproject.toml beside the package when it is
    not installed (a checkout on PYTHONPATH)."""
    from importlib import metadata

    try:
        return metadata.version(DISTRIBUTION)
    except metadata.PackageNotFoundError:
        import tomllib

        pyproject = Path(__file__).resolve().parents[1] / "pyproject.toml"
        try:
            return str(tomllib.loads(pyproject.read_text())["project"]["version"])
        except (OSError, ValueError, KeyError):
            return "unknown"


class _Version(argparse.Action):
    """``--version``: the version is looked up only when asked for."""

    def __init__(self, option_strings: list[str], dest: str = argparse.SUPPRESS, **kwargs: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS,
                         help="print the version and exit")

    def __call__(self, parser: argparse.ArgumentParser, namespace: Any, values: Any, option: Any = None) -> None:
        print(f"{parser.prog} {version()} ({DISTRIBUTION})")
        parser.exit()


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
    logger.setLevel(logging.INFO if _rank() == 0 else logging.ERROR)
    logger.propagate = False


def _error(message: str) -> None:
    if _rank() == 0:
        print(f"error: {message}", file=sys.stderr)


def _command(argv: list[str]) -> str | None:
    """The command word of ``argv`` (its first word that is not an option), None without one."""
    return next((a for a in argv if not a.startswith("-")), None)


def _parser(prog: str, command: str | None) -> argparse.ArgumentParser:
    """The top-level parser. For ``run`` and ``schema`` (and a bare ``--version``) only their own parsers: verify's,
    sweep's and converge's import forms, UFL or mpi4py, a second and more that a bad configuration need not wait."""
    from model.helptext import Formatter

    parser = argparse.ArgumentParser(prog=prog, description=DESCRIPTION, epilog=EPILOG, formatter_class=Formatter)
    parser.add_argument("--version", action=_Version)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    run_parser = sub.add_parser("run", help="run a TOML configuration", description=RUN_DESCRIPTION,
                                epilog=RUN_EPILOG, formatter_class=Formatter)
    run_parser.add_argument("config", type=Path, help="the configuration file (TOML; docs/configuration.md)")
    run_parser.add_argument("--out", type=Path, default=None, help="output directory (overrides output.dir)")
    run_parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="overrides",
                            help="override a key of the file: dotted path, value as TOML (material.0.E=2e5, "
                                 "loading.steps=20, 'boundary.0.value=[0.1]'); repeatable")
    run_parser.add_argument("--restart", type=Path, default=None, metavar="DIR",
                            help="continue the interrupted run in DIR from its last converged step (appends there)")
    if command not in _CHEAP:
        from model.verify.commands import add_parser as add_verify_parser

        add_verify_parser(sub)
        from model.studies.commands import add_parser as add_sweep_parser

        add_sweep_parser(sub)
        from model.studies.convergence_cli import add_parser as add_converge_parser

        add_converge_parser(sub)
        from model.studies.calibration_cli import add_parser as add_calibrate_parser

        add_calibrate_parser(sub)
    schema_parser = sub.add_parser("schema", help="the JSON Schema of the configuration file and its key reference, "
                                   "generated from model.config", formatter_class=Formatter,
                                   description="Writes the JSON Schema of a configuration file (for editors and "
                                               "validators) and the Markdown reference of every key.",
                                   epilog="examples:\n  softtissue schema > config.schema.json\n  softtissue schema "
                                          "--out docs/config.schema.json --markdown docs/config.md "
                                          "--membrane-out docs/membrane.schema.json")
    schema_parser.add_argument("--out", type=Path, default=None,
                               help="write the JSON Schema here (docs/config.schema.json; default: standard output "
                                    "unless --markdown is given)")
    schema_parser.add_argument("--markdown", type=Path, default=None,
                               help="write the Markdown reference of every key here (docs/config.md)")
    schema_parser.add_argument("--membrane-out", type=Path, default=None,
                               help="write the JSON Schema of a membrane run's file here (docs/membrane.schema.json)")
    return parser


def main(argv: list[str] | None = None, prog: str = "softtissue") -> int:
    """The command line (the ``softtissue`` console script; ``python -m model``). Installs the signal handlers
    first (model.signals) and puts the caller's back on return."""
    previous = signals.install()
    try:
        return _main(sys.argv[1:] if argv is None else list(argv), prog)
    except signals.StoppedEarly as err:  # before a run's steps: imports, configuration (model.signals)
        _error(str(err))
        return 128 + err.signum
    except Exception as err:  # a bug: one line on the screen, the traceback in a file (no input should get here)
        if os.environ.get("SOFTTISSUE_TRACEBACK"):
            raise
        _error(f"internal error (a bug of this program: please report it with {_save_traceback()}): "
               f"{type(err).__name__}: {' '.join(str(err).split())[:300]}")
        return 3
    finally:
        signals.restore(previous)


def _save_traceback() -> str:
    """Write the traceback being handled to a file of its own in the temporary folder; its path."""
    import tempfile
    import traceback

    with tempfile.NamedTemporaryFile("w", prefix="softtissue-traceback-", suffix=".txt", delete=False) as f:
        traceback.print_exc(file=f)
    return f.name


def _main(argv: list[str], prog: str) -> int:
    for i, arg in enumerate(argv, start=1):  # bytes the locale could not decode (dolfinx's logging chokes on them)
        try:
            arg.encode("utf-8")
        except UnicodeEncodeError:
            _error(f"argument {i} ({arg.encode('utf-8', 'backslashreplace').decode()!r}) is not UTF-8 text")
            return 2
    command = _command(argv)
    args = _parser(prog, command if command is not None or "--version" not in argv else "run").parse_args(argv)
    if args.command == "schema":
        return _schema(args)
    _configure_logging()
    if getattr(args, "handler", None) is not None:  # subcommands with a handler of their own (converge)
        return args.handler(args)
    if args.command == "verify":
        return _verify(args)
    if args.command == "sweep":
        from model.studies.commands import main as sweep_main

        return sweep_main(args)
    from model.config import load, read
    from model.config.membrane import is_membrane
    from model.config.overrides import parse_assignments
    from model.errors import ConfigError, SolveFailed
    from model.signals import Interrupted

    try:
        if args.restart is not None and args.out is not None and args.out.resolve() != args.restart.resolve():
            raise ConfigError(f"--restart {args.restart} and --out {args.out}: a restart writes into the folder "
                              "it continues; give one of them")
        overrides = parse_assignments(args.overrides)
        if is_membrane(read(args.config)):  # a [membrane] table: a membrane run (model.config.membrane)
            return _membrane(args, overrides)
        config = load(args.config, overrides)
        from model.pipeline import run  # dolfinx, PETSc, MPI: only for a configuration that is checked

        if args.restart is not None:
            summary = run(config, args.restart, restart=True)
        else:
            summary = run(config, args.out)
    except Interrupted as err:
        _error(str(err))
        return 128 + err.signum
    except ConfigError as err:
        _error(str(err))
        return 2
    except SolveFailed as err:
        _error(str(err))
        return 1
    if _rank() == 0:
        out = args.restart if args.restart is not None else args.out if args.out is not None else config.output.dir
        print(run_summary(summary, Path(out)))
    return 0


def _vector(values: list[float], unit: str) -> str:
    return "(" + ", ".join(f"{v:.4g}" for v in values) + ")" + (f" {unit}" if unit else "")


def run_summary(summary: dict, out: Path) -> str:
    """The lines a run ends with: status, steps (and cut-backs), dofs and time; at the last converged step each
    probe's displacement and each boundary's reaction with their units, the volume change of each region; the
    warnings' count; where the results are."""
    steps = summary.get("steps", [])
    converged = [s for s in steps if s.get("converged")]
    units = summary.get("units", {})
    length, force = units.get("length", ""), units.get("force", "")
    failed = len(steps) - len(converged)
    lines = [f"done: {len(converged)} steps ({summary.get('status', '?')}"
             + (f", {failed} cut back" if failed else "") + f"), {summary.get('dofs', 0):,} dofs, "
             f"{summary.get('wall_time_s', 0.0):.1f} s"]
    if converged:
        last = converged[-1]
        what = f"t = {last['time']:.4g}" if "time" in last else f"load factor {last['load_factor']:.4g}"
        lines.append(f"at {what}:")
        for name, u in last.get("probes", {}).items():
            lines.append(f"  probe {name}: u = {_vector(u, length)}")
        for name, f in last.get("reactions", {}).items():
            lines.append(f"  reaction of {name}: F = {_vector(f, force)}")
        for name, f in last.get("reactions_shared", {}).items():
            lines.append(f"    shared by {name} (in both reactions above): F = {_vector(f, force)}")
        rest = summary.get("region_volumes", {})
        changes = [f"{name} {100 * (v / rest[name] - 1):+.3g} %" for name, v in last.get("volumes", {}).items()
                   if rest.get(name)]
        if changes:
            lines.append("  volume change: " + ", ".join(changes))
    warnings = summary.get("warnings", [])
    if warnings:
        lines.append(f"{len(warnings)} warning{'s' if len(warnings) > 1 else ''} (printed above, and in summary.json)")
    lines.append(f"results in {out}: summary.json" + (", results.xdmf" if "results.xdmf" in summary.get("files", [])
                                                      else "") + (f", {summary['png']}" if summary.get("png") else ""))
    return "\n".join(lines)


def _membrane(args: argparse.Namespace, overrides: dict) -> int:
    """``run`` of a membrane document (model.config.membrane; model.experiments.membrane_run). Called inside
    ``run``'s error handling: ConfigError, SolveFailed and Interrupted give the same exit codes as a solid run."""
    from model.config.membrane import load_membrane
    from model.errors import ConfigError
    from model.experiments.membrane_run import run_membrane

    if args.restart is not None:
        raise ConfigError("--restart: a membrane run has no restart (run it again)")
    config = load_membrane(args.config, overrides)
    summary = run_membrane(config, args.out)
    if _rank() == 0:
        last = summary["steps"][-1]
        print(f"done: membrane, {len(summary['steps'])} pressure steps, {summary['surface']['triangles']} "
              f"triangles, {summary['wall_time_s']:.1f} s; p {last['pressure']:.6g}, V {last['volume']:.6g}, "
              f"contact fraction {last['contact_fraction']:.4g}")
        if "muscle" in summary:
            muscle = summary["muscle"]
            written = Path(args.out if args.out is not None else config.output.dir) / muscle["config"]
            print(f"muscle: {muscle['tetrahedra']} tetrahedra, volume {muscle['volume']:.6g}; run it with: "
                  f"python -m model run {written}")
    return 0


def _schema(args: argparse.Namespace) -> int:
    from model.config.reference import render_markdown, schema_text

    if args.out is not None:
        args.out.write_text(schema_text())
    elif args.markdown is None and args.membrane_out is None:
        sys.stdout.write(schema_text())
    if args.markdown is not None:
        args.markdown.write_text(render_markdown())
    if args.membrane_out is not None:
        from model.config.reference import membrane_schema_text

        args.membrane_out.write_text(membrane_schema_text())
    return 0


def _verify(args: argparse.Namespace) -> int:
    from model.verify.commands import main as verify_main

    return verify_main(args)
