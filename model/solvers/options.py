"""The values of [solver] petsc_options, checked before anything is deleted or solved.

NewtonSolver refuses an option *name* PETSc does not read (model.solvers.newton); a bad *value* would pass
that check and fail only inside PETSc, after the earlier run's files were removed and the scale check ran,
with PETSc's error dump. ``check_option_values`` runs right after ``build`` in model.pipeline, on every rank
(the same answer everywhere: the probes are on COMM_SELF and deterministic), and raises the one-line
ConfigError ``solver.petsc_options.KEY: ...`` for the first bad value in the order the options are given.

An option is recognised by its last component, so that the prefixed options of sub-solvers
(``fieldsplit_u_ksp_type``, ``fieldsplit_p_pc_type``, ``mg_levels_ksp_max_it``, ``sub_pc_type``, ...) are
checked as ``ksp_type``, ``pc_type``, ``*_max_it``:

- type names, against what this PETSc build has registered (probed on throwaway objects on COMM_SELF, with
  PETSc's error printing switched off: PETSc.Sys.pushErrorHandler("ignore"), popErrorHandler; both exist in
  petsc4py 3.18 and 3.22): ``ksp_type`` (KSP.setType), ``pc_type`` (PC.setType), ``snes_type`` (petsc4py's
  SNES.Type list: setType of a type that needs a DM, "aspin", crashes PETSc 3.18 on a bare SNES),
  ``snes_linesearch_type`` (SNES.setFromOptions with the name under a probe prefix: petsc4py 3.18 has no
  SNESLineSearch class), ``pc_factor_mat_solver_type`` (an LU, or the factorisation the same prefix's
  ``pc_type`` names, of a 2 x 2 matrix by that package: PC.setFactorSolverType, setUp);
- tolerances: ``*_rtol`` in [0, 1), ``*_atol`` and ``*_stol`` >= 0, ``*_divtol`` >= 1 (KSP stops as diverged
  when |r| > divtol |r_0|), ``*_max_it`` an integer >= 0; numbers, or strings PETSc reads as numbers
  ("1e-8"); not booleans. PETSc itself only refuses text (and 5.0 for an integer): it takes -1 and 1.5
  for a relative tolerance;
- booleans (BOOLEAN_OPTIONS): true or false, or what PETSc reads as one (1, 0, "yes", "no", "on", "off").

Any other option passes unchecked here (its name is NewtonSolver's check).
"""

from __future__ import annotations

import contextlib
import difflib
import functools
import logging
import math
import re
from collections.abc import Iterator, Mapping

from petsc4py import PETSc

from model.errors import ConfigError

log = logging.getLogger(__name__)

Value = str | int | float | bool

#: the prefix of the probes' options (deleted again after each probe)
_PROBE = "model_options_probe_"
#: factorisations a pc_type can name (the factor package's probe factorises the same way)
FACTOR_PC_TYPES = ("lu", "cholesky", "ilu", "icc")
#: packages the factor probe tries to list the ones this PETSc has
FACTOR_PACKAGES = ("mumps", "superlu_dist", "superlu", "umfpack", "klu", "cholmod", "petsc", "mkl_pardiso",
                   "mkl_cpardiso", "pastix", "strumpack", "lusol", "spqr")
#: the line searches a message lists (those of them this PETSc has: "none" is an alias of basic, "secant" the
#: later PETSc name of l2); a name not among them is still accepted when PETSc knows it (shell, ncglinear)
LINE_SEARCHES = ("basic", "bt", "l2", "secant", "cp", "nleqerr", "none")
#: options (last component) that take a boolean
BOOLEAN_OPTIONS = ("ksp_initial_guess_nonzero", "ksp_error_if_not_converged", "snes_error_if_not_converged",
                   "ksp_diagonal_scale", "ksp_diagonal_scale_fix", "snes_ksp_ew", "pc_gamg_reuse_interpolation",
                   "pc_gamg_use_parallel_coarse_grid_solver", "pc_factor_reuse_ordering", "pc_factor_reuse_fill",
                   "pc_fieldsplit_detect_saddle_point", "snes_lag_jacobian_persists",
                   "snes_lag_preconditioner_persists", "snes_converged_reason_view_cancel")
#: the strings PETSc reads as booleans (case-insensitive)
BOOLEAN_WORDS = ("true", "false", "yes", "no", "on", "off", "1", "0")
#: tolerance suffixes: (what, the range in words, the test)
TOLERANCES = {
    "rtol": ("a relative tolerance", "in [0, 1)", lambda v: 0 <= v < 1),
    "atol": ("an absolute tolerance", ">= 0", lambda v: v >= 0),
    "stol": ("a step tolerance", ">= 0", lambda v: v >= 0),
    "divtol": ("a divergence tolerance", ">= 1", lambda v: v >= 1),
    "max_it": ("an iteration count", "an integer >= 0", lambda v: v >= 0),
}
#: the type options by last component (longest first: "snes_linesearch_type" before "snes_type") and what they name
TYPE_OPTIONS = {
    "pc_factor_mat_solver_type": "factorisation package",
    "snes_linesearch_type": "line search",
    "snes_type": "SNES type",
    "ksp_type": "KSP type",
    "pc_type": "PC type",
}
#: a few names to show when a KSP, PC or SNES type is not known and no known name is close to it
_COMMON = {"ksp_type": ("preonly", "gmres", "fgmres", "cg", "minres", "bcgs"),
           "pc_type": ("lu", "cholesky", "gamg", "hypre", "fieldsplit", "jacobi", "sor", "none"),
           "snes_type": ("newtonls", "newtontr", "vinewtonrsls", "ksponly")}
