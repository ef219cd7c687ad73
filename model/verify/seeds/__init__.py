"""``verify seeds``: the formulas printed in the seed documents, transcribed as printed, against the UFL reference.

Each formula is a numpy transcription of what the
seed prints (the notation decisions are in each function's docstring), evaluated at the verify
samples (``deformation_samples(SAMPLES, SEED, inverted=False)``: identity, rotations, repeated singular values,
large stretches, nearly flat elements, random F; ``field_samples`` for S) and compared with
``model.verify.compare`` against the reference of the law the formula belongs to, computed
through the project's UFL forms (``ReferenceEvaluator``), at rtol 1e-8. A disagreement is a
finding: the row says what is wrong, and a ``-corrected`` row implements the corrected formula
and shows it agrees.

Seeds: Klár, Moffat, Museth and Sifakis, "Shape Targeting: A Versatile Active Elasticity Constitutive Model"
(SIGGRAPH Talks 2020; klar); Turchet, "Physics-based Modelling, Simulation, Placement and Learning for Musculo-Skeletal
Animations" (EngD thesis, Bournemouth University, 2018; thesis); Kassahun, Kachkovski, Song and Monem, "Automatic
Skinning Transformations using Mixed Finite Elements" (a Summer Geometry Initiative research blog post; sgi):

- shape-targeting-klar-2020.txt, eqs. 1-6 -> law ``shape_target`` (mu, field S = S_t);
- turchet-thesis-musculoskeletal.txt, eqs. 4.3, 4.11, 4.12 (section 4.3.3), appendix C.15, C.16,
  C.22 -> law ``stvk``; the thesis' Lame constants mu, lambda (defined from Y, nu right after
  eq. 4.3, the same formulas as energies.md) are the law's ``mu``, ``lmbda``;
- thesis eq. 4.5 (G = P B_m) and the stiffness printed below it, against the element vector and
  matrix dolfinx assembles on a one-cell mesh, for stvk, neo_hookean, corotated and shape_target.
- thesis eqs. 4.8 (= B.19), 4.9, 4.10 and dU/dF = 2 K ln(J) F^-T -> law ``muscle`` with its fibre term
  isolated (c1 = c2 = 0, P1 = 0, alpha = 1, a0 from ``field_samples``): P_fibre = P(muscle) - P(muscle with
  sigma_max = 0) = dF2/dlbar d lbar/dF, at the samples whose fibre stretch lies in the middle piece of f_active;
  the muscle with sigma_max = 0 is psi = K (ln J)^2 exactly, whose P is dU/dF.
- thesis eqs. 4.13-4.15 (spring potential, force, Hessian), section 3.3.3.1 (the membrane: 3x2 F, B, per-triangle
  energy, -grad and -Hessian, nodal pressure force) and eq. 4.4 (the semi-implicit backward Euler step) against
  references written in UFL and evaluated or assembled by dolfinx (``thesis_reference``: ufl.diff/ufl.derivative,
  a manifold triangle mesh in 3D, the closed surface of a tetrahedron, one Newton step of the implicit system).

- mixed-fem-skinning-sgi.txt, "Screened Poisson Equation" and "Mixed FEM": the printed KKT system and its
  stationarity conditions, the PDE against the energy it minimises, the KKT system with the mass and weight
  matrices against the standard finite elements (``sgi``: operators assembled by dolfinx on a triangle mesh);
  section "1.2 Apply Adjoint Method": dy/dR = -A^-1 (dA/dR) A^-1 b, the printed dy/dR = (dS, dx, 0), the
  gradients of L(S, x, lambda) and the chain rule for dE/dR against central differences (``sgi``, the mixed
  ARAP Lagrangian of forms.skinning assembled by model.problem.skinning).

Modules: ``common`` (rows, checks, numerics), ``klar`` and ``thesis`` (one per seed document: transcriptions
and rows), ``thesis_reference`` (the UFL/dolfinx references of the spring, membrane and time-step rows).

Rows (ids): klar-eq1, klar-eq2, klar-eq3, klar-eq4-6 (positive-det F), klar-psd (the PSD projection
the paper describes, checked independently: optimality certificate and random competitors), the
klar-eq1/eq3/eq4-6 ``-inverted`` rows (``--inverted`` samples: R* = U* V*^T as the text defines it
is a reflection when det F < 0), thesis-eq4.3, -eq4.11, -eq4.12, -eqC.15, -eqC.16 (each with C.22),
thesis-eq4.5-<law>, thesis-eq4.8, -eqB.19, -eq4.9, -eq4.10, -dUdF, thesis-eq4.13, -eq4.14, -eq4.15,
thesis-sec3.3.3.1-F, -energy, -forces, -hessian, -pressure, thesis-eq4.4, sgi-kkt, sgi-kkt-stationarity,
sgi-poisson-equation, sgi-kkt-fem, sgi-adjoint, sgi-adjoint-dlambda, sgi-adjoint-stationarity,
sgi-adjoint-gradient; ``-corrected`` variants for every disagreement.
"""

