"""Reference values of psi, P = dpsi/dF and A = dP/dF of a law at many F, through UFL and dolfinx.

Each sample is one cell of a mesh of N disjoint tetrahedra on MPI.COMM_SELF; F and the law's fields
(forms.metadata.FIELD_SHAPES: S (3,3), a0 (3,), s0 (3,), alpha ()) are DG0 functions, and psi,
P = law.stress(F) and A = ufl.diff(P, F) are dolfinx Expressions evaluated at the cell's one
quadrature point. Laws with a polar rotation use the simulations' quadrature-point machinery
(model.fields.polar.PolarField; model.fields.eigen.EigenField for ogden).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

import forms
from forms.law import Law
from forms.metadata import FIELD_SHAPES
from model import compat
from model.fields.eigen import EigenField
from model.fields.polar import PolarField

#: The quantities of a check, and their value shape per sample.
QUANTITIES = ("psi", "P", "A")
SHAPES: dict[str, tuple[int, ...]] = {"psi": (), "P": (3, 3), "A": (3, 3, 3, 3)}


def law_fields(material: str) -> tuple[str, ...]:
    """The fields a law takes: a built-in's name, or "FILE.py:FUNCTION" for a law of the user's own."""
    return forms.resolve_law(material).fields


def is_user_law(material: str) -> bool:
    """True for "FILE.py:FUNCTION", a law of the user's own (forms/user_law.py)."""
    return ".py:" in material


def compile_error(material: str, err: BaseException) -> str:
    """One line for an energy of the user's own that UFL cannot differentiate or FFCx cannot compile to C."""
    first = str(err).strip().splitlines()[0] if str(err).strip() else ""
    return (f"{material}: the energy does not compile (UFL/FFCx {type(err).__name__}: {first}); write it with "
            "UFL operators FFCx translates to C (+ - * / **, sqrt, exp, ln, cos, sin, ..., conditional, "
            "det, inv, tr, inner, dot)")


class ReferenceEvaluator:
    """psi, P, A of a law at many F (and per-sample fields), through UFL and dolfinx."""

    def __init__(self, material: str, params: dict[str, Any], num_samples: int) -> None:
        entry = forms.resolve_law(material)  # ParameterError naming the law when unknown
        self.material = material
        self.num_samples = n = num_samples
        reference_tet = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
        x = np.tile(reference_tet, (n, 1))
        cells = np.arange(4 * n, dtype=np.int64).reshape(n, 4)
        self.mesh = compat.create_mesh(MPI.COMM_SELF, cells, x)
        # dolfinx may renumber cells: the sample of local cell c is original_cell_index[c]
        self.order = np.asarray(self.mesh.topology.original_cell_index, dtype=np.int64)
        self.F = fem.Function(compat.function_space(self.mesh, "DG", 0, (3, 3)), name="F")
        self.fields: dict[str, fem.Function] = {}
        for name in entry.fields:
            space = compat.function_space(self.mesh, "DG", 0, FIELD_SHAPES[name])
            self.fields[name] = fem.Function(space, name=name)
        self.law: Law = entry.make(**self.fields, **params)
        Fv = ufl.variable(self.F)
        self.eigen = None
        if getattr(self.law, "needs_eigenbasis", False):  # per-point eigen state (forms.ogden)
            self.eigen = EigenField(self.mesh, self.law.spectral_argument(Fv), 1,  # type: ignore[attr-defined]
                                    self.law.spectral_derivatives)  # type: ignore[attr-defined]
            self.law = self.law.with_eigenbasis(self.eigen.Q0, self.eigen.D)  # type: ignore[attr-defined]
        R = None
        self.polar = None
        if self.law.needs_rotation:
            self.polar = PolarField(self.mesh, self.law.rotation_argument(Fv), 1)
            R = self.polar.rotation
        points = compat.quadrature_points(self.mesh, 1)
        try:
            psi = self.law.energy(Fv, R)
            P = self.law.stress(Fv, R)
            A = ufl.diff(P, Fv)
            with compat.self_jit_lock(self.mesh.comm):
                self.expressions = {"psi": fem.Expression(psi, points), "P": fem.Expression(P, points),
                                    "A": fem.Expression(A, points)}
        except Exception as err:  # noqa: BLE001 -- a law of the user's own: one line naming it
            if not is_user_law(material):
                raise
            raise forms.ParameterError(compile_error(material, err)) from None
        self.cells = np.arange(n, dtype=np.int32)

    def _set(self, function: fem.Function, values: np.ndarray) -> None:
        size = function.function_space.dofmap.index_map_bs
        values = np.asarray(values, dtype=np.float64).reshape(self.num_samples, size)
        function.x.array[:] = values[self.order].reshape(-1)

    def evaluate(self, F: np.ndarray, **fields: np.ndarray) -> dict[str, np.ndarray]:
        """{'psi': (N,), 'P': (N,3,3), 'A': (N,3,3,3,3)} at the given F (N,3,3) and fields."""
        self._set(self.F, F)
        for name, function in self.fields.items():
            if name not in fields:
                raise ValueError(f"{self.material} needs the field {name}")
            self._set(function, fields[name])
        if self.polar is not None:
            self.polar.update()
        if self.eigen is not None:
            self.eigen.update()
        inverse = np.empty_like(self.order)
        inverse[self.order] = np.arange(self.num_samples)
        out = {}
        for name in QUANTITIES:
            values = compat.evaluate(self.expressions[name], self.mesh, self.cells)
            out[name] = values.reshape(self.num_samples, *SHAPES[name])[inverse]
        return out

    def tangent_undefined(self, F: np.ndarray, **fields: np.ndarray) -> np.ndarray:
        """(N,) bool: the law's own statement of where A = dP/dF does not exist (forms.law.Law.tangent_undefined)."""
        return np.asarray(self.law.tangent_undefined(np.reshape(F, (-1, 3, 3)), **fields), dtype=bool)

    def stress_undefined(self, F: np.ndarray, **fields: np.ndarray) -> np.ndarray:
        """(N,) bool: where P = dpsi/dF does not exist (forms.law.Law.stress_undefined: a rotation law where
        the polar rotation is not unique)."""
        return np.asarray(self.law.stress_undefined(np.reshape(F, (-1, 3, 3)), **fields), dtype=bool)

    def parameters(self) -> dict[str, Any]:
        return self.law.parameters()


def reference(material: str, params: dict[str, Any], F: np.ndarray, **fields: np.ndarray) -> dict[str, np.ndarray]:
    """psi, P, A of ``material`` at F (N,3,3) with its fields (e.g. S), through the UFL forms."""
    F = np.asarray(F, dtype=np.float64).reshape(-1, 3, 3)
    return ReferenceEvaluator(material, params, len(F)).evaluate(F, **fields)