_PETSC_CLASS = {"ksp_type": "KSP", "pc_type": "PC", "snes_type": "SNES"}


def component(key: str) -> str | None:
    """The option a (possibly prefixed) key sets, when it is one checked here: ``fieldsplit_u_ksp_type`` ->
    ``ksp_type``, ``mg_levels_ksp_max_it`` -> ``max_it``, ``snes_rtol`` -> ``rtol``; None for the others."""
    for name in (*TYPE_OPTIONS, *BOOLEAN_OPTIONS):
        if key == name or key.endswith("_" + name):
            return name
    for suffix in TOLERANCES:
        if key.endswith("_" + suffix):
            return suffix
    return None


@contextlib.contextmanager
def quiet_petsc() -> Iterator[None]:
    """PETSc errors raised as PETSc.Error without PETSc printing its error dump (the "ignore" handler)."""
    PETSc.Sys.pushErrorHandler("ignore")
    try:
        yield
    finally:
        PETSc.Sys.popErrorHandler()


def type_names(option: str) -> frozenset[str]:
    """The names petsc4py's Type class lists for ``option`` ("ksp_type", "pc_type", "snes_type"): the types of the
    PETSc release it was built for (external packages' among them, registered or not)."""
    kinds = getattr(PETSc, _PETSC_CLASS[option]).Type
    return frozenset(v for k, v in vars(kinds).items() if not k.startswith("_") and isinstance(v, str))


@functools.cache
def known_type(option: str, name: str) -> bool:
    """Whether this PETSc has ``name`` registered for ``option`` ("ksp_type", "pc_type", "snes_type",
    "snes_linesearch_type"): setType on a new KSP or PC on COMM_SELF, setFromOptions of a new SNES for the line
    search; a SNES type against petsc4py's list (type_names: SNES types are all PETSc's own, and setType of one
    that needs a DM, "aspin", crashes PETSc 3.18 on a bare SNES)."""
    if option == "snes_type":
        return name in type_names(option)
    with quiet_petsc():
        if option == "snes_linesearch_type":
            snes = PETSc.SNES().create(PETSc.COMM_SELF)
            db = PETSc.Options()
            db[f"{_PROBE}snes_linesearch_type"] = name
            try:
                snes.setOptionsPrefix(_PROBE)
                snes.setFromOptions()
                return True
            except PETSc.Error:
                return False
            finally:
                db.delValue(f"{_PROBE}snes_linesearch_type")
                with contextlib.suppress(PETSc.Error):
                    snes.destroy()
        made = getattr(PETSc, _PETSC_CLASS[option])().create(PETSc.COMM_SELF)
        try:
            made.setType(name)
            return True
        except PETSc.Error:
            return False
        finally:
            with contextlib.suppress(PETSc.Error):  # KSP pipelcg refuses destroy before its set-up (3.18)
                made.destroy()


@functools.cache
def known_factor_package(package: str, factorisation: str = "lu") -> bool:
    """Whether this PETSc factorises with ``package`` (``factorisation``: lu, cholesky, ilu, icc): a 2 x 2
    diagonal AIJ matrix on COMM_SELF through PC.setFactorSolverType and PC.setUp."""
    with quiet_petsc():
        matrix = PETSc.Mat().createAIJ([2, 2], nnz=1, comm=PETSc.COMM_SELF)
        pc = PETSc.PC().create(PETSc.COMM_SELF)
        try:
            matrix.setValue(0, 0, 2.0)
            matrix.setValue(1, 1, 3.0)
            matrix.assemble()
            pc.setType(factorisation)
            pc.setFactorSolverType(package)
            pc.setOperators(matrix)
            pc.setUp()
            return True
        except PETSc.Error:
            return False
        finally:
            with contextlib.suppress(PETSc.Error):
                pc.destroy()
                matrix.destroy()


