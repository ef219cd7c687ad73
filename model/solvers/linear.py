"""Newton's linear solver: the presets of ``[solver] linear`` and the block preconditioner of Taylor-Hood.

Presets (flat PETSc options, under the solver's prefix; ``petsc_options`` override any of them):

    direct      preonly + LU (MUMPS)
    iterative   displacement formulation: CG + GAMG, the six rigid-body modes as near null space; GMRES + GAMG
                where Newton's matrix is not symmetric (ElasticityProblem.symmetry_reason: a follower pressure)
                mixed (Taylor-Hood P_k/P_(k-1)): GMRES, right preconditioned by a Schur-complement fieldsplit
    auto        direct below AUTO_DOFS unknowns (global), iterative from there

The Newton matrix of the mixed formulation, ordered [u, p],

    J = [ A   B^T ]     A = d2W/du2 (+ p d2g),  B = dg/du [q],  C = -int (1/kappa) p q dx  (0 when kappa = inf)
        [ B   C   ]

is factorised as J = [I 0; B A^-1 I] [A 0; 0 S] [I A^-1 B^T; 0 I], S = C - B A^-1 B^T (negative definite).
The preconditioner is that full factorisation (``pc_fieldsplit_schur_fact_type full``) with

    A^-1  ~ one V-cycle of algebraic multigrid on the displacement block (GAMG, near null space: the rigid-body
            modes of the u block and the dilation x - x_c; or hypre BoomerAMG with block size 3)
    S^-1  ~ Sp^-1,  Sp = - int (1/mu + 1/kappa) p q dx   (per material region; 1/kappa = 0 when kappa = inf),

the pressure mass matrix weighted by the shear and bulk compliances, spectrally equivalent to S
uniformly in the mesh size and in kappa -> inf (nu -> 1/2), so the number of Krylov iterations stays
bounded. Sp depends only on the materials (not on the state): it is assembled once per run. mu is the
small-strain shear modulus of the law (``shear_modulus``); kappa its bulk penalty (``Law.bulk_penalty``).
One application solves y_u = A~^-1 b_u, y_p = Sp^-1 (b_p - B y_u), x_u = A~^-1 (b_u - B^T y_p): two V-cycles
where the lower factor [A 0; B S] takes one, for 22-26 % fewer iterations at nu = 0.4999 (a V-cycle is only
an approximation of A^-1: the second one corrects the first) and counts that grow by about 20 % from nu = 0.3
to 0.4999 and from 1e4 to 1e6 dofs, where the lower factor's grew by 33 % (docs/solvers.md, "Scaling").

The fields are given to PETSc as index sets (PCFieldSplitSetIS) named "u" and "p": each rank's owned dofs of
the mixed space's sub-spaces, in the order of the collapsed sub-space (the u set node by node, x y z, block
size 3), in global numbering. So the u sub-matrix is laid out like the collapsed vector space, and the
rigid-body modes and the dilation built on that space are its near null space (composed with the u index set as
"nearnullspace", which PCFieldSplit attaches to the sub-matrix at every set-up).

With the fieldsplit preconditioner the Jacobian is a nested matrix by default ([solver] matrix = "auto":
``matrix_kind``, model.solvers.nested): one matrix per block, the index sets in the collapsed spaces' order,
so PCFieldSplit takes A, B^T, B and C as they are instead of copying them out of an assembled J.
"""

from __future__ import annotations

import logging
import math
import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import ufl
from dolfinx import fem, la
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from model.errors import ConfigError
from model.problem import ElasticityProblem

log = logging.getLogger(__name__)

Options = dict[str, str | int | float | bool]

#: the presets of [solver] linear
PRESETS = ("direct", "iterative", "auto")
#: "auto" chooses the iterative preset from this many unknowns (global): below it MUMPS is faster on one
#: or two ranks (docs/solvers.md, benchmarks/linear_presets.py)
AUTO_DOFS = 50_000
#: the fields of the mixed formulation, by their PETSc names
FIELDS = ("u", "p")
#: the Jacobian's matrix types of [solver] matrix (matrix_kind)
MATRICES = ("auto", "aij", "nest")