from __future__ import annotations

import json
from pathlib import Path

from mpi4py import MPI

from model.verify import ReferenceEvaluator, deformation_samples, field_samples
from model.verify.seeds.common import (
    ELEMENT_SAMPLES,
    KLAR,
    RTOL,
    SAMPLES,
    SEED,
    THESIS,
    SeedRow,
    _central_differences,
    format_table,
    to_json,
)
from model.verify.seeds.klar import (
    MU_KLAR,
    _klar_inverted_rows,
    _klar_rows,
    check_psd_projection,
    klar_eq1_energy,
    klar_eq2_corrected,
    klar_eq2_energy,
    klar_eq3_stress,
    klar_eq4_tangent,
    klar_eq5_rotation_differential,
    klar_rotation,
    klar_svd,
)
from model.verify.seeds.sgi import SGI, _sgi_rows, printed_kkt, sgi_operators
from model.verify.seeds.thesis import (
    LAMBDA_THESIS,
    MU_THESIS,
    TET,
    _element_rows,
    _euler_rows,
    _membrane_rows,
    _spring_rows,
    _thesis_muscle_rows,
    _thesis_rows,
    fibre_stretch_np,
    irving_Bm,
    muscle_fibre_derivatives,
    thesis_eq4_5_forces,
    thesis_eq4_5_stiffness,
    thesis_eq4_8_dlbar,
    thesis_eq4_10_corrected,
)

__all__ = ["ELEMENT_SAMPLES", "KLAR", "LAMBDA_THESIS", "MU_KLAR", "MU_THESIS", "RTOL", "SAMPLES", "SEED", "TET",
           "SGI", "THESIS", "SeedRow", "check_psd_projection", "fibre_stretch_np", "format_table", "irving_Bm",
           "klar_eq1_energy", "klar_eq2_corrected", "klar_eq2_energy", "klar_eq3_stress", "klar_eq4_tangent",
           "klar_eq5_rotation_differential", "klar_rotation", "klar_svd", "muscle_fibre_derivatives", "printed_kkt",
           "run_seeds", "seed_rows", "sgi_operators", "thesis_eq4_5_forces", "thesis_eq4_5_stiffness",
           "thesis_eq4_8_dlbar", "thesis_eq4_10_corrected", "to_json", "_central_differences"]


def seed_rows(include_inverted: bool = True) -> list[SeedRow]:
    """Every row of the table (collective-free: each MPI rank computes the same rows on COMM_SELF)."""
    F, _ = deformation_samples(SAMPLES, SEED, inverted=False)
    S = field_samples("shape_target", SAMPLES, SEED)["S"]
    klar = ReferenceEvaluator("shape_target", {"mu": MU_KLAR}, SAMPLES)
    klar_ref = klar.evaluate(F, S=S)
    stvk_ref = ReferenceEvaluator("stvk", {"mu": MU_THESIS, "lmbda": LAMBDA_THESIS}, SAMPLES).evaluate(F)
    rows = _klar_rows(F, S, klar_ref)
    if include_inverted:
        rows += _klar_inverted_rows(klar)
    rows += _thesis_rows(F, stvk_ref)
    rows += _thesis_muscle_rows()
    rows += _element_rows()
    rows += _spring_rows() + _membrane_rows() + _euler_rows()
    rows += _sgi_rows()
    return rows



def run_seeds(json_path: Path | str | None = None, rows: list[SeedRow] | None = None) -> int:
    """Print the table (rank 0) and write it as JSON when asked; 0 when the table was produced.

    Collective over COMM_WORLD (every rank computes the same rows on COMM_SELF; rank 0 prints and writes).
    ``rows`` skips the computation (tests).
    """
    rows = seed_rows() if rows is None else rows
    comm = MPI.COMM_WORLD
    if comm.rank == 0:
        print(format_table(rows))
        if json_path is not None:
            Path(json_path).write_text(json.dumps(to_json(rows), indent=2) + "\n")
    comm.barrier()
    return 0
