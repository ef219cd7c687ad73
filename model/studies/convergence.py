"""Mesh-convergence studies: one run per mesh, then per quantity of interest (QoI) the observed order,
the Richardson-extrapolated value and the grid convergence index (GCI) of the three finest meshes.

The procedure is Celik et al. (2008), "Procedure for Estimation and Reporting of Uncertainty Due to
Discretization in CFD Applications", J. Fluids Eng. 130, 078001 (the ASME V&V 20 procedure). With the
meshes numbered fine to coarse (h1 < h2 < h3) and phi_k the QoI on mesh k:

    h          = (V / N_cells)^(1/3)                     representative cell size (V the body's volume)
    r21, r32   = h2 / h1, h3 / h2                        refinement ratios (need not be equal)
    eps21      = phi2 - phi1, eps32 = phi3 - phi2,  s = sign(eps32 / eps21)
    p          = |ln|eps32 / eps21| + q(p)| / ln r21,  q(p) = ln((r21^p - s) / (r32^p - s))
                                                         observed order (their eq. 3, by fixed-point iteration)
    phi_ext^21 = (r21^p phi1 - phi2) / (r21^p - 1)       Richardson extrapolation (phi_ext^32 likewise)
    e_a^21     = |(phi1 - phi2) / phi1|                  approximate relative error (e_a^32 likewise)
    e_ext^21   = |(phi_ext^21 - phi1) / phi_ext^21|      extrapolated relative error
    GCI^21     = 1.25 e_a^21 / (r21^p - 1)               fine-grid convergence index
    GCI^32     = 1.25 e_a^32 / (r32^p - 1)               medium-grid convergence index
    ratio      = GCI^32 / (r21^p GCI^21)                 ~ 1 in the asymptotic range (with r21 = r32 and p from
                                                         the same three meshes it equals phi1 / phi2: it flags a
                                                         QoI still changing by a large fraction)

Warnings: oscillatory convergence (eps32 / eps21 < 0), an observed order out of range (p < 0.5, or
p > 2 x the formal order when it is given), an asymptotic ratio further than ``ratio_tolerance`` from 1,
refinement ratios below 1.3 (Celik et al.'s recommendation), values equal on two meshes or equal to
round-off (|eps| <= 1e-10 |phi|) on all three (no order: p and what follows from it are NaN).

When a QoI's exact value is known (a manufactured solution), ``exact`` adds the order against it from
the two finest meshes, p_exact = ln(|phi2 - exact| / |phi1 - exact|) / ln r21.

``converge(config, refine, qois, out)`` runs the meshes in this process (model.pipeline.run, collective
over ``comm``) and returns a ConvergenceStudy; ``ConvergenceStudy.from_table`` does the analysis of values
obtained otherwise. ``study.write(out)`` writes convergence.csv (a row per QoI), convergence_meshes.csv
(a row per mesh), convergence.md (both as Markdown tables) and convergence.png (log-log plot of
|phi - phi_ext| / |phi_ext| against h with the observed slope).
"""

from __future__ import annotations

import json
import logging
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from mpi4py import MPI

from model.errors import ConfigError

log = logging.getLogger(__name__)

#: Celik et al.'s safety factor for three-grid studies
SAFETY_FACTOR = 1.25
#: an observed order further than this from the formal one widens the GCI (WIDE_SAFETY_FACTOR, order min(p, formal))
ORDER_DEVIATION = 0.5
#: Roache's safety factor for estimates outside the asymptotic range (and for two-grid studies)
WIDE_SAFETY_FACTOR = 3.0
#: smallest refinement ratio Celik et al. recommend
MIN_RATIO = 1.3
#: differences between meshes below this fraction of |phi| are round-off, not discretization error
ROUND_OFF = 1e-10
_COMPONENTS = {"x": 0, "y": 1, "z": 2, "0": 0, "1": 1, "2": 2}


def representative_h(volume: float, cells: int, dim: int = 3) -> float:
    """h = (V / N)^(1/dim): the representative cell size of a mesh of N cells filling volume V."""
    if not (volume > 0 and cells > 0):
        raise ValueError(f"representative h needs a positive volume and cell count, got V={volume}, N={cells}")
    return float((volume / cells) ** (1.0 / dim))


