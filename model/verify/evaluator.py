"""Reference values of psi, P = dpsi/dF and A = dP/dF of a law at many F, through UFL and dolfinx.

Each sample is one cell of a mesh of disjoint tetrahedra on MPI.COMM_SELF (at most CHUNK of them; more
samples are evaluated chunk by chunk through the same mesh and compiled Expressions); F and the law's fields
(forms.metadata.FIELD_SHAPES: S (3,3), a0 (3,), s0 (3,), alpha ()) are DG0 functions, and psi,
P = law.stress(F) and A = ufl.diff(P, F) are dolfinx Expressions evaluated at the cell's one
quadrature point. Laws with a polar rotation use the simulations' quadrature-point machinery
(model.fields.polar.PolarField; model.fields.eigen.EigenField for ogden).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

import forms
from forms.law import Law, with_parameter_values
from forms.metadata import FIELD_SHAPES
from model import compat
from model.fields.eigen import EigenField
from model.fields.polar import PolarField

#: The quantities of a check, and their value shape per sample.
QUANTITIES = ("psi", "P", "A")
SHAPES: dict[str, tuple[int, ...]] = {"psi": (), "P": (3, 3), "A": (3, 3, 3, 3)}
#: samples per chunk of ReferenceEvaluator.evaluate: the most cells of its mesh (read when an evaluator is made)
CHUNK = 1024


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
    """psi, P, A of a law at many F (and per-sample fields), through UFL and dolfinx, in chunks.

    The mesh holds C = min(num_samples, CHUNK) disjoint tetrahedra (at least one), built and compiled
    once; ``evaluate`` takes any number M of samples and runs ceil(M / C) chunks through it, the last
    one padded with F = I and the chunk's first sample's fields (the padding is evaluated and
    discarded). Creating a mesh grows faster than linearly in its cells; the chunks keep the time
    linear in M. ``num_samples`` is only the size hint of the mesh.
    """

    def __init__(self, material: str, params: dict[str, Any], num_samples: int,
                 runtime_parameters: bool = False) -> None:
        """``runtime_parameters``: every finite number parameter of the law is held by a fem.Constant
        (forms.law.with_parameter_values), so that ``set_parameters`` changes it without compiling again
        (the diagnosis's parameter fit); ValueError when the law's parameters cannot be held so (numbers
        computed outside UFL, e.g. an eigen state)."""
        entry = forms.resolve_law(material)  # ParameterError naming the law when unknown
        self.material = material
        self.num_samples = num_samples
        #: samples per chunk: the cells of the mesh
        self.chunk = n = max(1, min(int(num_samples), int(CHUNK)))
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
        self.numeric_law = self.law
        self.constants: dict[str, tuple[fem.Constant, float]] = {}
        if runtime_parameters:
            self._hold_parameters()
        Fv = ufl.variable(self.F)
        self._Fv = Fv
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
        self._points = points
        self._terms: tuple[list[str], dict[str, Any]] | None = None
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
        self._place_samples(self.order)

    def _place_samples(self, order: np.ndarray) -> None:
        """Sample order[c] (a row of a chunk) in local cell c: the sample held by each DG0 dof, and the cell
        (row of an Expression's values) of each sample. Every DG0 space of the mesh numbers its dofs alike
        (one per cell, in blocks of the value size)."""
        self.order = np.asarray(order, dtype=np.int64)
        dofs = compat.cell_dofs(self.F.function_space.dofmap)[:, 0]
        self._dof_sample = np.empty(self.chunk, dtype=np.int64)
        self._dof_sample[dofs] = self.order
        self._sample_cell = np.empty(self.chunk, dtype=np.int64)
        self._sample_cell[self.order] = np.arange(self.chunk)

    def _set(self, function: fem.Function, values: np.ndarray) -> None:
        """function <- values (chunk, *shape) by sample: the dof of the cell of sample s gets values[s]."""
        size = function.function_space.dofmap.index_map_bs
        function.x.array[:] = values.reshape(self.chunk, size)[self._dof_sample].reshape(-1)

    def _as_samples(self, name: str, values: Any, m: int, shape: tuple[int, ...]) -> np.ndarray:
        """``values`` as (m, *shape) float64 (one value of ``shape`` is used for every sample), or ValueError."""
        array = np.asarray(values, dtype=np.float64)
        size = int(np.prod(shape, dtype=int))
        if array.shape == shape and m != 1:
            array = np.broadcast_to(array, (m, *shape))
        if array.size != m * size:
            raise ValueError(f"{self.material}: {name} of shape {array.shape} for {m} samples of F; expected "
                             f"{(m, *shape)}")
        return array.reshape(m, *shape)

    def evaluate(self, F: np.ndarray, **fields: np.ndarray) -> dict[str, np.ndarray]:
        """{'psi': (M,), 'P': (M,3,3), 'A': (M,3,3,3,3)} at the given F (M,3,3) and fields (M, *shape), for any M.

        Chunk by chunk of ``self.chunk`` samples: F and the fields are written into the DG0 functions,
        the polar rotation (PolarField.update) and the eigen state (EigenField.update) are refreshed
        from them, and psi, P = law.stress(F), A = dP/dF are evaluated at every cell.
        """
        F, given = self._given(F, fields)
        return self._run({name: (self.expressions[name], SHAPES[name]) for name in QUANTITIES}, F, given)

    def _run(self, expressions: dict[str, tuple[Any, tuple[int, ...]]], F: np.ndarray,
             given: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Each Expression (value shape ``shape``) at every sample of F (M,3,3), chunk by chunk."""
        m = len(F)
        out = {name: np.empty((m, *shape)) for name, (_, shape) in expressions.items()}
        c = self.chunk
        for start in range(0, m, c):
            k = min(c, m - start)
            F_chunk = F[start:start + k]
            chunk_fields = {name: value[start:start + k] for name, value in given.items()}
            if k < c:  # padding: F = I with the chunk's first sample's fields
                F_chunk = np.concatenate([F_chunk, np.broadcast_to(np.eye(3), (c - k, 3, 3))])
                chunk_fields = {name: np.concatenate([value, np.broadcast_to(value[0], (c - k, *value.shape[1:]))])
                                for name, value in chunk_fields.items()}
            self._set(self.F, F_chunk)
            for name, function in self.fields.items():
                self._set(function, chunk_fields[name])
            if self.polar is not None:
                self.polar.update()
            if self.eigen is not None:
                self.eigen.update()
            rows = self._sample_cell[:k]
            for name, (expression, shape) in expressions.items():
                values = compat.evaluate(expression, self.mesh, self.cells)
                out[name][start:start + k] = values.reshape(c, *shape)[rows]
        return out

    def _given(self, F: np.ndarray, fields: dict[str, Any]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """F as (M, 3, 3) and every field of the law as (M, *shape) (one value: for every sample); ValueError
        naming what is missing or of the wrong shape."""
        F = np.asarray(F, dtype=np.float64)
        if F.size % 9:
            raise ValueError(f"{self.material}: F of shape {F.shape}; expected (M, 3, 3)")
        F = F.reshape(-1, 3, 3)
        given = {}
        for name in self.fields:
            if name not in fields:
                raise ValueError(f"{self.material} needs the field {name}")
            given[name] = self._as_samples(name, fields[name], len(F), FIELD_SHAPES[name])
        return F, given

    # --- the diagnosis's parameter fit and energy terms (model.verify.diagnosis) ---------------------------

    def _hold_parameters(self) -> None:
        numbers = {}
        for f in dataclasses.fields(self.law) if dataclasses.is_dataclass(self.law) else ():
            value = getattr(self.law, f.name)
            if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value):
                numbers[f.name] = float(value)
        if not numbers:
            raise ValueError(f"{self.material}: no number parameter to hold as a runtime value")
        self.constants = {name: (fem.Constant(self.mesh, value), value) for name, value in numbers.items()}
        self.law = with_parameter_values(self.law, {name: (c, [value]) for name, (c, value) in self.constants.items()})

    def set_parameters(self, values: dict[str, float]) -> None:
        """The runtime parameters (``runtime_parameters``) at ``values``, the others at the law's own numbers."""
        for name, (constant, own) in self.constants.items():
            constant.value = float(values.get(name, own))

    def energy_terms(self) -> list[str]:
        """The addends of the law's energy psi = sum_k psi_k (its top-level sums, UFL), described: "term k of K"
        and, when psi_k depends on a field, which ("a fibre term: it depends on a0"). Empty for a law whose
        P is not d psi_k / dF term by term (a polar rotation, an eigen state)."""
        return self._energy_terms()[0]

    def _energy_terms(self) -> tuple[list[str], dict[str, Any]]:
        if self._terms is not None:
            return self._terms
        self._terms = ([], {})
        if self.polar is not None or self.eigen is not None:
            return self._terms
        Fv = self._Fv
        try:
            psi = self.law.energy(Fv, None)
        except Exception:  # noqa: BLE001 -- the diagnosis goes on without the law's terms
            return self._terms
        addends = _addends(psi)
        F_coefficient = self.F
        fields = {function: name for name, function in self.fields.items()}
        kept, names = [], []
        for term in addends:
            coefficients = ufl.algorithms.extract_coefficients(term)
            if F_coefficient not in coefficients:
                continue
            on = sorted(fields[c] for c in coefficients if c in fields)
            kept.append(term)
            names.append(on)
        if len(kept) < 2:
            return self._terms
        count = len(kept)
        described = []
        for k, on in enumerate(names):
            text = f"term {k + 1} of {count} of the law's energy"
            if "a0" in on or "s0" in on:
                text += f" (a fibre term: it depends on {', '.join(on)})"
            elif on:
                text += f" (it depends on {', '.join(on)})"
            described.append(text)
        P = [ufl.diff(t, Fv) for t in kept]
        A = [ufl.diff(Pk, Fv) for Pk in P]
        try:
            with compat.self_jit_lock(self.mesh.comm):
                expressions = {"psi": (fem.Expression(ufl.as_vector(kept), self._points), (count,)),
                               "P": (fem.Expression(ufl.as_tensor(P), self._points), (count, 3, 3)),
                               "A": (fem.Expression(ufl.as_tensor(A), self._points), (count, 3, 3, 3, 3))}
        except Exception:  # noqa: BLE001 -- the diagnosis goes on without the law's terms
            return self._terms
        self._terms = (described, expressions)
        return self._terms

    def evaluate_terms(self, F: np.ndarray, **fields: np.ndarray) -> dict[str, np.ndarray]:
        """{'psi': (M,K), 'P': (M,K,3,3), 'A': (M,K,3,3,3,3)}: each term of ``energy_terms`` and its derivatives."""
        _, expressions = self._energy_terms()
        if not expressions:
            return {}
        F, given = self._given(F, fields)
        return self._run(expressions, F, given)

    def tangent_undefined(self, F: np.ndarray, **fields: np.ndarray) -> np.ndarray:
        """(N,) bool: the law's own statement of where A = dP/dF does not exist (forms.law.Law.tangent_undefined)."""
        return np.asarray(self.law.tangent_undefined(np.reshape(F, (-1, 3, 3)), **fields), dtype=bool)

    def stress_undefined(self, F: np.ndarray, **fields: np.ndarray) -> np.ndarray:
        """(N,) bool: where P = dpsi/dF does not exist (forms.law.Law.stress_undefined: a rotation law where
        the polar rotation is not unique)."""
        return np.asarray(self.law.stress_undefined(np.reshape(F, (-1, 3, 3)), **fields), dtype=bool)

    def parameters(self) -> dict[str, Any]:
        return self.numeric_law.parameters()


def _addends(expression: Any) -> list[Any]:
    """The operands of the top-level sums of a UFL scalar: a + (b + c) -> [a, b, c]."""
    if isinstance(expression, ufl.classes.Sum):
        return [t for operand in expression.ufl_operands for t in _addends(operand)]
    return [expression]


def reference(material: str, params: dict[str, Any], F: np.ndarray, **fields: np.ndarray) -> dict[str, np.ndarray]:
    """psi, P, A of ``material`` at F (N,3,3) with its fields (e.g. S), through the UFL forms."""
    F = np.asarray(F, dtype=np.float64).reshape(-1, 3, 3)
    return ReferenceEvaluator(material, params, len(F)).evaluate(F, **fields)