DIRECT: Options = {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"}
#: displacement formulation: CG + GAMG (the matrix carries the rigid-body modes as near null space). Threshold 0
#: (every coupling in the aggregation graph; 0.02 takes 10-20 % fewer iterations but makes the coarse levels'
#: Galerkin products twice as costly on P2: slower from about 1e5 dofs); the interpolation is reused across
#: Newton iterations (the same iterations, no aggregation in the set-ups after the first). docs/solvers.md,
#: "Iterative presets: tuning".
ITERATIVE_DISPLACEMENT: Options = {
    "ksp_type": "cg",
    "ksp_rtol": 1e-8,
    "ksp_max_it": 1000,
    "pc_type": "gamg",
    "pc_gamg_type": "agg",
    "pc_gamg_threshold": 0.0,
    "pc_gamg_reuse_interpolation": True,
    "mg_levels_ksp_type": "chebyshev",
    "mg_levels_pc_type": "jacobi",
}
#: displacement formulation with a nonsymmetric tangent (ElasticityProblem.symmetry_reason: a follower pressure, a
#: residual term of unknown symmetry): CG needs J = J^T, so GMRES, right preconditioned (its residual norm is the
#: true one), with the same GAMG (a fixed linear operator: GMRES, not FGMRES). The restart is above the iterations
#: a Newton step takes (docs/solvers.md, "Nonsymmetric tangents": 20-30 on the follower-pressure beam at 6e4 dofs),
#: so GMRES never restarts there.
ITERATIVE_DISPLACEMENT_NONSYMMETRIC: Options = {
    **ITERATIVE_DISPLACEMENT,
    "ksp_type": "gmres",
    "ksp_pc_side": "right",
    "ksp_gmres_restart": 200,
}
#: Krylov methods that need a symmetric matrix (a warning when the user picks one for a nonsymmetric tangent)
SYMMETRIC_KRYLOV = ("cg", "minres", "symmlq", "cr", "pipecg", "pipecr", "groppcg", "nash", "stcg", "gltr", "qcg")
#: mixed formulation: GMRES, right preconditioned by the Schur fieldsplit (full), GAMG on u, SSOR on the weighted
#: pressure mass matrix. The preconditioner is a fixed linear operator (two V-cycles, one SOR sweep), so GMRES is
#: enough and keeps one basis where FGMRES keeps two (1 GB at 1e6 dofs); an inner Krylov solve in the user's options
#: (fieldsplit_u_ksp_type cg, ...) makes it vary from one application to the next: then FGMRES (resolve).
ITERATIVE_MIXED: Options = {
    "ksp_type": "gmres",
    "ksp_pc_side": "right",
    "ksp_rtol": 1e-8,
    "ksp_max_it": 1000,
    "ksp_gmres_restart": 200,
    "pc_type": "fieldsplit",
    "pc_fieldsplit_type": "schur",
    "pc_fieldsplit_schur_fact_type": "full",
    "pc_fieldsplit_schur_precondition": "user",
    "fieldsplit_u_ksp_type": "preonly",
    "fieldsplit_u_pc_type": "gamg",
    "fieldsplit_u_pc_gamg_type": "agg",
    "fieldsplit_u_pc_gamg_threshold": 0.0,
    "fieldsplit_u_pc_gamg_reuse_interpolation": True,
    # stop coarsening below 5000 unknowns (direct solve there): with seven modes per aggregate the levels of a
    # few dozen rows can be rank deficient (a coarse diagonal of 1e-15 relative; Chebyshev's estimate 1.2e15 at
    # 1.03M dofs on 2 ranks: 62.2 instead of 43.2 iterations per Newton iteration). docs/solvers.md
    "fieldsplit_u_pc_gamg_coarse_eq_limit": 5000,
    "fieldsplit_u_mg_levels_ksp_type": "chebyshev",
    "fieldsplit_u_mg_levels_pc_type": "jacobi",
    "fieldsplit_p_ksp_type": "preonly",
    "fieldsplit_p_pc_type": "sor",
}

#: a Krylov method inside the fieldsplit (anything but preonly makes the preconditioner nonlinear)
_INNER_KRYLOV = re.compile(r"^fieldsplit_.+?_ksp_type$")
_FIELDSPLIT_NAME = re.compile(r"^fieldsplit_(.+?)(?:_(upper|inner))?_(ksp|pc|mat|mg|sub|snes)_")
#: the Schur factorisation's own A00 solvers: PCFieldSplit (3.18 to 3.24, fieldsplit.c, PCSetUp_FieldSplit) reads
#: ``fieldsplit_<S>_upper_`` (the second u solve of fact_type full / upper) and ``fieldsplit_<S>_inner_`` (the A00
#: solve inside the Schur complement's application) under the name S of the *second* split, the Schur
#: complement's: here p. It creates them only when an option with that prefix is in the database at its first
#: set-up; ``fieldsplit_u_upper_...`` it never reads.
SCHUR_SPLIT = FIELDS[1]
#: PCFieldSplit's own field definitions by component or block size (the solver gives u and p as index sets)
_FIELD_DEFINITIONS = re.compile(r"^pc_fieldsplit_(\d+_fields|block_size|detect_saddle_point)$")


@dataclass
class LinearChoice:
    """The linear solver a run uses: the preset asked for, the one it resolved to, and the options it adds."""

    requested: str
    preset: str
    dofs: int
    options: Options = field(default_factory=dict)
    #: why Newton's matrix is not symmetric (ElasticityProblem.symmetry_reason), None when it is
    nonsymmetric_because: str | None = None

    @property
    def symmetric(self) -> bool:
        return self.nonsymmetric_because is None

    def as_dict(self, effective: Options) -> dict[str, Any]:
        """For summary.json: ``linear`` (the resolved preset), what was asked for, the PETSc options in effect,
        ``symmetric`` (whether Newton's matrix is) and, when it is not, ``nonsymmetric_because``."""
        out: dict[str, Any] = {"linear": self.preset, "linear_requested": self.requested, "dofs": self.dofs,
                               "auto_dofs": AUTO_DOFS, "symmetric": self.symmetric}
        if self.nonsymmetric_because is not None:
            out["nonsymmetric_because"] = self.nonsymmetric_because
        out["petsc_options"] = {k: effective[k] for k in sorted(effective)}
        return out


def shear_modulus(law: Any) -> float:
    """The small-strain shear modulus mu of a law (the coefficient of the Schur preconditioner's 1/mu).

    Lame-parametrised laws (stvk, neo_hookean, corotated): mu. Mooney-Rivlin, and muscle/tendon with
    isotropic = "mooney_rivlin": 2 (c1 + c2) (c (Ibar - 3) = 2 c dev(eps):dev(eps) + O(eps^3)); muscle/tendon
    with isotropic = "stvk": mu; shape targets: mu (mu ||F - R S||^2 = mu eps:eps + O(eps^3) at S = I). Otherwise
    ValueError: the law has no shear stiffness this preconditioner knows of.
    """
    if getattr(law, "isotropic", None) == "mooney_rivlin" or (hasattr(law, "c1") and not hasattr(law, "isotropic")):
        value = 2.0 * (float(law.c1) + float(law.c2))
    elif hasattr(law, "mu"):
        value = float(law.mu)
    else:
        raise ValueError(f"law {getattr(law, 'name', law)!r} has no shear modulus (mu, or c1 and c2)")
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"law {getattr(law, 'name', law)!r}: shear modulus {value!r} (needs a finite value > 0)")
    return value


