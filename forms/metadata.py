"""What a law's parameters mean: declarative metadata, its validation and its Markdown rendering.

A law is described by a ``LawEntry``: its name, its formula (one line, as energies.md writes it),
the fields it needs (S, a0, alpha), how its energy splits for the mixed formulation
(psi = W + (kappa/2) g(F)^2, forms.law), and per parameter a ``Parameter``:

    name      the key in a configuration (``mu``, ``lmbda``, ``c1`` ...)
    meaning   one line
    unit      dimension and SI unit, e.g. "Pa (stress)", "dimensionless"
    default   a number (or a word for a choice), or None: required
    allowed   the range, written as the law's ParameterError writes it: "> 0", ">= 0",
              "in (-1, 0.5)", "> -2 mu / 3"; "or inf (incompressible)" for a bulk parameter

``Parameter.check`` raises the same ParameterError as the built-in laws ("law: key = value, must
be allowed"); user laws (forms.user_law) are validated by it, the built-in laws by their own
``__post_init__`` (tests/test_law_registry.py checks that the two agree).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from forms.law import Law, require, require_bulk, require_finite

#: The fields a law may take besides its scalar parameters (energies.md), with their meaning.
FIELD_MEANINGS: dict[str, str] = {
    "S": "shape target: a symmetric positive definite 3x3 matrix per cell (dimensionless)",
    "a0": "unit fibre direction in the reference configuration (a 3-vector per cell)",
    "alpha": "activation in [0, 1] (dimensionless, per cell, a function of time)",
    "s0": "unit sheet direction in the reference configuration, orthogonal to a0 (a 3-vector per cell)",
}

#: The value shape of each field per cell (sample): a 3x3 matrix, a 3-vector or a scalar.
FIELD_SHAPES: dict[str, tuple[int, ...]] = {"S": (3, 3), "a0": (3,), "alpha": (), "s0": (3,)}


def format_number(value: Any) -> str:
    """A number as a reader writes it: 500, 0.05, 6.6, 3e5, 2.7e6, inf; anything else as str."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return str(value)
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    if value == int(value) and abs(value) < 1e4:
        return str(int(value))
    text = f"{value:.6e}" if value == int(value) else f"{value:.6g}"
    mantissa, _, exponent = text.partition("e")
    if not exponent:
        return mantissa
    if "." in mantissa:
        mantissa = mantissa.rstrip("0").rstrip(".")
    return f"{mantissa}e{int(exponent)}"


@dataclass(frozen=True)
class Parameter:
    """One parameter of a law: what it means, its unit, default and allowed range (module docstring).

    The range is ``lower``/``upper`` (None: unbounded), exclusive where ``lower_open``/``upper_open``;
    ``constraint`` replaces it when the bound depends on another parameter ("> -2 mu / 3", "> l_ofl"),
    ``choices`` when the value is a word. ``infinite``: +inf is accepted (a bulk parameter, the
    incompressible limit). ``applies`` says when the parameter is used ("isotropic = stvk").
    """

    name: str
    meaning: str
    unit: str
    default: float | str | None = None
    lower: float | None = None
    upper: float | None = None
    lower_open: bool = True
    upper_open: bool = True
    constraint: str = ""
    choices: tuple[str, ...] = ()
    infinite: bool = False
    applies: str = ""

    @property
    def required(self) -> bool:
        return self.default is None

    @property
    def interval(self) -> str:
        """The numeric range as the ParameterError writes it: "> 0", ">= 0", "in (-1, 0.5)", "finite"."""
        low, high = self.lower, self.upper
        if low is not None and high is not None:
            left, right = "(" if self.lower_open else "[", ")" if self.upper_open else "]"
            return f"in {left}{format_number(low)}, {format_number(high)}{right}"
        if low is not None:
            return f"{'>' if self.lower_open else '>='} {format_number(low)}"
        if high is not None:
            return f"{'<' if self.upper_open else '<='} {format_number(high)}"
        return "finite"

    @property
    def allowed(self) -> str:
        """The allowed values in words (the documentation's "allowed" column)."""
        if self.choices:
            return "one of " + ", ".join(self.choices)
        text = self.constraint or self.interval
        return f"{text}, or inf (incompressible)" if self.infinite else text

    def check(self, law: str, value: Any) -> None:
        """ParameterError "law: name = value, must be ..." unless ``value`` is allowed (numeric bounds only)."""
        if self.choices:
            require(value in self.choices, law, self.name, value, f"one of {', '.join(self.choices)}")
            return
        if self.infinite:
            require_bulk(law, **{self.name: value})
        else:
            require_finite(law, **{self.name: value})
        if self.lower is not None:
            ok = value > self.lower if self.lower_open else value >= self.lower
            require(ok, law, self.name, value, self.interval)
        if self.upper is not None:
            ok = value < self.upper if self.upper_open else value <= self.upper
            require(ok, law, self.name, value, self.interval)


