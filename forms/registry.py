"""The law registry: every built-in law with its parameter metadata, and user laws from files.

    REGISTRY["neo_hookean"]                   the LawEntry of a built-in law (forms.metadata)
    resolve_law("neo_hookean")                the same
    resolve_law("my_law.py:psi", base=dir)    a user's law from a file (forms.user_law), relative to base
    resolve_law(...).make(mu=1e3, lmbda=inf)  the Law, parameters validated (ParameterError naming the key)
    laws_markdown()                           "## Laws and their parameters" for docs/config.md

forms.LAWS (name -> Law class), forms.FIELDS (name -> fields) and forms.make_law are derived from
REGISTRY, so there is one list of laws. Formulas are those of docs/laws.md.
"""

from __future__ import annotations

from pathlib import Path

from forms.fibre_laws import (
    BLEMKER_PARAMETERS,
    HOLZAPFEL_OGDEN_PARAMETERS,
    TRANS_ISO_MOONEY_RIVLIN_PARAMETERS,
    Blemker,
    HolzapfelOgden,
    TransIsoMooneyRivlin,
)
from forms.isotropic import Corotated, MooneyRivlin, NeoHookean, StVenantKirchhoff
from forms.isotropic_more import SNH_VARIANTS, Arap, FixedCorotated, StableNeoHookean, Yeoh
from forms.law import ParameterError
from forms.metadata import LawEntry, Parameter
from forms.metadata import laws_markdown as _laws_markdown
from forms.muscle import Muscle, Tendon
from forms.ogden import Ogden
from forms.shape_target import ShapeTarget, Volume

PA = "Pa (stress)"
ONE = "dimensionless"

#: (E, nu) or (mu, lmbda), the two ways to give an isotropic law's Lame constants (energies.md)
LAME_SETS = (("E", "nu"), ("mu", "lmbda"))


def _lame(bulk: bool = True, applies: str = "") -> tuple[Parameter, ...]:
    """E, nu, mu, lmbda; lmbda is the law's bulk parameter (inf allowed) when ``bulk``."""
    lmbda = (Parameter("lmbda", "first Lame parameter (the bulk penalty kappa of the mixed split)", PA,
                       constraint="> -2 mu / 3", infinite=True, applies=applies) if bulk else
             Parameter("lmbda", "first Lame parameter", PA, applies=applies))
    return (Parameter("E", "Young's modulus", PA, lower=0.0, applies=applies),
            Parameter("nu", "Poisson's ratio", ONE, lower=-1.0, upper=0.5, applies=applies),
            Parameter("mu", "shear modulus, the second Lame parameter", PA, lower=0.0, applies=applies),
            lmbda)


def _isotropic_part(applies_mr: str, applies_stvk: str) -> tuple[Parameter, ...]:
    """The isotropic part F1 of muscle and tendon: its choice, Mooney-Rivlin's c1, c2 or StVK's Lame set."""
    return (Parameter("isotropic", "isotropic part F1: Mooney-Rivlin (Teran) or StVK (the thesis)", "choice",
                      default="mooney_rivlin", choices=("mooney_rivlin", "stvk")),
            Parameter("c1", "Mooney-Rivlin coefficient of (Ibar1 - 3)", PA, default=500.0, lower=0.0,
                      lower_open=False, applies=applies_mr),
            Parameter("c2", "Mooney-Rivlin coefficient of (Ibar2 - 3)", PA, default=0.0, lower=0.0,
                      lower_open=False, applies=applies_mr),
            *_lame(bulk=False, applies=applies_stvk),
            Parameter("K", "volumetric coefficient of K (ln J)^2 (kappa = 2 K)", PA, default=1.0e7, lower=0.0,
                      infinite=True))


_K = Parameter("K", "volumetric coefficient of K (ln J)^2 (kappa = 2 K)", PA, lower=0.0, infinite=True)