def check_options(problem: ElasticityProblem, options: Options, key: str = "solver.petsc_options") -> None:
    """ConfigError for fieldsplit options PETSc could not apply here: fields other than u and p, the Schur
    factorisation's A00 sub-solvers (``_upper_``, ``_inner_``) under another name than the Schur split's
    (``fieldsplit_p_upper_...``, ``fieldsplit_p_inner_...``; SCHUR_SPLIT), or a fieldsplit preconditioner on the
    displacement formulation (one field)."""
    for name in options:
        match = _FIELDSPLIT_NAME.match(name)
        if match and match.group(1) not in FIELDS:
            raise ConfigError(f"{key}.{name}: the fields of the mixed formulation are named u and p "
                              f"(fieldsplit_u_..., fieldsplit_p_...), not {match.group(1)!r}")
        if match and match.group(2) and match.group(1) != SCHUR_SPLIT:
            qualifier = match.group(2)
            raise ConfigError(f"{key}.{name}: PETSc names the Schur factorisation's {qualifier} solve of the u block "
                              f"after the Schur complement's split: fieldsplit_{SCHUR_SPLIT}_{qualifier}_..., not "
                              f"fieldsplit_{match.group(1)}_{qualifier}_...")
        if _FIELD_DEFINITIONS.match(name):
            raise ConfigError(f"{key}.{name}: the solver defines the fields itself (index sets u and p of the "
                              "mixed formulation); leave out PETSc's field definitions")
    if options.get("pc_type") == "fieldsplit" and problem.formulation != "mixed":
        raise ConfigError(f"{key}.pc_type: fieldsplit needs the mixed formulation (fields u and p); the displacement "
                          "formulation has one field (use discretization.formulation = \"mixed\" or pc_type gamg)")