@dataclass(frozen=True)
class LawEntry:
    """A law of the registry: metadata for documentation and validation, and the Law class it builds.

    ``make(**params)`` builds the law from parameters and fields by keyword (ParameterError naming the
    key otherwise). ``parameter_sets``: alternative sets of which exactly one must be given, e.g.
    (("E", "nu"), ("mu", "lmbda")), under ``sets_condition`` when not always. ``bulk_parameter`` is
    the parameter that sets kappa of psi = W + (kappa/2) g(F)^2, ``volume_constraint`` g(F) in words.
    ``source`` is the file of a user law (None for a built-in one).
    """

    name: str
    summary: str
    formula: str
    parameters: tuple[Parameter, ...]
    law: type[Law]
    fields: tuple[str, ...] = ()
    parameter_sets: tuple[tuple[str, ...], ...] = ()
    sets_condition: str = ""
    bulk_parameter: str | None = None
    volume_constraint: str = ""
    kappa: str = ""
    notes: tuple[str, ...] = ()
    source: str | None = None

    def make(self, **params: Any) -> Law:
        """The law built from its parameters (and fields: S, a0, alpha) by keyword."""
        return self.law.from_parameters(**params)  # type: ignore[attr-defined]

    def parameter(self, name: str) -> Parameter:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(f"{self.name} has no parameter {name!r}")

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    @property
    def defaults(self) -> dict[str, Any]:
        """{name: default} of the parameters that have one."""
        return {p.name: p.default for p in self.parameters if p.default is not None}

    def markdown(self, level: int = 3) -> str:
        """This law as Markdown: heading, formula, mixed split, fields, parameter sets and a parameter table."""
        lines = [f"{'#' * level} `{self.name}`", ""]
        if self.summary:
            lines += [self.summary, ""]
        lines += [f"    psi = {self.formula}", ""]
        facts = []
        if self.bulk_parameter:
            kappa = self.kappa or self.bulk_parameter
            kappa = "" if kappa == "kappa" else f", kappa = {kappa}"
            facts.append(f"Mixed split: psi = W + (kappa/2) g(F)^2 with g = {self.volume_constraint}{kappa}; "
                         f"`{self.bulk_parameter} = inf` is incompressible (mixed formulation only).")
        if self.fields:
            facts.append("Fields: " + "; ".join(f"`{f}`, {FIELD_MEANINGS[f]}" for f in self.fields) + ".")
        else:
            facts.append("Fields: none.")
        if self.parameter_sets:
            sets = " or ".join("(" + ", ".join(s) + ")" for s in self.parameter_sets)
            when = f" ({self.sets_condition})" if self.sets_condition else ""
            facts.append(f"Give either {sets}, not both{when}.")
        facts += list(self.notes)
        if self.source:
            facts.append(f"Defined in `{self.source}`.")
        lines += [" ".join(facts), ""]
        lines += ["| parameter | meaning | unit | default | allowed |", "|---|---|---|---|---|"]
        for p in self.parameters:
            default = _default_text(self, p)
            meaning = p.meaning + (f" (when {p.applies})" if p.applies else "")
            cells = [f"`{p.name}`", meaning, p.unit, default, p.allowed]
            lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
        return "\n".join(lines) + "\n"


def _default_text(entry: LawEntry, p: Parameter) -> str:
    if p.default is not None:
        return format_number(p.default)
    for group in entry.parameter_sets:
        if p.name in group:
            others = [n for n in group if n != p.name]
            return f"required (with {', '.join(others)})" if others else "required"
    return "required"


def laws_markdown(entries: Iterable[LawEntry], level: int = 2, intro: str = "") -> str:
    """The section "Laws and their parameters": per law its formula, fields and a table of parameters.

    Deterministic: the entries in the order given, numbers written by ``format_number``.
    """
    lines = [f"{'#' * level} Laws and their parameters", ""]
    if intro:
        lines += [intro, ""]
    text = "\n".join(lines) + "\n"
    return text + "\n".join(entry.markdown(level + 1) for entry in entries)


__all__ = ["FIELD_MEANINGS", "FIELD_SHAPES", "LawEntry", "Parameter", "format_number", "laws_markdown"]