def observed_order(r21: float, r32: float, eps21: float, eps32: float, tol: float = 1e-12,
                   max_iterations: int = 500) -> tuple[float, bool]:
    """(p, converged) of p = |ln|eps32/eps21| + q(p)| / ln r21, q(p) = ln((r21^p - s)/(r32^p - s)),
    s = sign(eps32/eps21), by fixed-point iteration from q = 0 (Celik et al. 2008, eq. 3).

    NaN when eps21 or eps32 is zero (no order can be observed)."""
    if eps21 == 0 or eps32 == 0 or not (np.isfinite(eps21) and np.isfinite(eps32)):
        return math.nan, False
    s = 1.0 if eps32 / eps21 > 0 else -1.0
    log_ratio = math.log(abs(eps32 / eps21))
    p = abs(log_ratio) / math.log(r21)
    for _ in range(max_iterations):
        a, b = r21 ** p - s, r32 ** p - s
        if a <= 0 or b <= 0:  # s = 1 and p -> 0: q undefined
            return p, False
        new = abs(log_ratio + math.log(a / b)) / math.log(r21)
        if abs(new - p) <= tol * max(1.0, abs(new)):
            return new, True
        p = new
    return p, False


@dataclass(frozen=True)
class GCIResult:
    """The three-grid analysis of one QoI (meshes fine to coarse: h = (h1, h2, h3), phi = (phi1, phi2, phi3));
    the formulas are in the module docstring. Relative errors and GCIs are fractions (0.022 = 2.2 %)."""

    h: tuple[float, float, float]
    phi: tuple[float, float, float]
    r21: float
    r32: float
    eps21: float
    eps32: float
    s: float
    p: float
    phi_ext21: float
    phi_ext32: float
    e_a21: float
    e_a32: float
    e_ext21: float
    e_ext32: float
    gci_fine21: float
    gci_medium32: float
    asymptotic_ratio: float
    p_exact: float = math.nan
    warnings: tuple[str, ...] = ()
    #: the safety factor and the order the GCIs were computed with (SAFETY_FACTOR and p, or widened)
    gci_safety_factor: float = SAFETY_FACTOR
    gci_order: float = math.nan

    def as_dict(self) -> dict[str, Any]:
        """A flat dict (h1..h3, phi1..phi3 and the scalar fields; warnings joined by "; ")."""
        out: dict[str, Any] = {f"h{i + 1}": v for i, v in enumerate(self.h)}
        out.update({f"phi{i + 1}": v for i, v in enumerate(self.phi)})
        for name in ("r21", "r32", "eps21", "eps32", "s", "p", "phi_ext21", "phi_ext32", "e_a21", "e_a32",
                     "e_ext21", "e_ext32", "gci_fine21", "gci_medium32", "asymptotic_ratio", "p_exact",
                     "gci_safety_factor", "gci_order"):
            out[name] = getattr(self, name)
        out["warnings"] = "; ".join(self.warnings)
        return out