def resolve(problem: ElasticityProblem, requested: str, user: Options | None = None, *,
            vi: bool = False, tangent: str = "exact") -> LinearChoice:
    """The preset [solver] linear = ``requested`` resolves to for this problem, with its PETSc options.

    "auto" is "direct" below AUTO_DOFS global unknowns and "iterative" from there, except with VI contact (its
    reduced systems have no fixed fields, and CG on them is untested): always "direct". The iterative preset
    follows the symmetry of Newton's matrix (problem.symmetry_reason(tangent)): the displacement formulation
    takes CG + GAMG where J = J^T and GMRES + GAMG where not (ITERATIVE_DISPLACEMENT_NONSYMMETRIC); the mixed
    formulation's GMRES with the Schur fieldsplit serves both (J symmetric indefinite without a follower pressure).
    The reason is the choice's ``nonsymmetric_because`` (summary.json). A Krylov method the user names that needs
    a symmetric matrix (``ksp_type`` cg, minres, ...: SYMMETRIC_KRYLOV) on a nonsymmetric one is logged as a
    warning and kept. ConfigError naming the key for combinations that cannot work: the mixed iterative preset
    with VI contact, a law without a shear modulus, or fieldsplit options naming other fields.
    """
    user = dict(user or {})
    if requested not in PRESETS:
        raise ConfigError(f"solver.linear: {requested!r} is not one of {', '.join(PRESETS)}")
    imap = problem.space.dofmap.index_map
    dofs = int(imap.size_global * problem.space.dofmap.index_map_bs)
    check_options(problem, user)
    because = problem.symmetry_reason(tangent)
    if because is not None and str(user.get("ksp_type", "")).lower() in SYMMETRIC_KRYLOV:
        if problem.domain.mesh.comm.rank == 0:
            log.warning("solver.petsc_options.ksp_type = %r needs a symmetric matrix, but Newton's matrix is not "
                        "symmetric (%s): expect DIVERGED_LINEAR_SOLVE; leave ksp_type out (GMRES) or use gmres",
                        user["ksp_type"], because)
    preset = requested
    if requested == "auto":
        preset = "iterative" if dofs >= AUTO_DOFS and not vi else "direct"
    if preset == "direct":
        return LinearChoice(requested, preset, dofs, dict(DIRECT), because)
    if problem.formulation == "displacement":
        chosen = ITERATIVE_DISPLACEMENT if because is None else ITERATIVE_DISPLACEMENT_NONSYMMETRIC
        return LinearChoice(requested, preset, dofs, _without_others(chosen, user), because)
    if vi:
        raise ConfigError("solver.linear: \"iterative\" with the mixed formulation cannot be used with contact "
                          "method \"vi\" (the VI solver's reduced systems have no fixed u and p fields); use "
                          "linear = \"direct\"")
    for i, (region, law) in enumerate(problem.materials):
        try:
            shear_modulus(law)
        except ValueError as err:
            raise ConfigError(f"solver.linear: \"iterative\" with the mixed formulation needs the shear modulus of "
                              f"every material; material[{i}] (region {region!r}): {err}") from None
    return LinearChoice(requested, preset, dofs, _without_others(ITERATIVE_MIXED, user), because)