def _check_type(key: str, option: str, value: Value, options: Mapping[str, Value]) -> None:
    what = TYPE_OPTIONS[option]
    name = value if isinstance(value, str) and not isinstance(value, bool) else None
    if option == "pc_factor_mat_solver_type":
        prefix = key[: -len(option)]
        pc_type = options.get(f"{prefix}pc_type", "lu")
        factorisation = pc_type if pc_type in FACTOR_PC_TYPES else "lu"
        if name is not None and known_factor_package(name, factorisation):
            return
        here = [p for p in FACTOR_PACKAGES if known_factor_package(p, factorisation)]
        raise ConfigError(f"solver.petsc_options.{key}: {value!r} is not a {what} this PETSc has for "
                          f"{factorisation} (it has: {', '.join(here)})")
    if name is not None and name.strip() and known_type(option, name):
        return
    if option == "snes_linesearch_type":
        accepted = [n for n in LINE_SEARCHES if known_type(option, n)]
        raise ConfigError(f"solver.petsc_options.{key}: {value!r} is not a {what} PETSc knows "
                          f"(one of: {', '.join(accepted)})")
    near = [n for n in difflib.get_close_matches(name, sorted(type_names(option)), n=3) if known_type(option, n)] \
        if name else []
    score = [difflib.SequenceMatcher(None, name, n).ratio() for n in near]
    close = sorted(n for n, r in zip(near, score) if r == max(score))[:2]  # the closest, and one that ties
    hint = f"did you mean {' or '.join(map(repr, close))}?" if close else \
        f"e.g. {', '.join(n for n in _COMMON[option] if known_type(option, n))}"
    raise ConfigError(f"solver.petsc_options.{key}: {value!r} is not a {what} PETSc knows ({hint})")


def _number(value: Value) -> float | None:
    """The number PETSc reads from ``value`` (a number, or a string that is one), or None (booleans, text)."""
    if isinstance(value, bool):
        return None
    if isinstance(value, int | float):
        return float(value)
    try:
        return float(value.strip())
    except ValueError:
        return None


def _check_tolerance(key: str, suffix: str, value: Value) -> None:
    what, bounds, test = TOLERANCES[suffix]
    number = _number(value)
    if suffix == "max_it":
        integral = isinstance(value, int) and not isinstance(value, bool) or \
            isinstance(value, str) and value.strip().lstrip("+-").isdigit()
        if not integral:
            raise ConfigError(f"solver.petsc_options.{key}: {value!r} is not an integer ({what}, {bounds})")
    elif number is None or math.isnan(number):
        raise ConfigError(f"solver.petsc_options.{key}: {value!r} is not a number ({what}, {bounds})")
    if not test(number):
        raise ConfigError(f"solver.petsc_options.{key}: {value!r} is out of range, must be {bounds} ({what})")


def _check_boolean(key: str, value: Value) -> None:
    if isinstance(value, bool) or (isinstance(value, int | str) and str(value).strip().lower() in BOOLEAN_WORDS):
        return
    raise ConfigError(f"solver.petsc_options.{key}: {value!r} is not a boolean (true or false)")


#: options whose value is a PETSc viewer ("-snes_monitor", "-ksp_view ascii:file.txt", ...)
_VIEWER = re.compile(r"(^|_)(monitor|view|converged_reason)(_true_residual|_short|_singular_value|_solution|_residual"
                     r"|_lg_residualnorm)?$")
#: the viewer types a viewer option's value may start with ("type:file:format:mode"; "" is standard output)
VIEWER_TYPES = ("", "ascii", "stdout", "stderr", "draw", "binary", "hdf5", "vtk", "socket", "saws", "glvis", "matlab",
                "adios")


def is_viewer(key: str) -> bool:
    """Whether option ``key`` takes a PETSc viewer as its value (a monitor, a view, a converged reason)."""
    return _VIEWER.search(key) is not None


def petsc_value(key: str, value: Value) -> Value | None:
    """The value to put in PETSc's options database for ``key``: a viewer option given as a boolean (TOML's
    ``snes_monitor = true``) is switched on by the empty value (PETSc reads "true" as a viewer's name and stops
    with "Unsupported viewer true") or left out (false, None); other values as they are."""
    if is_viewer(key) and isinstance(value, bool):
        return "" if value else None
    return value


def _check_viewer(key: str, value: Value) -> None:
    if isinstance(value, bool):
        return
    kind = str(value).split(":", 1)[0].strip().lower()
    if kind not in VIEWER_TYPES:
        raise ConfigError(f"solver.petsc_options.{key}: {value!r} is not a PETSc viewer (true, or \"TYPE[:FILE]\" "
                          f"with TYPE one of {', '.join(t for t in VIEWER_TYPES if t)})")


def check_option_values(options: Mapping[str, Value]) -> None:
    """ConfigError ``solver.petsc_options.KEY: ...`` (one line) for the first option whose value PETSc would
    refuse or that is out of range (module docstring); options not recognised by ``component`` pass."""
    for key, value in options.items():
        if is_viewer(key):
            _check_viewer(key, value)
            continue
        option = component(key)
        if option is None:
            continue
        if option in TYPE_OPTIONS:
            _check_type(key, option, value, options)
        elif option in TOLERANCES:
            _check_tolerance(key, option, value)
        else:
            _check_boolean(key, value)
    log.debug("PETSc option values checked: %d options", len(options))


__all__ = ["BOOLEAN_OPTIONS", "FACTOR_PACKAGES", "LINE_SEARCHES", "TOLERANCES", "TYPE_OPTIONS",
           "check_option_values", "component", "is_viewer", "known_factor_package", "known_type", "petsc_value",
           "quiet_petsc", "type_names"]
