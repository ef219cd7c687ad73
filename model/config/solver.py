"""[solver]: the nonlinear method, Newton's tangent, PETSc options and Projective Dynamics' stopping rule."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import AfterValidator, Discriminator, Tag, WithJsonSchema

from model.config.base import (
    By,
    Flag,
    Integer,
    NonNegative,
    Number,
    Text,
    Variant,
    Wording,
    count,
    fail,
    interval,
    key,
    kinds,
)

SOLVER_METHODS = ("newton", "projective_dynamics")
TANGENTS = ("exact", "projected")
#: Newton's linear-solver presets (model.solvers.linear)
LINEAR_PRESETS = ("direct", "iterative", "auto")


def _scalar_kind(value: Any) -> str | None:
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, int):
        return "integer"
    if isinstance(value, float):
        return "number"
    if isinstance(value, str):
        return "string"
    return None


#: the value of a PETSc option: a string, number or boolean
OptionValue = Annotated[
    Annotated[Text, Tag("string")] | Annotated[Integer, Tag("integer")] | Annotated[Number, Tag("number")]
    | Annotated[Flag, Tag("boolean")],
    Discriminator(_scalar_kind),
    WithJsonSchema({"type": ["string", "number", "boolean"]}),
    Wording(union_tag_not_found="must be a string, number or boolean, got {input!r}"),
]


def _no_dash(options: dict[str, Any]) -> dict[str, Any]:
    for name in options:
        if name.startswith("-"):
            fail("write the option without its leading '-'", name)
    return options


PetscOptions = Annotated[dict[str, OptionValue], AfterValidator(_no_dash)]


class SolverConfig(Variant):
    """[solver]: ``method`` "newton" (PETSc SNES, with the exact or the projected tangent) or
    "projective_dynamics" (local/global iterations; shape-target laws with kappa = 0 only)."""

    kind_key = "method"

    method: str = key("the nonlinear solver", default="newton")
    tangent: Literal["exact", "projected"] = key(
        "Newton's tangent: the exact second derivative of the energy, or its per-quadrature-point projection onto "
        "positive semi-definite tensors (displacement formulation only)", default="exact")
    linear: Literal["direct", "iterative", "auto"] = key(
        "Newton's linear solver: \"direct\" (MUMPS LU), \"iterative\" (displacement formulation: CG + GAMG with the "
        "rigid-body near null space, GMRES + GAMG where the tangent is not symmetric (a follower pressure); mixed: "
        "GMRES with a Schur-complement fieldsplit (the full block factorisation), "
        "AMG on the displacement block (rigid-body modes and the dilation as near null space) and the "
        "(1/mu + 1/kappa)-weighted pressure mass matrix for the Schur complement) or \"auto\" (direct below "
        "50000 unknowns, iterative from there); petsc_options override any of its options",
        default="auto")
    matrix: Literal["auto", "aij", "nest"] = key(
        "Newton's matrix: \"nest\" (one PETSc matrix per block of the mixed formulation's fields u and p, taken as "
        "they are by the fieldsplit preconditioner: the Jacobian held once instead of twice), \"aij\" (the whole "
        "Jacobian assembled into one matrix, which every preconditioner takes) or \"auto\" (nest with the "
        "mixed formulation's fieldsplit preconditioner and no contact or sliding between bodies, aij otherwise)",
        default="auto")
    allow_rigid_modes: Flag = key(
        "skip the support check before the solve, which refuses a run where a piece of the mesh can move rigidly "
        "(a translation or rotation that no displacement condition, bone or contact holds; docs/configuration.md)",
        default=False)
    petsc_options: PetscOptions = key(
        "PETSc options without their leading '-', e.g. { snes_rtol = 1e-8, ksp_type = \"preonly\" }",
        default_factory=dict)
    pd_max_iterations: count(1, 1_000_000) = key(
        "Projective Dynamics: most global steps per load step", default=1000)
    pd_rtol: Annotated[Number, *interval(0, 1, "()")] = key(
        "Projective Dynamics: stop when the residual norm falls below pd_rtol times its value at the start of the "
        "load step", "dimensionless", default=1e-8)
    pd_atol: NonNegative = key("Projective Dynamics: or when the residual norm falls below pd_atol",
                               "N (force)", default=1e-12)


class NewtonSettings(SolverConfig):
    """[solver] with method = "newton" (the default): PETSc SNES with line search."""

    keys = ("method", "tangent", "linear", "matrix", "allow_rigid_modes", "petsc_options")
    method: Literal["newton"] = key("the nonlinear solver: PETSc SNES Newton", default="newton")


class ProjectiveDynamicsSettings(SolverConfig):
    """[solver] with method = "projective_dynamics": a local polar step per quadrature point and a global
    linear solve with a constant matrix, until the residual is small."""

    keys = ("method", "allow_rigid_modes", "petsc_options", "pd_max_iterations", "pd_rtol", "pd_atol")
    method: Literal["projective_dynamics"] = key("the nonlinear solver: Projective Dynamics iterations")


Solver = kinds(NewtonSettings, ProjectiveDynamicsSettings, by=By("method", "newton"))

__all__ = ["LINEAR_PRESETS", "SOLVER_METHODS", "TANGENTS", "NewtonSettings", "PetscOptions",
           "ProjectiveDynamicsSettings", "Solver", "SolverConfig"]