def gci(h: Sequence[float], phi: Sequence[float], formal_order: float | None = None,
        safety_factor: float = SAFETY_FACTOR, ratio_tolerance: float = 0.1,
        exact: float | None = None) -> GCIResult:
    """The three-grid GCI analysis (Celik et al. 2008) of values ``phi`` on meshes of sizes ``h``, both ordered
    fine to coarse (h1 < h2 < h3). ``formal_order``: the discretization's order, for the range warning;
    ``exact``: the QoI's exact value when known (adds p_exact). Raises ValueError on bad input."""
    if len(h) != 3 or len(phi) != 3:
        raise ValueError(f"three meshes are needed, got {len(h)} sizes and {len(phi)} values")
    h1, h2, h3 = (float(v) for v in h)
    phi1, phi2, phi3 = (float(v) for v in phi)
    if not (0 < h1 < h2 < h3):
        raise ValueError(f"mesh sizes must be positive and ordered fine to coarse, got h = {tuple(h)}")
    if not all(np.isfinite((phi1, phi2, phi3))):
        raise ValueError(f"the values must be finite, got phi = {tuple(phi)}")
    r21, r32 = h2 / h1, h3 / h2
    eps21, eps32 = phi2 - phi1, phi3 - phi2
    warnings: list[str] = []
    nan = math.nan
    scale = max(abs(phi1), abs(phi2), abs(phi3))
    if max(abs(eps21), abs(eps32)) <= ROUND_OFF * scale:  # e.g. a reaction that equals the applied load
        warnings.append(f"the values agree to round-off (|eps| <= {ROUND_OFF:g} |phi|): the QoI does not depend on "
                        "the mesh, no order can be observed")
        eps21_, eps32_ = 0.0, 0.0
    else:
        eps21_, eps32_ = eps21, eps32
    s = nan if eps21_ == 0 or eps32_ == 0 else (1.0 if eps32 / eps21 > 0 else -1.0)
    p, converged = observed_order(r21, r32, eps21_, eps32_)
    if math.isnan(p):
        if not warnings:
            warnings.append("two meshes give the same value: no order can be observed")
    elif not converged:
        warnings.append(f"the fixed-point iteration for p did not converge (last p = {p:.4g})")
    if s < 0:
        warnings.append(f"oscillatory convergence (eps32/eps21 = {eps32 / eps21:.3g} < 0)")
    if not math.isnan(p):
        if p < 0.5:
            warnings.append(f"observed order p = {p:.3g} < 0.5")
        if formal_order is not None and p > 2 * formal_order:
            warnings.append(f"observed order p = {p:.3g} > 2 x the formal order {formal_order:g}")
    widened = (formal_order is not None and not math.isnan(p) and abs(p - formal_order) > ORDER_DEVIATION)
    if widened:
        warnings.append(f"observed order p = {p:.3g} differs from the formal order {formal_order:g} by more than "
                        f"{ORDER_DEVIATION:g}: a singularity (a clamped edge, a re-entrant corner, a point load) or "
                        "meshes not yet in the asymptotic range; the GCI band is widened (safety factor "
                        f"{WIDE_SAFETY_FACTOR:g}, order min(p, {formal_order:g})) and is itself uncertain")
    if min(r21, r32) < MIN_RATIO:
        warnings.append(f"refinement ratio {min(r21, r32):.3g} < {MIN_RATIO} (Celik et al. recommend more)")
    e_a21 = abs(eps21 / phi1) if phi1 != 0 else nan
    e_a32 = abs(eps32 / phi2) if phi2 != 0 else nan
    if math.isnan(p):
        phi_ext21 = phi_ext32 = e_ext21 = e_ext32 = gci21 = gci32 = ratio = nan
    else:
        f21, f32 = r21 ** p, r32 ** p
        phi_ext21 = (f21 * phi1 - phi2) / (f21 - 1)
        phi_ext32 = (f32 * phi2 - phi3) / (f32 - 1)
        e_ext21 = abs((phi_ext21 - phi1) / phi_ext21) if phi_ext21 != 0 else nan
        e_ext32 = abs((phi_ext32 - phi2) / phi_ext32) if phi_ext32 != 0 else nan
        gci21 = safety_factor * e_a21 / (f21 - 1)
        gci32 = safety_factor * e_a32 / (f32 - 1)
        ratio = gci32 / (f21 * gci21) if gci21 > 0 else nan  # with the observed p: is it asymptotic?
        if widened:
            order = min(p, float(formal_order))  # a smaller order, a wider band
            safety_factor = WIDE_SAFETY_FACTOR
            gci21 = safety_factor * e_a21 / (r21 ** order - 1)
            gci32 = safety_factor * e_a32 / (r32 ** order - 1)
        if not math.isnan(ratio) and abs(ratio - 1) > ratio_tolerance:
            warnings.append(f"asymptotic ratio GCI32/(r21^p GCI21) = {ratio:.3g}, not within {ratio_tolerance:g} "
                            "of 1: the meshes may not be in the asymptotic range")
    p_exact = nan
    if exact is not None:
        d1, d2 = abs(phi1 - exact), abs(phi2 - exact)
        if d1 > 0 and d2 > 0:
            p_exact = math.log(d2 / d1) / math.log(r21)
    return GCIResult((h1, h2, h3), (phi1, phi2, phi3), r21, r32, eps21, eps32, s, p, phi_ext21, phi_ext32,
                     e_a21, e_a32, e_ext21, e_ext32, gci21, gci32, ratio, p_exact, tuple(warnings),
                     safety_factor, min(p, float(formal_order)) if widened else p)