def matrix_kind(problem: ElasticityProblem, requested: str, options: Options, *, tangent: str = "exact",
                bounds: bool = False) -> str:
    """The Jacobian's PETSc matrix for [solver] matrix = ``requested``: "nest" (one matrix per block of the fields
    u and p, model.solvers.nested: PCFieldSplit takes the blocks as they are instead of copying them out of an
    assembled matrix) or "aij" (the whole Jacobian assembled into one matrix).

    "auto" is "nest" where a nest can serve: the mixed formulation with ``pc_type`` fieldsplit (the iterative
    preset), the exact tangent, no variable bounds (VI contact) and no coupling terms added to the matrix
    (contact and sliding between bodies, problem.couplings: they add matrices in the mixed space's numbering;
    obstacles, bones and sliding on bones are UFL energies, in the blocks' forms); "aij" elsewhere, which every
    preconditioner takes (LU needs it). "nest" where it cannot serve: ConfigError naming why. (A block whose form
    cannot be separated, model.solvers.nested.BlockError, falls back to "aij" under "auto" when the solver is made.)
    """
    if requested not in MATRICES:
        raise ConfigError(f"solver.matrix: {requested!r} is not one of {', '.join(MATRICES)}")
    reason = None
    if problem.formulation != "mixed":
        reason = "needs the mixed formulation (its fields u and p are the blocks)"
    elif str(options.get("pc_type", "")) != "fieldsplit":
        reason = (f"needs a fieldsplit preconditioner (the iterative preset), not pc_type = "
                  f"{options.get('pc_type', 'none')!r}: other preconditioners need the assembled matrix")
    elif tangent != "exact":
        reason = "needs the exact tangent"
    elif bounds:
        reason = "cannot be used with contact method \"vi\" (variable bounds)"
    elif problem.couplings:
        reason = "cannot be used with contact or sliding between bodies (their terms are added to an assembled matrix)"
    if requested == "nest" and reason is not None:
        raise ConfigError(f"solver.matrix: \"nest\" {reason}; use \"auto\" or \"aij\"")
    return "nest" if requested == "nest" or (requested == "auto" and reason is None) else "aij"


def _without_others(preset: Options, user: Options) -> Options:
    """The preset's options less those of a preconditioner or Krylov method the user replaced (so that the
    options recorded as in effect are the ones PETSc reads)."""
    options = dict(preset)
    if user.get("pc_type", options.get("pc_type")) != options.get("pc_type"):
        options = {k: v for k, v in options.items()
                   if not k.startswith(("pc_fieldsplit_", "fieldsplit_", "pc_gamg_", "mg_levels_"))}
    if "ksp_type" not in user and options.get("ksp_type") == "gmres" and any(
            _INNER_KRYLOV.match(k) and str(v) != "preonly" for k, v in user.items()):
        options["ksp_type"] = "fgmres"  # an inner Krylov solve: the preconditioner varies, so flexible GMRES
    if str(user.get("ksp_type", options.get("ksp_type"))) not in ("gmres", "fgmres"):
        options.pop("ksp_gmres_restart", None)
        options.pop("ksp_pc_side", None)
    if str(options.get("ksp_type")) == "fgmres":
        options.pop("ksp_pc_side", None)  # FGMRES is right preconditioned only
    return options


def vector_rigid_body_modes(space: fem.FunctionSpace, dilation: bool = False) -> list[PETSc.Vec]:
    """The six rigid-body modes of a blocked vector space (block size 3), owned entries, orthonormalised.

    Translations e_i, rotations x -> e_k x x about the axes (u_a = -x_b, u_b = x_a), modified Gram-Schmidt.
    With ``dilation``, a seventh mode u = x - x_c (x_c the centre of the dofs' bounding box): a zero-energy mode
    of the deviatoric stiffness 2 mu dev(eps):dev(eps) (dev(eps(x)) = dev(I) = 0), which is what the displacement
    block of the mixed formulation holds when the law's volumetric part is left to the pressure (docs/solvers.md,
    "The displacement block's near null space").
    """
    imap = space.dofmap.index_map
    bs = space.dofmap.index_map_bs
    if bs != 3:
        raise ValueError(f"rigid-body modes: a vector space of block size 3, got {bs}")
    owned = imap.size_local
    x = space.tabulate_dof_coordinates()[:owned]
    vectors = [la.create_petsc_vector(imap, bs) for _ in range(7 if dilation else 6)]
    for i in range(3):  # translations
        with vectors[i].localForm() as local:
            local.array[i:owned * bs:bs] = 1.0
    for k, (a, b) in enumerate(((0, 1), (1, 2), (2, 0))):
        with vectors[3 + k].localForm() as local:
            local.array[a:owned * bs:bs] = -x[:, b]
            local.array[b:owned * bs:bs] = x[:, a]
    if dilation:
        comm = space.mesh.comm
        low, high = np.full(3, np.inf), np.full(3, -np.inf)
        if owned:
            low, high = x[:, :3].min(axis=0), x[:, :3].max(axis=0)
        comm.Allreduce(MPI.IN_PLACE, low, op=MPI.MIN)
        comm.Allreduce(MPI.IN_PLACE, high, op=MPI.MAX)
        with vectors[6].localForm() as local:
            for i in range(3):
                local.array[i:owned * bs:bs] = x[:, i] - 0.5 * (low[i] + high[i])
    for i, v in enumerate(vectors):  # modified Gram-Schmidt
        for w in vectors[:i]:
            v.axpy(-w.dot(v), w)
        v.normalize()
    return vectors