BUILT_IN: tuple[LawEntry, ...] = (
    LawEntry("stvk", "St Venant-Kirchhoff: linear stress-strain in the Green-Lagrange strain.",
             "mu E:E + (lmbda/2) (tr E)^2", _lame(), StVenantKirchhoff, parameter_sets=LAME_SETS,
             bulk_parameter="lmbda", volume_constraint="tr E"),
    LawEntry("neo_hookean", "Compressible neo-Hookean solid.",
             "(mu/2)(tr C - 3) - mu ln J + (lmbda/2)(ln J)^2", _lame(), NeoHookean, parameter_sets=LAME_SETS,
             bulk_parameter="lmbda", volume_constraint="ln J"),
    LawEntry("mooney_rivlin", "Isochoric Mooney-Rivlin with Teran et al. 2003's volumetric term (no factor 1/2).",
             "c1 (Ibar1 - 3) + c2 (Ibar2 - 3) + K (ln J)^2",
             (Parameter("c1", "coefficient of (Ibar1 - 3)", PA, lower=0.0, lower_open=False),
              Parameter("c2", "coefficient of (Ibar2 - 3)", PA, lower=0.0, lower_open=False), _K),
             MooneyRivlin, bulk_parameter="K", volume_constraint="ln J", kappa="2 K", notes=("c1 + c2 > 0.",)),
    LawEntry("corotated", "Corotated linear elasticity, R(F) the rotation of the polar decomposition of F.",
             "mu ||F - R(F)||^2 + (lmbda/2)(J - 1)^2", _lame(), Corotated, parameter_sets=LAME_SETS,
             bulk_parameter="lmbda", volume_constraint="J - 1"),
    LawEntry("fixed_corotated", "Fixed corotated (Stomakhin et al. 2012, with the rotation variant of the SVD): "
             "corotated under its graphics name, the same code and values.",
             "mu ||F - R(F)||^2 + (lmbda/2)(J - 1)^2", _lame(), FixedCorotated, parameter_sets=LAME_SETS,
             bulk_parameter="lmbda", volume_constraint="J - 1",
             notes=("mu ||F - R||^2 = mu sum_i (sigma_i - 1)^2 with signed singular values: equal to `corotated` "
                    "with the same (mu, lmbda).",)),
    LawEntry("arap", "As-rigid-as-possible (HOBAK's ARAP.cpp, Kim & Eberle 2022): corotated with lmbda = 0, the same "
             "code and values.",
             "mu ||F - R(F)||^2",
             (Parameter("mu", "stiffness of the distance to the rotation, HOBAK's mu (no factor 1/2: corotated's mu)",
                        PA, lower=0.0),),
             Arap, notes=("No volumetric term (kappa = 0): displacement formulation only.",)),
    LawEntry("stable_neo_hookean", "Stable Neo-Hookean (Smith, de Goes & Kim 2018), defined for inverted F too. "
             "(mu, lmbda) or (E, nu) are the Lame constants of linear elasticity: the law reparametrises them to "
             "(ms, ls) so that its small-strain tangent is linear elasticity's.",
             "rest_stable: (ms/2)(Ic - 3) - ms (J - 1) + (ls/2)(J - 1)^2, ms = mu, ls = lmbda + mu; "
             "paper: (ms/2)(Ic - 3) + (ls/2)(J - alpha)^2 - (ms/2) ln(Ic + 1), ms = 4 mu / 3, ls = lmbda + 5 mu / 6, "
             "alpha = 1 + 3 ms / (4 ls); Ic = ||F||^2",
             (Parameter("variant", "rest_stable: Kim & Eberle 2022's form (HOBAK's SNH); paper: Smith et al. 2018 "
                        "eq. 14 with the ln(Ic + 1) term", "choice", default="rest_stable", choices=SNH_VARIANTS),
              *_lame()[:3],
              Parameter("lmbda", "first Lame parameter of linear elasticity (kappa = ls of the mixed split)", PA,
                        constraint="> -2 mu / 3", infinite=True)),
             StableNeoHookean, parameter_sets=LAME_SETS, bulk_parameter="lmbda", volume_constraint="J - 1",
             kappa="ls (lmbda + mu, or lmbda + 5 mu / 6 for paper)",
             notes=("P(I) = 0 for both variants; psi(I) = 0 (rest_stable), 9 ms^2 / (32 ls) - ms ln 2 (paper).",)),
    LawEntry("yeoh", "Yeoh (1993), FEBio's \"Yeoh\" isochoric part (three terms) with FEBio's default volumetric "
             "term U(J) = (k/2)(ln J)^2, k = kappa.",
             "c1 (Ibar1 - 3) + c2 (Ibar1 - 3)^2 + c3 (Ibar1 - 3)^3 + (kappa/2)(ln J)^2",
             (Parameter("c1", "coefficient of (Ibar1 - 3): the small-strain shear modulus is 2 c1", PA, lower=0.0),
              Parameter("c2", "coefficient of (Ibar1 - 3)^2", PA, default=0.0),
              Parameter("c3", "coefficient of (Ibar1 - 3)^3", PA, default=0.0),
              Parameter("kappa", "bulk modulus (FEBio's k)", PA, lower=0.0, infinite=True)),
             Yeoh, bulk_parameter="kappa", volume_constraint="ln J"),
    LawEntry("shape_target", "Shape targeting (Klar et al. 2020, after Phace): distance of F to the rotated "
             "target S, R* = argmin over R in SO(3) of ||F - R S||_F.",
             "mu ||F - R* S||_F^2 + (kappa/2)(J - det S)^2",
             (Parameter("mu", "stiffness of the distance to the target shape", PA, lower=0.0),
              Parameter("kappa", "volume penalty", PA, default=0.0, lower=0.0, lower_open=False, infinite=True)),
             ShapeTarget, fields=("S",), bulk_parameter="kappa", volume_constraint="J - det S"),
    LawEntry("volume", "The volume term of shape targeting alone (no shear stiffness).",
             "(kappa/2)(J - det S)^2",
             (Parameter("kappa", "volume penalty", PA, lower=0.0, infinite=True),),
             Volume, fields=("S",), bulk_parameter="kappa", volume_constraint="J - det S"),
    LawEntry("muscle", "Fibre-activated muscle (Teran et al. 2003 / Blemker et al. 2005 form, as in Turchet's "
             "thesis, 2018): F1 isotropic, lbar the isochoric fibre stretch, s = lbar / l_ofl, f_active and "
             "f_passive the curves of docs/laws.md.",
             "F1 + K (ln J)^2 + F2(lbar, alpha), dF2/dlbar = (sigma_max / l_ofl) (f_passive(s) + alpha f_active(s))",
             (*_isotropic_part("isotropic = mooney_rivlin", "isotropic = stvk"),
              Parameter("sigma_max", "maximum isometric fibre stress", PA, default=3.0e5, lower=0.0,
                        lower_open=False),
              Parameter("P1", "scale of the passive fibre curve (times sigma_max)", ONE, default=0.05, lower=0.0,
                        lower_open=False),
              Parameter("P2", "exponent of the passive fibre curve", ONE, default=6.6, lower=0.0),
              Parameter("l_ofl", "optimal fibre stretch (the active curve peaks at lbar = l_ofl)", ONE, default=1.0,
                        lower=0.0),
              Parameter("l_star", "fibre stretch where the passive curve turns linear", ONE, default=1.4,
                        constraint="> l_ofl")),
             Muscle, fields=("a0", "alpha"), parameter_sets=LAME_SETS, sets_condition="when isotropic = stvk",
             bulk_parameter="K", volume_constraint="ln J", kappa="2 K"),
    LawEntry("tendon", "Passive tendon: the muscle's structure with the along-fibre stress curve sigma_tendon "
             "(0 for lbar <= 1, L1 (exp(L2 (lbar - 1)) - 1) up to l_star_t, linear beyond).",
             "F1 + K (ln J)^2 + F2(lbar), dF2/dlbar = sigma_tendon(lbar)",
             (*_isotropic_part("isotropic = mooney_rivlin", "isotropic = stvk"),
              Parameter("L1", "scale of the along-fibre stress curve", PA, default=2.7e6, lower=0.0,
                        lower_open=False),
              Parameter("L2", "exponent of the along-fibre stress curve", ONE, default=46.4, lower=0.0),
              Parameter("l_star_t", "fibre stretch where the stress curve turns linear", ONE, default=1.03,
                        lower=1.0)),
             Tendon, fields=("a0",), parameter_sets=LAME_SETS, sets_condition="when isotropic = stvk",
             bulk_parameter="K", volume_constraint="ln J", kappa="2 K"),
    LawEntry("ogden", "Ogden (1972) in FEBio's uncoupled form: lbar_i = J^(-1/3) lambda_i the isochoric principal "
             "stretches, up to six terms (as FEBio). Ogden's mu_p, alpha_p: c_p = mu_p alpha_p, m_p = alpha_p; "
             "small-strain shear modulus sum_p c_p / 2.",
             "sum_p c_p / m_p^2 (lbar_1^m_p + lbar_2^m_p + lbar_3^m_p - 3) + (kappa/2)(ln J)^2",
             (Parameter("c1", "coefficient of the first term (c_p = mu_p alpha_p of Ogden's form)", PA, lower=0.0),
              Parameter("m1", "exponent of the first term (alpha_p)", ONE, constraint="!= 0"),
              *(parameter
                for p, nth in ((2, "second"), (3, "third"), (4, "fourth"), (5, "fifth"), (6, "sixth"))
                for parameter in (Parameter(f"c{p}", f"coefficient of the {nth} term (0: absent)", PA, default=0.0,
                                            lower=0.0, lower_open=False),
                                  Parameter(f"m{p}", f"exponent of the {nth} term", ONE, default=1.0,
                                            constraint="!= 0"))),
              Parameter("kappa", "bulk modulus of (kappa/2)(ln J)^2 (FEBio's k)", PA, lower=0.0, lower_open=False,
                        infinite=True)),
             Ogden, bulk_parameter="kappa", volume_constraint="ln J",
             notes=("m_p != 0. The tangent is exact at repeated stretches (a per-point eigenbasis, forms.spectral). "
                    "Source: Ogden 1972, Proc. R. Soc. A 326, 565-584; FEBio's Ogden material (c_i, m_i).",)),
    LawEntry("holzapfel_ogden", "Passive myocardium (Holzapfel & Ogden 2009, eq. 5.38) in the isochoric invariants "
             "of Cbar = J^(-2/3) C, with FEBio's default volumetric term: fibre (a0) and sheet (s0) terms act in "
             "tension only (H the unit step), I8 = a0 . Cbar s0.",
             "a/(2b)(exp(b(Ibar1 - 3)) - 1) + sum_{i=f,s} H(Ibar4i - 1) a_i/(2 b_i)(exp(b_i (Ibar4i - 1)^2) - 1) "
             "+ a_fs/(2 b_fs)(exp(b_fs Ibar8^2) - 1) + (kappa/2)(ln J)^2",
             HOLZAPFEL_OGDEN_PARAMETERS, HolzapfelOgden, fields=("a0", "s0"), bulk_parameter="kappa",
             volume_constraint="ln J",
             notes=("Defaults: Holzapfel & Ogden 2009, Table 1 (kappa: a choice of this project).",
                    "In a configuration file s0 comes from `sheets = { type = ... }`, given as `fibres` is.")),
    LawEntry("trans_iso_mooney_rivlin", "Transversely isotropic Mooney-Rivlin (Weiss, Maker & Govindjee 1996; "
             "FEBio's \"trans iso Mooney-Rivlin\") with FEBio's uncoupled active contraction as an energy: "
             "lbar dF2/dlbar = 0 (lbar < 1), c3 (exp(c4 (lbar - 1)) - 1) (1 <= lbar < lam_max), c5 lbar + c6 "
             "beyond; lbar dFa/dlbar = T(lbar) = Tmax (E - 1)/(E - 1 + (camax/ca0)^2), E = exp(beta (refl lbar - "
             "l0)) for refl lbar >= l0, else 0.",
             "c1 (Ibar1 - 3) + c2 (Ibar2 - 3) + F2(lbar) + alpha Fa(lbar) + (k/2)(ln J)^2",
             TRANS_ISO_MOONEY_RIVLIN_PARAMETERS, TransIsoMooneyRivlin, fields=("a0", "alpha"), bulk_parameter="k",
             volume_constraint="ln J",
             notes=("Defaults: the FEBio user manual's example (c1 ... lam_max, k read as MPa; ca0, beta, l0, refl "
                    "of its active contraction); Tmax is a choice of this project.",
                    "psi integrates F2 and Fa by 32-point Gauss-Legendre quadrature (no elementary antiderivative); "
                    "P and A are exact.")),
    LawEntry("blemker", "Skeletal muscle (Blemker, Pinsky & Delp 2005; FEBio's \"muscle material\"): Criscione's "
             "along-fibre and cross-fibre shear invariants B1^2 = Ibar5/Ibar4^2 - 1, B2 = arccosh((Ibar1 Ibar4 - "
             "Ibar5)/(2 sqrt(Ibar4))), FEBio's (9/16) g3 (ln Ibar4)^2, and the muscle law's fibre curves with "
             "l_ofl = Lofl, l_star = lam_max, P1 = p1, P2 = p2, sigma_max = smax.",
             "g1 B1^2 + g2 B2^2 + (9/16) g3 (ln Ibar4)^2 + F2(lbar, alpha) + (k/2)(ln J)^2, "
             "dF2/dlbar = (smax/Lofl)(f_passive(lbar/Lofl) + alpha f_active(lbar/Lofl))",
             BLEMKER_PARAMETERS, Blemker, fields=("a0", "alpha"), bulk_parameter="k", volume_constraint="ln J",
             notes=("Defaults: the FEBio user manual's muscle material example (g3 = 0: FEBio's default).",)),
)