@dataclass(frozen=True)
class QoI:
    """A quantity of interest read from a run's summary at its last converged step.

    ``probe:NAME:COMPONENT`` (displacement of a probe, COMPONENT x|y|z|0|1|2), ``reaction:BOUNDARY:COMPONENT``
    (force a Dirichlet boundary exerts on the body), ``energy[:KEY]`` (an energy of the step, KEY default
    strain_energy: strain_energy, active_energy, load_potential, total_potential, ...)."""

    kind: str
    name: str
    component: int | None = None

    @property
    def label(self) -> str:
        if self.kind == "energy":
            return f"energy:{self.name}"
        return f"{self.kind}:{self.name}:{'xyz'[self.component]}"  # type: ignore[index]

    @classmethod
    def parse(cls, text: str) -> QoI:
        """A QoI from its command-line form (ConfigError naming it when malformed)."""
        parts = text.strip().split(":")
        kind = parts[0]
        if kind == "energy" and len(parts) in (1, 2):
            return cls("energy", parts[1] if len(parts) == 2 and parts[1] else "strain_energy")
        if kind in ("probe", "reaction") and len(parts) == 3 and parts[1]:
            if parts[2].lower() not in _COMPONENTS:
                raise ConfigError(f"--qoi {text}: component {parts[2]!r} is not one of x, y, z, 0, 1, 2")
            return cls(kind, parts[1], _COMPONENTS[parts[2].lower()])
        raise ConfigError(f"--qoi {text}: write probe:NAME:COMPONENT, reaction:BOUNDARY:COMPONENT or energy[:KEY]")

    def value(self, step: Mapping[str, Any]) -> float:
        """The QoI's value in a converged step of summary.json (ConfigError naming what is missing)."""
        if self.kind == "energy":
            if step.get(self.name) is None:
                known = sorted(k for k in step if k.endswith("_energy") or k.endswith("_potential"))
                raise ConfigError(f"--qoi {self.label}: the run has no energy {self.name!r} "
                                  f"(it has {', '.join(known)})")
            return float(step[self.name])
        table = step.get("probes" if self.kind == "probe" else "reactions", {})
        if self.name not in table:
            what = "probe" if self.kind == "probe" else "Dirichlet boundary"
            raise ConfigError(f"--qoi {self.label}: no {what} {self.name!r} (the run has "
                              f"{', '.join(sorted(table)) or 'none'})")
        return float(table[self.name][self.component])


def _as_qoi(q: QoI | str) -> QoI:
    return q if isinstance(q, QoI) else QoI.parse(q)