def rigid_body_modes(problem: ElasticityProblem) -> PETSc.NullSpace:
    """The six rigid-body modes of a displacement space, orthonormalised (a near null space for GAMG; the mixed
    formulation's u block gets them through model.solvers.linear.MixedFields)."""
    if problem.formulation != "displacement":
        raise ValueError("rigid-body modes: only for the displacement formulation")
    return PETSc.NullSpace().create(vectors=vector_rigid_body_modes(problem.space), comm=problem.space.mesh.comm)


class MixedFields:
    """The u and p index sets of a mixed (Taylor-Hood) problem, the u block's near null space and the Schur
    preconditioner's weighted pressure mass matrix Sp = - sum_r int (1/mu_r + 1/kappa_r) p q dx_r.

    ``nested``: the index sets are those of the block layout of a nested Jacobian (model.solvers.nested): on each
    rank its owned u dofs in the collapsed space's order, then its owned p dofs, numbered contiguously from the
    rank's offset (as PCFieldSplit needs, sorted); the near null space and Sp are then the collapsed spaces' own."""

    def __init__(self, problem: ElasticityProblem, nested: bool = False) -> None:
        if problem.formulation != "mixed":
            raise ValueError("MixedFields: only for the mixed formulation")
        space = problem.space
        comm = space.mesh.comm
        imap = space.dofmap.index_map
        bs = space.dofmap.index_map_bs
        owned = imap.size_local * bs
        first = imap.local_range[0] * bs
        self.spaces: dict[str, fem.FunctionSpace] = {}
        self.index_sets: dict[str, PETSc.IS] = {}
        #: per field: the collapsed space's owned dofs in the order of the field's rows (ascending global index in
        #: the mixed space, as PCFieldSplit needs)
        self.order: dict[str, np.ndarray] = {}
        #: per field: the mixed space's local dof of each local (owned, then ghost) dof of the collapsed space
        self.parents: dict[str, np.ndarray] = {}
        self.nested = nested
        for i, name in enumerate(FIELDS):
            collapsed, parent = space.sub(i).collapse()
            parent = np.asarray(parent, dtype=np.int64)
            sub_bs = collapsed.dofmap.index_map_bs
            n = collapsed.dofmap.index_map.size_local * sub_bs
            mine = parent[:n]
            if np.any(mine >= owned) or np.any(parent[n:] < owned):
                raise RuntimeError(f"field {name}: the collapsed space's owned dofs are not the mixed space's")
            self.parents[name] = parent
            if nested:  # the block layout: from the rank's first row (as the mixed space's), u then p
                order = np.arange(n)
                index_set = PETSc.IS().createStride(n, first, 1, comm=comm)
                first += n
            else:
                order = np.argsort(mine, kind="stable")
                index_set = PETSc.IS().createGeneral((first + mine[order]).astype(PETSc.IntType), comm=comm)
            # block size 3 (hypre's nodal coarsening) when the sorted u dofs come node by node, x y z
            blocks = order.reshape(-1, sub_bs)
            nodal = bool(np.all(blocks // sub_bs == blocks[:, :1] // sub_bs)
                         and np.all(blocks % sub_bs == np.arange(sub_bs)))
            if comm.allreduce(nodal, op=MPI.LAND) and sub_bs > 1:
                index_set.setBlockSize(sub_bs)
            self.spaces[name] = collapsed
            self.index_sets[name] = index_set
            self.order[name] = order
        self.modes = self._rigid_body_modes()
        self.near_null_space = PETSc.NullSpace().create(vectors=self.modes, comm=comm)
        self.index_sets["u"].compose("nearnullspace", self.near_null_space)
        self.compliance = [(region, 1.0 / shear_modulus(law) + (0.0 if math.isinf(law.bulk_penalty)
                                                                    else 1.0 / law.bulk_penalty))
                           for region, law in problem.materials]
        self.schur_matrix = self._weighted_mass(problem)

    def _rigid_body_modes(self) -> list[PETSc.Vec]:
        """The u block's near null space, laid out like the u field's rows (its index set's order): the six
        rigid-body modes of the collapsed u space and the dilation (vector_rigid_body_modes(..., dilation=True))."""
        collapsed = vector_rigid_body_modes(self.spaces["u"], dilation=True)
        order = self.order["u"]
        index_set = self.index_sets["u"]
        out = []
        for mode in collapsed:
            vector = PETSc.Vec().createMPI((index_set.getLocalSize(), index_set.getSize()), comm=index_set.comm)
            vector.setBlockSize(index_set.getBlockSize())
            vector.array[:] = mode.array_r[: len(order)][order]
            out.append(vector)
            mode.destroy()
        return out

    def _weighted_mass(self, problem: ElasticityProblem) -> PETSc.Mat:
        """Sp = - sum_r int (1/mu_r + 1/kappa_r) p q dx_r, assembled on the collapsed pressure space and taken in
        the p field's row order."""
        pressure = self.spaces["p"]
        msh = pressure.mesh
        p, q = ufl.TrialFunction(pressure), ufl.TestFunction(pressure)
        degree = 2 * (problem.degree - 1)
        dx = ufl.Measure("dx", domain=msh, subdomain_data=problem.domain.cell_tags,
                         metadata={"quadrature_degree": degree})
        form = None
        for region, weight in self.compliance:
            measure = dx if region == "all" else dx(problem.domain.regions[region])
            term = -fem.Constant(msh, PETSc.ScalarType(weight)) * p * q * measure
            form = term if form is None else form + term
        matrix = fem_petsc.assemble_matrix(fem.form(form))
        matrix.assemble()
        if self.nested:  # the collapsed space's order is the field's
            return matrix
        start = pressure.dofmap.index_map.local_range[0]
        rows = PETSc.IS().createGeneral((start + self.order["p"]).astype(PETSc.IntType), comm=msh.comm)
        reordered = matrix.createSubMatrix(rows, rows)
        rows.destroy()
        matrix.destroy()
        return reordered

    def configure(self, pc: PETSc.PC, options: Options) -> None:
        """Give a fieldsplit PC its u and p fields and, for ``pc_fieldsplit_schur_precondition user``, Sp."""
        pc.setFieldSplitIS(*((name, self.index_sets[name]) for name in FIELDS))
        if str(options.get("pc_fieldsplit_type", "")).lower() == "schur" and \
                str(options.get("pc_fieldsplit_schur_precondition", "")).lower() == "user":
            # petsc4py 3.18 names the enum PC.SchurPreType; later releases also PC.FieldSplitSchurPreType
            kinds = getattr(PETSc.PC, "FieldSplitSchurPreType", None) or PETSc.PC.SchurPreType
            pc.setFieldSplitSchurPreType(kinds.USER, self.schur_matrix)

    def destroy(self) -> None:
        self.schur_matrix.destroy()
        self.near_null_space.destroy()
        for vector in self.modes:
            vector.destroy()
        for index_set in self.index_sets.values():
            index_set.destroy()


def configure_fields(snes: PETSc.SNES, problem: ElasticityProblem, options: Options) -> MixedFields | None:
    """After SNESSetFromOptions: when the preconditioner is fieldsplit (mixed formulation), give it the u and
    p fields and the Schur preconditioner; None otherwise."""
    pc = snes.getKSP().getPC()
    if pc.getType() != PETSc.PC.Type.FIELDSPLIT:
        return None
    check_options(problem, {"pc_type": "fieldsplit"})
    fields = MixedFields(problem)
    fields.configure(pc, options)
    return fields


class LinearMonitor:
    """The linear iterations of every Newton iteration of the last NewtonSolver.solve (a SNES monitor: at Newton
    iteration k > 0 of a SNES solve, SNESGetLinearSolveIterations minus its value at k - 1). A solve may run
    SNES more than once (bt on the total potential, then full steps) and take a Newton step of its own (the
    Dirichlet step): ``reset`` starts a solve, ``add`` records a step taken outside SNES."""

    def __init__(self, snes: PETSc.SNES) -> None:
        self.per_newton: list[int] = []
        self._total = 0
        snes.setMonitor(self)

    def reset(self) -> None:
        self.per_newton = []
        self._total = 0

    def add(self, count: int) -> None:
        self.per_newton.append(int(count))

    def __call__(self, snes: PETSc.SNES, iteration: int, norm: float) -> None:
        if iteration == 0:  # a SNES solve starts: its count starts at 0
            self._total = 0
            return
        total = snes.getLinearSolveIterations()
        self.per_newton.append(int(total - self._total))
        self._total = total