#: Every built-in law's entry by its name in energies.md, in the order of energies.md.
REGISTRY: dict[str, LawEntry] = {entry.name: entry for entry in BUILT_IN}


def resolve_law(spec: str, base: Path | str | None = None) -> LawEntry:
    """The registry entry of ``spec``: a built-in law's name, or a user law "FILE.py:FUNCTION" (FILE
    relative to ``base``, default the working directory; "FILE.py" alone means FUNCTION = psi).

    ParameterError when the name is unknown or the file breaks the contract of forms.user_law.
    """
    if spec in REGISTRY:
        return REGISTRY[spec]
    path, _, function = spec.rpartition(":") if ":" in spec else (spec, ":", "psi")
    if path.endswith(".py"):
        from forms.user_law import load_user_law

        return load_user_law(spec, Path(path), function, Path(base) if base is not None else Path("."))
    raise ParameterError(f"unknown law {spec!r} (choose from {', '.join(sorted(REGISTRY))}, or FILE.py:FUNCTION "
                         "for a law of your own)")


INTRO = ("Every law is a strain-energy density psi(F) per unit reference volume (Pa = J/m^3), written "
         "as in docs/laws.md; UFL derives the stress and the tangent. Each splits as "
         "psi = W + (kappa/2) g(F)^2 for the mixed (Taylor-Hood) formulation; its bulk parameter = inf "
         "is exact incompressibility, which only the mixed formulation accepts. A law of your own: "
         "`law = \"FILE.py:FUNCTION\"` (forms/user_law.py), with a volumetric term (kappa/2) g^2, "
         "g = J - 1 (or ln J), kappa default 0.")


def laws_markdown(entries: list[LawEntry] | None = None, level: int = 2) -> str:
    """The Markdown section "Laws and their parameters" for the built-in laws (and ``entries`` after them)."""
    return _laws_markdown([*BUILT_IN, *(entries or [])], level, INTRO)


__all__ = ["BUILT_IN", "LAME_SETS", "REGISTRY", "laws_markdown", "resolve_law"]