@dataclass
class ConvergenceStudy:
    """A mesh-convergence study: ``meshes`` (a row per mesh, fine to coarse: the refined value (a list as JSON), h,
    cells, dofs, volume, wall time, status and a column per QoI label), ``results`` (QoI label -> GCIResult of the
    three finest meshes) and ``table`` (a row per QoI)."""

    meshes: pd.DataFrame
    results: dict[str, GCIResult]
    refine_key: str = ""
    formal_order: float | None = None
    files: dict[str, Path] = field(default_factory=dict)

    @classmethod
    def from_table(cls, meshes: pd.DataFrame, qois: Sequence[str], formal_order: float | None = None,
                   exact: Mapping[str, float] | None = None, refine_key: str = "",
                   ratio_tolerance: float = 0.1) -> ConvergenceStudy:
        """The analysis of a table with a column "h" and a column per QoI in ``qois`` (rows in any order; the
        three smallest h with finite values are used). ``exact``: known exact values by QoI label."""
        if "h" not in meshes:
            raise ValueError("the table needs a column 'h'")
        ordered = meshes.sort_values("h", kind="stable").reset_index(drop=True)
        results = {}
        for label in qois:
            if label not in ordered:
                raise ValueError(f"the table has no column {label!r}")
            rows = ordered[np.isfinite(ordered[label].to_numpy(dtype=float))]
            if len(rows) < 3:
                raise ValueError(f"{label}: three meshes with a value are needed, got {len(rows)}")
            finest = rows.iloc[:3]
            results[label] = gci(finest["h"].to_list(), finest[label].to_list(), formal_order,
                                 ratio_tolerance=ratio_tolerance, exact=(exact or {}).get(label))
        return cls(ordered, results, refine_key, formal_order)

    @property
    def table(self) -> pd.DataFrame:
        """A row per QoI: its label and GCIResult.as_dict()."""
        return pd.DataFrame([{"qoi": label, **r.as_dict()} for label, r in self.results.items()])

    @property
    def warnings(self) -> list[str]:
        return [f"{label}: {w}" for label, r in self.results.items() for w in r.warnings]

    def markdown(self) -> str:
        """The per-QoI tables (the quantities of Celik et al.'s Table 1) and the per-mesh table, as Markdown."""
        lines = ["# Mesh-convergence study", ""]
        if self.refine_key:
            lines += [f"Refined: `{self.refine_key}`; the three finest meshes give the order, extrapolation and GCI "
                      "(Celik et al. 2008). Relative errors and GCIs in percent.", ""]
        for label, r in self.results.items():
            rows = [("h1, h2, h3", ", ".join(_fmt(v) for v in r.h)), ("r21, r32", f"{r.r21:.4g}, {r.r32:.4g}"),
                    ("phi1, phi2, phi3", ", ".join(_fmt(v) for v in r.phi)), ("observed order p", f"{r.p:.4g}"),
                    ("phi_ext^21", _fmt(r.phi_ext21)), ("e_a^21 (%)", _pct(r.e_a21)),
                    ("e_ext^21 (%)", _pct(r.e_ext21)), ("GCI_fine^21 (%)", _pct(r.gci_fine21)),
                    ("GCI_medium^32 (%)", _pct(r.gci_medium32)),
                    ("GCI^32 / (r21^p GCI^21)", f"{r.asymptotic_ratio:.4g}")]
            if not math.isnan(r.p_exact):
                rows.append(("order against the exact value", f"{r.p_exact:.4g}"))
            lines += [f"## {label}", "", *_markdown_table(["quantity", "value"], rows), ""]
            lines += [f"- warning: {w}" for w in r.warnings] + ([""] if r.warnings else [])
        lines += ["## Meshes", ""]
        columns = list(self.meshes.columns)
        rows = [tuple(f"[{v}]({v}/summary.json)" if c == "folder" and isinstance(v, str) else _fmt(v)
                      for c, v in zip(columns, row)) for row in self.meshes.itertuples(index=False)]
        lines += _markdown_table(columns, rows)
        return "\n".join(lines) + "\n"

    def plot(self, path: Path) -> Path:
        """convergence.png: per QoI, |phi_k - phi_ext^21| / |phi_ext^21| against h (log-log) with the slope p
        drawn through the finest mesh."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        n = max(len(self.results), 1)
        fig, axes = plt.subplots(1, n, figsize=(4.5 * n, 4), squeeze=False)
        for ax, (label, r) in zip(axes[0], self.results.items()):
            h = self.meshes["h"].to_numpy(dtype=float)
            values = self.meshes[label].to_numpy(dtype=float)
            scale = abs(r.phi_ext21) if r.phi_ext21 not in (0.0,) and np.isfinite(r.phi_ext21) else 1.0
            err = np.abs(values - r.phi_ext21) / scale
            ok = np.isfinite(err) & (err > 0)
            if ok.any():
                ax.loglog(h[ok], err[ok], "o-", label="meshes")
            if np.isfinite(r.p) and ok.any():
                e1 = abs(r.phi[0] - r.phi_ext21) / scale
                hs = np.array([h[ok].min(), h[ok].max()])
                if e1 > 0:
                    ax.loglog(hs, e1 * (hs / r.h[0]) ** r.p, "k--", label=f"slope p = {r.p:.2f}")
                    if self.formal_order is not None:  # what the discretisation promises, through the same point
                        ax.loglog(hs, e1 * (hs / r.h[0]) ** self.formal_order, ":", color="C3",
                                  label=f"formal order {self.formal_order:g}")
            if not np.isfinite(r.p):
                ax.text(0.5, 0.5, "no observed order\n(see the warnings)", ha="center", va="center",
                        transform=ax.transAxes)
            ax.set_xlabel("h = (V / N_cells)^(1/3)")
            ax.set_ylabel("error estimate |phi - phi_ext| / |phi_ext|")
            ax.set_title(label)
            ax.grid(True, which="both", alpha=0.3)
            if ok.any():
                ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(path, dpi=100)
        plt.close(fig)
        return Path(path)

    def write(self, out: str | Path, comm: MPI.Comm = MPI.COMM_WORLD) -> dict[str, Path]:
        """convergence.csv, convergence_meshes.csv, convergence.md and convergence.png in ``out`` (rank 0 writes;
        the paths are returned on every rank)."""
        directory = Path(out)
        files = {"csv": directory / "convergence.csv", "meshes_csv": directory / "convergence_meshes.csv",
                 "markdown": directory / "convergence.md", "png": directory / "convergence.png"}
        if comm.rank == 0:
            directory.mkdir(parents=True, exist_ok=True)
            self.table.to_csv(files["csv"], index=False)
            self.meshes.to_csv(files["meshes_csv"], index=False)
            files["markdown"].write_text(self.markdown())
            self.plot(files["png"])
        comm.barrier()
        self.files = files
        return files


def _fmt(value: Any) -> str:
    if isinstance(value, (float, np.floating)):
        return "nan" if not np.isfinite(value) else f"{value:.6g}"
    return str(value)


def _pct(value: float) -> str:
    return "nan" if not np.isfinite(value) else f"{100 * value:.3g}"


def _markdown_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return out + ["| " + " | ".join(str(c).replace("|", "\\|") for c in row) + " |" for row in rows]


def parse_refine(text: str) -> tuple[str, list[Any]]:
    """"KEY=v1,v2,v3" (values as TOML) -> (KEY, [v1, v2, v3]); ConfigError naming it when malformed."""
    from model.config.overrides import parse_value, split_values

    key, sep, values = text.partition("=")
    if not sep or not key.strip() or not re.search(r"\S", values):
        raise ConfigError(f"--refine {text!r}: write KEY=V1,V2,V3, e.g. mesh.cells=4,8,16")
    parsed = [parse_value(v) for v in split_values(values)]
    return key.strip(), parsed


def converge(config: str | Path | Mapping[str, Any], refine: Mapping[str, Sequence[Any]],
             qois: Sequence[QoI | str], out: str | Path, *, overrides: Mapping[str, Any] | None = None,
             formal_order: float | None = None, base: str | Path = ".", ratio_tolerance: float = 0.1,
             comm: MPI.Comm = MPI.COMM_WORLD) -> ConvergenceStudy:
    """Run ``config`` (a TOML file, or a parsed document with paths relative to ``base``) once per value of the
    one key in ``refine`` (e.g. {"mesh.cells": [4, 8, 16]}; three values or more, with ``overrides`` applied
    to every run) into OUT/mesh_K, in this process, collectively over ``comm``; read each QoI at the last
    converged step; analyse the three finest meshes (ConvergenceStudy.from_table) and write the study's files
    into OUT. A run that fails gets status "failed" and NaN values (the analysis then uses the next meshes).
    Raises ConfigError on bad input (before any run where it can tell)."""
    from model.config import parse
    from model.config.document import read
    from model.config.overrides import apply
    from model.errors import SolveFailed
    from model.pipeline import run

    if len(refine) != 1:
        raise ConfigError(f"--refine: give exactly one key to refine, got {', '.join(refine) or 'none'}")
    (key, values), = refine.items()
    values = list(values)
    if len(values) < 3:
        raise ConfigError(f"--refine {key}: three values or more are needed, got {len(values)}")
    parsed = [_as_qoi(q) for q in qois]
    if not parsed:
        raise ConfigError("--qoi: name at least one quantity of interest")
    if isinstance(config, (str, Path)):
        raw, base = read(config), Path(config).parent
    else:
        raw, base = dict(config), Path(base)
    directory = Path(out)
    configs = [parse(apply(raw, {**(overrides or {}), key: v}), base) for v in values]  # every error first
    probes = {p.name for p in configs[0].probes}
    for q in parsed:
        if q.kind == "probe" and q.name not in probes:
            raise ConfigError(f"--qoi {q.label}: no probe {q.name!r} in the configuration (it has "
                              f"{', '.join(sorted(probes)) or 'none'})")
    records = []
    for k, (value, cfg) in enumerate(zip(values, configs)):
        record: dict[str, Any] = {key: value if isinstance(value, (int, float, str)) else json.dumps(value),
                                  "folder": f"mesh_{k}"}
        estimate = estimated_wall_time(key, values[:k], [r["wall_time_s"] for r in records], value)
        record["estimated_wall_time_s"] = estimate
        if estimate is not None and comm.rank == 0:
            log.info("mesh_%d (%s = %s): estimated %s from the previous meshes' wall times", k, key, value,
                     _duration(estimate))
        try:
            summary = run(cfg, directory / f"mesh_{k}", comm)
            status = summary["status"]
        except SolveFailed:
            summary = _read_summary(directory / f"mesh_{k}", comm)
            status = "failed"
        steps = [s for s in summary.get("steps", []) if s.get("converged")]
        volume = float(summary["region_volumes"]["all"])
        record.update(h=representative_h(volume, int(summary["cells"])), cells=int(summary["cells"]),
                      dofs=int(summary["dofs"]), volume=volume, wall_time_s=float(summary["wall_time_s"]),
                      status=status, load_factor=steps[-1]["load_factor"] if steps else math.nan)
        for q in parsed:
            record[q.label] = q.value(steps[-1]) if steps and status == "completed" else math.nan
        records.append(record)
    records = comm.bcast(records, root=0)  # one table on every rank (wall times are rank 0's)
    study = ConvergenceStudy.from_table(pd.DataFrame(records), [q.label for q in parsed], formal_order,
                                        refine_key=key, ratio_tolerance=ratio_tolerance)
    study.write(directory, comm)
    return study


def refinement_measure(key: str, value: Any) -> float | None:
    """A number proportional to a mesh's cell count from the refined key's value: a size (a key ending in "size")
    as size^-3, a cell count per edge as n^3, a list of counts as their product; None when it cannot tell."""
    try:
        if isinstance(value, (list, tuple)):
            return float(np.prod([float(v) for v in value]))
        number = float(value)
    except (TypeError, ValueError):
        return None
    if number <= 0:
        return None
    return number ** -3 if key.rsplit(".", 1)[-1].endswith("size") else number ** 3


def estimated_wall_time(key: str, previous: Sequence[Any], seconds: Sequence[float], value: Any) -> float | None:
    """The next mesh's wall time from the previous ones: wall time ~ N^b fitted through the last two meshes
    (N the refinement_measure of the key's value; b at least 1); None with fewer than two or no measure."""
    if len(previous) < 2:
        return None
    measures = [refinement_measure(key, v) for v in (*previous[-2:], value)]
    times = list(seconds[-2:])
    if any(m is None for m in measures) or any(not (t > 0) for t in times) or measures[0] == measures[1]:
        return None
    n0, n1, n2 = measures
    b = max(1.0, math.log(times[1] / times[0]) / math.log(n1 / n0))
    return float(times[1] * (n2 / n1) ** b)


def _duration(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.1f} min"


def _read_summary(directory: Path, comm: MPI.Comm) -> dict[str, Any]:
    text = (directory / "summary.json").read_text() if comm.rank == 0 else None
    return json.loads(comm.bcast(text, root=0))
