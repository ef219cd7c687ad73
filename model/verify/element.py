"""``verify element``: a user's element force vector and stiffness matrix against dolfinx on that one cell.

The reference (``element_reference``) is what dolfinx assembles from the project's own UFL forms on a
mesh of exactly the user's cell (MPI.COMM_SELF), with u interpolated from the nodal displacements:

    f_a = int_e P(F) : grad N_a dX,           F = I + grad u,  u = sum_a N_a u_a,  P = law.stress (forms/)
    K_ab = d f_a / d u_b = int_e grad N_a : A(F) : grad N_b dX,   A = dP/dF (ufl.derivative, never by hand)
    W = int_e psi(F) dX                       (the element energy: f = dW/du, K = d2W/du2)

f is the internal force, the gradient of the element energy (the residual of the elastic part, positive
when it pushes back against the displacement's direction of increasing energy); the elastic force of
graphics codes, -dW/du, is its negative, and so is their force Jacobian -K. K is symmetric.
Laws with a polar rotation use model.fields.polar.PolarField on the same quadrature points, as the
simulations and ``verify emit`` do.

Degrees of freedom are node-major: (u_x, u_y, u_z) of node 0, then of node 1, ...: f has 3n entries
f[3 a + i] = f_a,i and K[3 a + i, 3 b + j] = d f_a,i / d u_b,j, n the number of nodes.

Cells and node orderings (``node_order``: the user's numbering of the cell's nodes):

- ``tet4``: the 4-node tetrahedron, P1; nodes = vertices 0, 1, 2, 3 in every convention (VTK_TETRA = 10,
  gmsh type 4, basix/dolfinx). Default quadrature degree 1 (one point at the centroid: exact, the
  integrand is constant).
- ``tet10``: the 10-node tetrahedron, P2, isoparametric (the edge nodes may be moved off the midpoints: the
  geometry is P2 too). Vertices 0-3, then the edge nodes on the edges
    vtk (VTK_QUADRATIC_TETRA = 24):  4:(0,1) 5:(1,2) 6:(0,2) 7:(0,3) 8:(1,3) 9:(2,3)
    gmsh (type 11):                  4:(0,1) 5:(1,2) 6:(0,2) 7:(0,3) 8:(2,3) 9:(1,3)
    dolfinx (basix's P2):            4:(2,3) 5:(1,3) 6:(1,2) 7:(0,3) 8:(0,2) 9:(0,1)
  Default quadrature degree 2: basix's 4-point rule (points (a, a, a) and its permutations with b, a =
  (5 - sqrt 5)/20, b = 1 - 3 a, weights 1/24 of the reference volume 1/6), the usual rule of tet10 codes,
  exact for the linear-elastic stiffness of a straight-sided tet10. The integrand of a nonlinear law is not
  a polynomial: give the degree of your own rule (``quadrature_degree``, basix's default rule of that
  degree), or the rule itself (``quadrature`` = (points, weights), ``custom_rule``), to compare like
  with like.
- ``hex8``: the 8-node hexahedron, Q1 (trilinear), with 2x2x2 Gauss points (quadrature degree 3 in
  basix: Gauss-Jacobi = Gauss-Legendre with 2 points per direction, at (1 -+ 1/sqrt 3)/2 of [0, 1]).
    vtk (VTK_HEXAHEDRON = 12) and gmsh (type 5): 0:(0,0,0) 1:(1,0,0) 2:(1,1,0) 3:(0,1,0), then 4-7 the
      same on the face z = 1 (counter-clockwise around each face);
    dolfinx (basix, tensor-product): 0:(0,0,0) 1:(1,0,0) 2:(0,1,0) 3:(1,1,0) 4:(0,0,1) 5:(1,0,1)
      6:(0,1,1) 7:(1,1,1) (vtk nodes 2, 3 and 6, 7 swapped).
- an explicit permutation p (a sequence of n integers): dolfinx/basix node j is your node p[j].

The mesh is built in dolfinx's order from the permuted nodes, and the dofs dolfinx creates are matched
back to the user's nodes by their coordinates (so nothing depends on how dolfinx numbers the dofs).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from mpi4py import MPI


@dataclass(frozen=True)
class CellType:
    """A cell the checker knows: dolfinx's cell, the Lagrange degree, nodes and default quadrature degree."""

    name: str
    dolfinx_cell: str
    degree: int
    nodes: int
    quadrature_degree: int
    description: str


CELLS: dict[str, CellType] = {
    "tet4": CellType("tet4", "tetrahedron", 1, 4, 1, "4-node tetrahedron (P1), one quadrature point"),
    "tet10": CellType("tet10", "tetrahedron", 2, 10, 2, "10-node tetrahedron (P2, isoparametric), 4-point rule"),
    "hex8": CellType("hex8", "hexahedron", 1, 8, 3, "8-node hexahedron (Q1), 2x2x2 Gauss points"),
}

#: per cell and convention, p with dolfinx node j = the convention's node p[j]
NODE_ORDERS: dict[str, dict[str, tuple[int, ...]]] = {
    "tet4": {"vtk": (0, 1, 2, 3), "gmsh": (0, 1, 2, 3), "dolfinx": (0, 1, 2, 3)},
    "tet10": {"vtk": (0, 1, 2, 3, 9, 8, 5, 7, 6, 4), "gmsh": (0, 1, 2, 3, 8, 9, 5, 7, 6, 4),
              "dolfinx": tuple(range(10))},
    "hex8": {"vtk": (0, 1, 3, 2, 4, 5, 7, 6), "gmsh": (0, 1, 3, 2, 4, 5, 7, 6), "dolfinx": tuple(range(8))},
}

COMPONENTS = "xyz"

NodeOrder = str | Sequence[int]


def cell_type(cell: str) -> CellType:
    """The CellType of ``cell`` ("tet4", "tet10", "hex8"); ValueError naming it otherwise."""
    if cell not in CELLS:
        raise ValueError(f"cell = {cell!r}: unknown cell type (choose from {', '.join(CELLS)})")
    return CELLS[cell]


def node_permutation(cell: str, node_order: NodeOrder = "vtk") -> np.ndarray:
    """p with dolfinx/basix node j = the user's node p[j], for a named convention or an explicit permutation."""
    spec = cell_type(cell)
    if isinstance(node_order, str):
        orders = NODE_ORDERS[spec.name]
        if node_order not in orders:
            raise ValueError(f"node_order = {node_order!r}: unknown ordering (choose from {', '.join(orders)}, or a "
                             f"permutation of 0..{spec.nodes - 1})")
        return np.array(orders[node_order], dtype=np.int64)
    try:
        p = np.asarray(node_order)
        ok = p.shape == (spec.nodes,) and np.issubdtype(p.dtype, np.integer) and \
            sorted(p.tolist()) == list(range(spec.nodes))
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ValueError(f"node_order = {node_order!r}: not a permutation of 0..{spec.nodes - 1} (a {cell} has "
                         f"{spec.nodes} nodes)")
    return p.astype(np.int64)


def _nodal(values: Any, key: str, spec: CellType) -> np.ndarray:
    """(n, 3) nodal array from (n, 3) or node-major (3n,) input; ValueError naming ``key`` otherwise."""
    try:
        a = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{key}: not an array of numbers") from None
    if a.shape not in ((spec.nodes, 3), (3 * spec.nodes,)):
        raise ValueError(f"{key}: shape {a.shape}, a {spec.name} has {spec.nodes} nodes: expected ({spec.nodes}, 3) "
                         f"or ({3 * spec.nodes},)")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{key}: has entries that are not finite numbers")
    return a.reshape(spec.nodes, 3)


def quadrature_rule(cell: str, degree: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(points, weights) of basix's default rule of ``degree`` on the reference cell (the tetrahedron with
    vertices 0, e_x, e_y, e_z; the cube [0, 1]^3): the rule the reference uses (dolfinx's "default" scheme)."""
    import basix

    spec = cell_type(cell)
    degree = spec.quadrature_degree if degree is None else degree
    points, weights = basix.make_quadrature(getattr(basix.CellType, spec.dolfinx_cell), degree)
    return np.asarray(points), np.asarray(weights)


@dataclass(frozen=True)
class ElementReference:
    """The reference of one element: f (3n,), K (3n, 3n), W, in the user's node numbering (node-major)."""

    cell: str
    law: str
    node_order: tuple[int, ...]
    quadrature_degree: int | None  # None: the custom rule ``quadrature`` (points, weights)
    f: np.ndarray
    K: np.ndarray
    W: float
    parameters: dict[str, Any] = field(default_factory=dict)
    quadrature_points: int = 0
    #: quadrature points where the law's tangent A = dP/dF is undefined (Law.tangent_undefined: a breakpoint
    #: of a piecewise fibre curve, a rotation that is not unique); K is not a derivative there
    tangent_undefined: int = 0
    #: quadrature points where P itself is undefined (Law.stress_undefined: a rotation law where the polar
    #: rotation is not unique, psi has a kink there); f is not a derivative there
    stress_undefined: int = 0

    @property
    def quadrature(self) -> str:
        """The rule in words: "degree 2 (4 points)" or "custom rule of 5 points"."""
        if self.quadrature_degree is None:
            return f"custom rule of {self.quadrature_points} points"
        return f"degree {self.quadrature_degree} ({self.quadrature_points} points)"


def _quadrature_degree(spec: CellType, quadrature_degree: Any) -> int:
    if quadrature_degree is None:
        return spec.quadrature_degree
    if isinstance(quadrature_degree, bool) or not isinstance(quadrature_degree, (int, np.integer)) or \
            quadrature_degree < 1:
        raise ValueError(f"quadrature_degree = {quadrature_degree!r}: must be an integer >= 1")
    return int(quadrature_degree)


#: the reference cell's volume: the tetrahedron with vertices 0, e_x, e_y, e_z; the unit cube
REFERENCE_VOLUME = {"tetrahedron": 1.0 / 6.0, "hexahedron": 1.0}


def custom_rule(cell: str, points: Any, weights: Any) -> tuple[np.ndarray, np.ndarray]:
    """A quadrature rule of the user's own, validated: points (m, 3) in the reference cell (the tetrahedron
    with vertices 0, e_x, e_y, e_z, the same for vtk, gmsh and basix; the cube [0, 1]^3 of vtk and basix,
    gmsh's [-1, 1]^3 mapped by (xi + 1)/2), weights (m,) summing to its volume (1/6, 1)."""
    spec = cell_type(cell)
    try:
        p = np.asarray(points, dtype=np.float64)
        w = np.asarray(weights, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError("quadrature_points, quadrature_weights: not arrays of numbers") from None
    if p.ndim != 2 or p.shape[1] != 3 or len(p) == 0 or not np.all(np.isfinite(p)):
        raise ValueError(f"quadrature_points: shape {p.shape}, expected (m, 3) finite reference coordinates")
    if w.shape != (len(p),) or not np.all(np.isfinite(w)):
        raise ValueError(f"quadrature_weights: shape {w.shape}, expected ({len(p)},) finite numbers (one per point)")
    tol = 1e-12
    inside = np.all(p >= -tol, axis=1) & (np.all(p <= 1 + tol, axis=1) if spec.dolfinx_cell == "hexahedron"
                                          else p.sum(axis=1) <= 1 + tol)
    if not np.all(inside):
        i = int(np.flatnonzero(~inside)[0])
        raise ValueError(f"quadrature_points: point {i} {p[i].tolist()} lies outside the reference "
                         f"{spec.dolfinx_cell} (vertices 0, e_x, e_y, e_z; or [0, 1]^3)")
    volume = REFERENCE_VOLUME[spec.dolfinx_cell]
    if abs(w.sum() - volume) > 1e-12 * volume:
        raise ValueError(f"quadrature_weights: they sum to {w.sum():.15g}, must sum to the reference cell's volume "
                         f"{volume:.15g} (weights that sum to 1 on a tetrahedron: multiply them by 1/6)")
    return p, w


def _field_values(law: str, needed: tuple[str, ...], fields: Mapping[str, Any] | None
                 ) -> dict[str, np.ndarray]:
    """The value of each field the law takes, validated (shapes of forms.metadata.FIELD_SHAPES)."""
    from forms.metadata import FIELD_SHAPES

    fields = dict(fields or {})
    unknown = sorted(set(fields) - set(needed))
    if unknown:
        allowed = ", ".join(needed) if needed else "none"
        raise ValueError(f"fields: {law} does not take the field {unknown[0]!r} (its fields: {allowed})")
    out = {}
    for name in needed:
        if name not in fields:
            raise ValueError(f"fields: {law} needs the field {name!r} (shape {FIELD_SHAPES[name]})")
        try:
            value = np.asarray(fields[name], dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"fields: {name} is not an array of numbers") from None
        if value.shape != FIELD_SHAPES[name] and value.size == int(np.prod(FIELD_SHAPES[name])):
            value = value.reshape(FIELD_SHAPES[name])
        if value.shape != FIELD_SHAPES[name] or not np.all(np.isfinite(value)):
            raise ValueError(f"fields: {name} has shape {value.shape}, expected {FIELD_SHAPES[name]} finite numbers "
                             "(one value per element)")
        out[name] = value
    return out


class ElementAssembler:
    """One element's cell, law and quadrature, compiled once; ``assemble(u)`` gives f, K, W at many u.

    The generalisation of the one-tetrahedron assembler of ``verify seeds``: any cell of CELLS, any node
    numbering, fields as fem.Constants that ``assemble`` may change. Arguments as ``assemble_element``.
    """

    def __init__(self, law: str, params: Mapping[str, Any], X: np.ndarray, cell: str = "tet4",
                 fields: Mapping[str, Any] | None = None, node_order: NodeOrder = "vtk",
                 quadrature_degree: int | None = None, quadrature: tuple[Any, Any] | None = None) -> None:
        import ufl
        from dolfinx import fem

        import forms
        from model import compat
        from model.fields.polar import PolarField

        spec = self.spec = cell_type(cell)
        X = self.X = _nodal(X, "X", spec)
        self.perm = node_permutation(cell, node_order)
        degree = _quadrature_degree(spec, quadrature_degree)
        self.rule = None
        if quadrature is not None:
            if quadrature_degree is not None:
                raise ValueError("quadrature_degree, quadrature_points: give one of the two, not both")
            self.rule = custom_rule(cell, *quadrature)
        self.degree = None if self.rule is not None else degree
        self.law = law
        entry = forms.resolve_law(law)  # ParameterError naming the law when unknown
        scale = float(np.max(np.ptp(X, axis=0)))
        gaps = np.linalg.norm(X[:, None, :] - X[None, :, :], axis=2) + np.eye(spec.nodes) * (scale + 1.0)
        if scale == 0.0 or gaps.min() <= 1e-9 * scale:
            a, b = np.unravel_index(int(np.argmin(gaps)), gaps.shape)
            raise ValueError(f"X: nodes {min(a, b)} and {max(a, b)} coincide (a degenerate {cell})")

        cells = np.arange(spec.nodes, dtype=np.int64)[None, :]
        msh = self.mesh = compat.create_mesh(MPI.COMM_SELF, cells, X[self.perm], spec.degree, spec.dolfinx_cell)
        space = compat.function_space(msh, "Lagrange", spec.degree, (3,))
        # dof node d of the space -> the user's node, matched by position (the dof points are the geometry nodes)
        points = space.tabulate_dof_coordinates()[:, :3]
        distance = np.linalg.norm(points[:, None, :] - X[None, :, :], axis=2)
        user = np.argmin(distance, axis=1)
        if len(user) != spec.nodes or sorted(user.tolist()) != list(range(spec.nodes)) or \
                distance[np.arange(len(user)), user].max() > 1e-10 * scale:
            raise RuntimeError(f"{cell}: could not match dolfinx's dofs to the element's nodes by position")
        self.dof = (3 * user[:, None] + np.arange(3)).reshape(-1)  # the space's entry k is the user's entry dof[k]

        self.u = fem.Function(space)
        self._fields = dict(fields or {})
        self.constants = {name: fem.Constant(msh, value)
                          for name, value in _field_values(law, entry.fields, fields).items()}
        self.material = entry.make(**self.constants, **dict(params))
        F = ufl.Identity(3) + ufl.grad(self.u)
        R = None
        self.polar = None
        self.eigen = None
        if getattr(self.material, "needs_eigenbasis", False):  # per-point eigen state (forms.ogden)
            from model.fields.eigen import EigenField

            if self.rule is not None:
                raise ValueError(f"quadrature_points: {law} uses a per-point eigenbasis, stored at basix's default "
                                 "points; give quadrature_degree instead of a rule of your own")
            self.eigen = EigenField(msh, self.material.spectral_argument(F), degree,  # type: ignore[attr-defined]
                                    self.material.spectral_derivatives)  # type: ignore[attr-defined]
            self.material = self.material.with_eigenbasis(self.eigen.Q0, self.eigen.D)  # type: ignore[attr-defined]
        if self.material.needs_rotation:
            if self.rule is not None:
                raise ValueError(f"quadrature_points: {law} uses the polar rotation, stored at basix's default "
                                 "points; give quadrature_degree instead of a rule of your own")
            self.polar = PolarField(msh, self.material.rotation_argument(F), degree)
            R = self.polar.rotation
        metadata: dict[str, Any] = {"quadrature_degree": degree}
        if self.rule is not None:
            # tuples of Python floats: UFL puts str() of each value into the form's signature (the JIT cache key),
            # which is exact for a float (its repr) but rounds a numpy array to 8 digits
            metadata = {"quadrature_rule": "custom", "quadrature_degree": 1,
                        "quadrature_points": tuple(tuple(float(x) for x in point) for point in self.rule[0]),
                        "quadrature_weights": tuple(float(w) for w in self.rule[1])}
        dx = ufl.dx(domain=msh, metadata=metadata)
        try:
            residual = ufl.inner(self.material.stress(F, R), ufl.grad(ufl.TestFunction(space))) * dx
            with compat.self_jit_lock(msh.comm):
                self.forms = (fem.form(residual),
                              fem.form(ufl.derivative(residual, self.u, ufl.TrialFunction(space))),
                              fem.form(self.material.energy(F, R) * dx))
        except Exception as err:  # noqa: BLE001 -- a law of the user's own: one line naming it
            from model.verify.evaluator import compile_error, is_user_law

            if not is_user_law(law):
                raise
            raise ValueError(compile_error(law, err)) from None
        rule_points = self.rule[0] if self.rule is not None else compat.quadrature_points(msh, degree)
        self.num_points = len(rule_points)
        self._F_at_points = fem.Expression(F, np.asarray(rule_points, dtype=np.float64))

    def assemble(self, u: np.ndarray, fields: Mapping[str, Any] | None = None) -> ElementReference:
        """f, K, W at the nodal displacements u (n, 3) in the user's numbering; ``fields`` replace the values
        of the law's fields given so far."""
        from dolfinx import fem
        from dolfinx.fem import petsc as fem_petsc

        u = _nodal(u, "u", self.spec)
        if fields:
            values = _field_values(self.law, tuple(self.constants), {**self._fields, **fields})
            for name, value in values.items():
                self.constants[name].value[...] = value
            self._fields.update(fields)
        self.u.x.array[:] = u.reshape(-1)[self.dof]
        if self.polar is not None:
            self.polar.update()
        if self.eigen is not None:
            self.eigen.update()
        n = 3 * self.spec.nodes
        vector = fem_petsc.assemble_vector(self.forms[0])
        matrix = fem_petsc.assemble_matrix(self.forms[1])
        matrix.assemble()
        f = np.empty(n)
        K = np.empty((n, n))
        f[self.dof] = vector.array
        K[np.ix_(self.dof, self.dof)] = matrix.convert("dense").getDenseArray()
        vector.destroy()
        matrix.destroy()
        W = float(fem.assemble_scalar(self.forms[2]))
        from model import compat

        F = compat.evaluate(self._F_at_points, self.mesh, np.array([0], dtype=np.int32)).reshape(-1, 3, 3)
        fields = {name: np.broadcast_to(np.asarray(c.value), (len(F), *np.shape(c.value)))
                  for name, c in self.constants.items()}
        undefined = int(np.count_nonzero(self.material.tangent_undefined(F, **fields)))
        kinks = int(np.count_nonzero(self.material.stress_undefined(F, **fields)))
        return ElementReference(self.spec.name, self.law, tuple(int(i) for i in self.perm), self.degree, f, K, W,
                                self.material.parameters(), self.num_points, undefined, kinks)


def assemble_element(law: str, params: Mapping[str, Any], X: np.ndarray, u: np.ndarray, cell: str = "tet4",
                     fields: Mapping[str, Any] | None = None, node_order: NodeOrder = "vtk",
                     quadrature_degree: int | None = None,
                     quadrature: tuple[Any, Any] | None = None) -> ElementReference:
    """f, K and W of one element assembled by dolfinx (module docstring), in the user's node numbering.

    X, u: (n, 3) reference coordinates and displacements of the nodes in the user's numbering
    (``node_order``); ``fields``: the law's per-element constants (S (3,3), a0 (3,), s0 (3,), alpha ());
    ``quadrature_degree``: basix's default rule of that degree (default: the cell's, see CELLS);
    ``quadrature``: instead, a rule of your own, (points (m, 3), weights (m,)) on the reference cell
    (``custom_rule``; not for laws with a polar rotation, whose rotation lives on basix's default points).
    """
    spec = cell_type(cell)
    _nodal(X, "X", spec)
    _nodal(u, "u", spec)
    return ElementAssembler(law, params, X, cell, fields, node_order, quadrature_degree, quadrature).assemble(u)


def element_reference(law: str, params: Mapping[str, Any], X: np.ndarray, u: np.ndarray, cell: str = "tet4",
                      fields: Mapping[str, Any] | None = None, node_order: NodeOrder = "vtk",
                      quadrature_degree: int | None = None,
                      quadrature: tuple[Any, Any] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(f (3n,), K (3n, 3n)): f_a = int P : grad N_a dX, K = df/du, node-major, in the user's node numbering.

    See ``assemble_element`` for the arguments and the module docstring for cells, orderings and quadrature.
    """
    ref = assemble_element(law, params, X, u, cell, fields, node_order, quadrature_degree, quadrature)
    return ref.f, ref.K


# --- the user's element: files -------------------------------------------------------------------------------

@dataclass
class ElementInput:
    """An element as a user gives it (``load_element``)."""

    cell: str
    material: str | None
    params: dict[str, Any]
    fields: dict[str, np.ndarray]
    X: np.ndarray
    u: np.ndarray
    node_order: NodeOrder = "vtk"
    quadrature_degree: int | None = None
    f: np.ndarray | None = None
    K: np.ndarray | None = None
    W: float | None = None
    quadrature: tuple[np.ndarray, np.ndarray] | None = None  # a rule of the user's own (points, weights)


FILE_KEYS = ("cell", "node_order", "material", "params", "fields", "quadrature_degree", "quadrature_points",
             "quadrature_weights", "X", "u", "f", "K", "W")
FIELD_NAMES = ("S", "a0", "s0", "alpha")


def _read(source: Path | str | Mapping[str, Any]) -> tuple[str, dict[str, Any]]:
    """(name for messages, raw content) of an .npz or .json file, or of a dict of arrays."""
    if isinstance(source, Mapping):
        return "element", dict(source)
    path = Path(source)
    if path.suffix == ".npz":
        try:
            with np.load(path, allow_pickle=False) as data:
                content: dict[str, Any] = {k: data[k] for k in data.files}
        except (OSError, ValueError) as err:
            raise ValueError(f"{path}: cannot read as .npz ({err})") from None
        for key in ("params", "fields", "params_json", "fields_json", "node_order"):
            if key in content and content[key].dtype.kind in "US":
                text = str(content[key])
                if key == "node_order" and not text.lstrip().startswith("["):
                    content[key] = text
                    continue
                try:
                    content[key.removesuffix("_json")] = json.loads(text)
                except json.JSONDecodeError as err:
                    raise ValueError(f"{path}: {key}: invalid JSON ({err.msg} at column {err.colno})") from None
        return str(path), content
    if path.suffix == ".json":
        try:
            content = json.loads(path.read_text())
        except json.JSONDecodeError as err:
            raise ValueError(f"{path}: invalid JSON ({err.msg} at line {err.lineno}, column {err.colno})") from None
        if not isinstance(content, dict):
            raise ValueError(f"{path}: the JSON file must hold an object with the keys {', '.join(FILE_KEYS)}")
        return str(path), content
    raise ValueError(f"{path}: unknown file type {path.suffix!r} (an element file is .npz or .json)")


def load_element(source: Path | str | Mapping[str, Any], material: str | None = None,
                 params: Mapping[str, Any] | None = None, node_order: NodeOrder | None = None,
                 quadrature_degree: int | None = None) -> ElementInput:
    """An element from a file (.npz or .json) or a dict with the keys cell, node_order (default "vtk"),
    material, params, fields, quadrature_degree or quadrature_points and quadrature_weights (a rule of your own,
    ``custom_rule``), X, u and the user's f, K (and W); the arguments, when given, replace the file's values
    (a quadrature_degree argument replaces the file's rule too). ValueError naming the key for bad input."""
    name, raw = _read(source)
    if "cell" not in raw:
        raise ValueError(f"{name}: missing 'cell' (one of {', '.join(CELLS)})")
    cell = str(np.asarray(raw["cell"])) if not isinstance(raw["cell"], str) else raw["cell"]
    try:
        spec = cell_type(cell)
    except ValueError as err:
        raise ValueError(f"{name}: {err}") from None
    for key in ("X", "u"):
        if key not in raw:
            raise ValueError(f"{name}: missing array {key!r} (({spec.nodes}, 3) for a {cell})")
    mat = material if material is not None else raw.get("material")
    if mat is not None and not isinstance(mat, str):
        mat = str(np.asarray(mat))
    file_params = raw.get("params", {})
    if not isinstance(file_params, dict):
        raise ValueError(f"{name}: params must be an object of KEY: VALUE, not {type(file_params).__name__}")
    fields = raw.get("fields", {})
    if not isinstance(fields, dict):
        raise ValueError(f"{name}: fields must be an object of NAME: value, not {type(fields).__name__}")
    fields = {**fields, **{k: raw[k] for k in FIELD_NAMES if k in raw}}
    order = node_order if node_order is not None else raw.get("node_order", "vtk")
    if isinstance(order, np.ndarray):
        order = str(order) if order.dtype.kind in "US" else order.tolist()
    degree = quadrature_degree if quadrature_degree is not None else raw.get("quadrature_degree")
    if isinstance(degree, np.ndarray):
        degree = int(degree)
    rule = None
    given = [k for k in ("quadrature_points", "quadrature_weights") if k in raw]
    if given and quadrature_degree is None:
        if len(given) == 1:
            other = ({"quadrature_points", "quadrature_weights"} - set(given)).pop()
            raise ValueError(f"{name}: {given[0]} without {other}")
        if degree is not None:
            raise ValueError(f"{name}: quadrature_degree and quadrature_points: give one of the two, not both")
        rule = (raw["quadrature_points"], raw["quadrature_weights"])
    try:
        node_permutation(cell, order)
        X = _nodal(raw["X"], "X", spec)
        u = _nodal(raw["u"], "u", spec)
        _quadrature_degree(spec, degree)
        if rule is not None:
            rule = custom_rule(cell, *rule)
    except ValueError as err:
        raise ValueError(f"{name}: {err}") from None
    n = 3 * spec.nodes
    f = K = W = None
    if "f" in raw:
        f = np.asarray(raw["f"], dtype=np.float64)
        if f.shape not in ((n,), (spec.nodes, 3)):
            raise ValueError(f"{name}: f: shape {f.shape}, a {cell} has {n} dofs: expected ({n},) or ({spec.nodes}, 3)")
        f = f.reshape(n)
    if "K" in raw:
        K = np.asarray(raw["K"], dtype=np.float64)
        if K.shape != (n, n):
            raise ValueError(f"{name}: K: shape {K.shape}, a {cell} has {n} dofs: expected ({n}, {n})")
    if "W" in raw:
        W = float(np.asarray(raw["W"], dtype=np.float64))
    return ElementInput(cell, mat, {**file_params, **dict(params or {})}, fields, X, u, order, degree, f, K, W, rule)


# --- check ---------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ElementError:
    """The error of one quantity: Frobenius norms, relative to max(||ref||, floor); the worst entry."""

    quantity: str
    abs_error: float
    rel_error: float
    worst: str
    ok: bool


@dataclass(frozen=True)
class ElementReport:
    cell: str
    material: str
    node_order: str
    quadrature: str
    rtol: float
    rows: tuple[ElementError, ...]
    hints: tuple[str, ...]

    @property
    def ok(self) -> bool:
        return all(r.ok for r in self.rows)

    def format(self) -> str:
        lines = [f"element {self.cell}, law {self.material}, node order {self.node_order}, quadrature "
                 f"{self.quadrature}, rtol {self.rtol:g}; f = dW/du (internal force), K = df/du, node-major",
                 f"{'quantity':8} {'abs error':>11} {'rel error':>11}  result  worst entry"]
        for r in self.rows:
            lines.append(f"{r.quantity:8} {r.abs_error:11.3e} {r.rel_error:11.3e}  {'ok' if r.ok else 'FAIL':6}  "
                         f"{r.worst}")
        lines += [f"hint: {h}" for h in self.hints]
        return "\n".join(lines)


def _dof_name(i: int) -> str:
    return f"node {i // 3} {COMPONENTS[i % 3]}"


def _relative(user: np.ndarray, ref: np.ndarray, floor: float) -> float:
    return float(np.linalg.norm(user - ref) / max(np.linalg.norm(ref), floor, 1e-300))


def _error_row(name: str, user: np.ndarray, ref: np.ndarray, floor: float, rtol: float) -> ElementError:
    diff = np.abs(user - ref)
    rel = _relative(user, ref, floor)
    if not np.all(np.isfinite(user)):
        rel = np.inf
    i = np.unravel_index(int(np.nanargmax(np.where(np.isfinite(diff), diff, np.inf))), diff.shape) if diff.size \
        else ()
    if name == "f":
        worst = f"f[{i[0]}] ({_dof_name(i[0])}): yours {user[i]:.6e}, reference {ref[i]:.6e}"
    elif name == "K":
        worst = (f"K[{i[0]}, {i[1]}] (f of {_dof_name(i[0])} by u of {_dof_name(i[1])}): yours {user[i]:.6e}, "
                 f"reference {ref[i]:.6e}")
    else:
        worst = f"yours {float(user):.6e}, reference {float(ref):.6e}"
    return ElementError(name, float(np.linalg.norm(user - ref)), rel, worst, bool(rel <= rtol))


def _node_dofs(nodes: np.ndarray) -> np.ndarray:
    return (3 * np.asarray(nodes)[:, None] + np.arange(3)).reshape(-1)


def _hints(data: ElementInput, ref: ElementReference, rtol: float, floors: dict[str, float]) -> list[str]:
    """Why f or K disagree, when a simple transformation of the user's values makes them agree."""
    hints = []
    user = {q: getattr(data, q) for q in ("f", "K") if getattr(data, q) is not None}
    refs = {"f": ref.f, "K": ref.K}
    bad = {q for q, a in user.items() if _relative(a, refs[q], floors[q]) > rtol}
    if not bad:
        return hints
    for q in sorted(bad):
        a, r = user[q], refs[q]
        if _relative(-a, r, floors[q]) <= rtol:
            hints.append(f"{q} has the opposite sign: the reference is the internal force f = dW/du = int P : grad N "
                         "dX and its Jacobian K = df/du; elastic forces -dW/du (graphics codes) and their Jacobian are "
                         "the negatives")
            continue
        denom = float(np.vdot(r, r))
        c = float(np.vdot(a, r)) / denom if denom > 0 else 0.0
        if c != 0 and abs(c - 1) > rtol and _relative(a / c, r, floors[q]) <= max(rtol, 1e-12):
            hints.append(f"{q} is {c:.6g} times the reference (a constant factor: a modulus such as mu vs mu/2, the "
                         "element volume, or the quadrature weights)")
            continue
        n = len(ref.f) // 3
        blocked = (3 * (np.arange(3 * n) % n) + np.arange(3 * n) // n)  # component-major index -> node-major
        back = np.argsort(blocked)  # yours, component-major, put back into node-major order
        moved = a[np.ix_(back, back)] if q == "K" else a[back]
        if _relative(moved, r, floors[q]) <= rtol:
            hints.append(f"{q} agrees in component-major order (all x, then all y, then all z): the reference is "
                         "node-major (x, y, z of node 0, then node 1, ...)")
            continue
        if q == "K" and np.linalg.norm(a - a.T) > rtol * np.linalg.norm(a):
            hints.append(f"your K is not symmetric (||K - K^T|| / ||K|| = "
                         f"{np.linalg.norm(a - a.T) / np.linalg.norm(a):.2e}): the stiffness of a hyperelastic element "
                         "is the Hessian of its energy, symmetric (a transposed A = dP/dF in the assembly shows so)")
    # node renumbering: X and u in the stated order, f and K in another convention's
    stated = np.array(ref.node_order)
    named = data.node_order if isinstance(data.node_order, str) else "the given permutation"
    for other, p in NODE_ORDERS[ref.cell].items():
        p = np.array(p)
        if np.array_equal(p, stated):
            continue
        q_nodes = np.empty_like(p)
        q_nodes[p] = stated  # user's f, K in `other` numbering: f_out[p[j]] = f_ref[stated[j]]
        idx = _node_dofs(q_nodes)
        if all(_relative(user[q], refs[q][np.ix_(idx, idx)] if q == "K" else refs[q][idx], floors[q]) <= rtol
               for q in user):
            hints.append(f"f and K agree when their nodes are renumbered from {named} order (X, u) to {other} order: "
                         "your code returns them in another numbering than it reads the nodes")
    n = len(ref.f) // 3
    for i in range(n):
        for j in range(i + 1, n):
            nodes = np.arange(n)
            nodes[[i, j]] = [j, i]
            idx = _node_dofs(nodes)
            if all(_relative(user[q], refs[q][np.ix_(idx, idx)] if q == "K" else refs[q][idx], floors[q]) <= rtol
                   for q in user):
                hints.append(f"f and K agree with nodes {i} and {j} swapped")
    return hints


def _alternative_orders(data: ElementInput, ref: ElementReference, rtol: float, floors: dict[str, float]
                        ) -> list[str]:
    """Named conventions under which the reference of the same file agrees (the file's node_order is wrong)."""
    hints = []
    for other, p in NODE_ORDERS[ref.cell].items():
        if tuple(p) == ref.node_order:
            continue
        try:
            alt = assemble_element(ref.law, data.params, data.X, data.u, data.cell, data.fields, other,
                                   data.quadrature_degree, data.quadrature)
        except (ValueError, RuntimeError):
            continue
        refs = {"f": alt.f, "K": alt.K}
        if all(_relative(getattr(data, q), refs[q], floors[q]) <= rtol
               for q in ("f", "K") if getattr(data, q) is not None):
            hints.append(f"f and K agree with node_order = {other!r}: your element numbers its nodes as {other} does")
    return hints


def check_element(source: Path | str | Mapping[str, Any] | ElementInput, rtol: float = 1e-8,
                  material: str | None = None, params: Mapping[str, Any] | None = None,
                  node_order: NodeOrder | None = None, quadrature_degree: int | None = None) -> ElementReport:
    """Compare a user's element f, K (and W) with ``assemble_element`` of the same element.

    Errors are Frobenius norms: rel = ||yours - ref|| / max(||ref||, floor), floor = 1e-6 ||K_ref|| diam(X) for f
    (f vanishes at rest) and 0 for K and W; each row names its worst entry (node, component). When f or K
    is off, hints say whether the opposite sign, a constant factor, component-major order, a node renumbering
    or another node_order convention makes it agree. ValueError naming the key for bad input.
    """
    data = source if isinstance(source, ElementInput) else \
        load_element(source, material, params, node_order, quadrature_degree)
    if data.material is None:
        raise ValueError("material: the file has none; give --material (and --param)")
    if data.f is None and data.K is None:
        raise ValueError("f, K: the file holds neither the element vector f nor the matrix K to check")
    if not (isinstance(rtol, (int, float)) and rtol > 0):
        raise ValueError(f"rtol = {rtol!r}: must be a number > 0")
    ref = assemble_element(data.material, data.params, data.X, data.u, data.cell, data.fields, data.node_order,
                           data.quadrature_degree, data.quadrature)
    diam = float(np.max(np.linalg.norm(data.X[:, None] - data.X[None], axis=2)))
    floors = {"f": 1e-6 * float(np.linalg.norm(ref.K)) * diam, "K": 0.0, "W": 0.0}
    rows = []
    notes = []
    for q in ("f", "K", "W"):
        value = getattr(data, q)
        if q == "f" and value is not None and ref.stress_undefined:
            notes.append(f"f not checked: the stress of {data.material} is undefined at {ref.stress_undefined} of "
                         f"{ref.quadrature_points} quadrature points (Law.stress_undefined: psi has a kink where the "
                         "polar rotation is not unique); move u away from it to check f")
            continue
        if q == "K" and value is not None and ref.tangent_undefined:
            notes.append(f"K not checked: the tangent of {data.material} is undefined at {ref.tangent_undefined} of "
                         f"{ref.quadrature_points} quadrature points (Law.tangent_undefined: a breakpoint of a fibre "
                         "curve, or a rotation that is not unique); move u away from it to check K")
            continue
        if value is not None:
            rows.append(_error_row(q, np.asarray(value, dtype=np.float64), np.asarray(getattr(ref, q)), floors[q],
                                   rtol))
    if not any(r.quantity in ("f", "K") for r in rows):
        missing = "; and the file has no f" if data.f is None else ("; and the file has no K" if data.K is None
                                                                     else "")
        raise ValueError("; ".join(notes) + missing)
    hints: list[str] = []
    if not all(r.ok for r in rows if r.quantity in ("f", "K")):
        checked = replace(data, K=None) if notes else data
        hints = _hints(checked, ref, rtol, floors)
        hints += _alternative_orders(checked, ref, rtol, floors)
    order = data.node_order if isinstance(data.node_order, str) else str(list(data.node_order))
    return ElementReport(data.cell, data.material, order, ref.quadrature, rtol, tuple(rows), tuple(notes + hints))


def write_element_reference(source: Path | str | Mapping[str, Any], out: Path | str, material: str | None = None,
                            params: Mapping[str, Any] | None = None, node_order: NodeOrder | None = None,
                            quadrature_degree: int | None = None) -> ElementReference:
    """Write the reference f, K, W of an element file's cell, X, u (and law) to ``out`` (.npz or .json), in the
    element file layout (so a user sees the layout, and the written file passes ``check_element``)."""
    data = load_element(source, material, params, node_order, quadrature_degree)
    if data.material is None:
        raise ValueError("material: the file has none; give --material (and --param)")
    ref = assemble_element(data.material, data.params, data.X, data.u, data.cell, data.fields, data.node_order,
                           data.quadrature_degree, data.quadrature)
    out = Path(out)
    order = data.node_order if isinstance(data.node_order, str) else [int(i) for i in data.node_order]
    fields = {k: np.asarray(v, dtype=np.float64).tolist() for k, v in data.fields.items()}
    content = {"cell": data.cell, "node_order": order, "material": data.material, "params": ref.parameters,
               "fields": fields, "X": data.X.tolist(), "u": data.u.tolist(), "f": ref.f.tolist(), "K": ref.K.tolist(),
               "W": ref.W}
    if data.quadrature is not None:
        content["quadrature_points"] = data.quadrature[0].tolist()
        content["quadrature_weights"] = data.quadrature[1].tolist()
    else:
        content["quadrature_degree"] = ref.quadrature_degree
    if out.suffix == ".json":
        out.write_text(json.dumps(content, indent=1) + "\n")
    elif out.suffix == ".npz":
        arrays = {k: np.asarray(v) for k, v in content.items() if k not in ("params", "fields", "node_order")}
        np.savez(out, **arrays, params_json=np.array(json.dumps(ref.parameters, sort_keys=True)),
                 fields_json=np.array(json.dumps(fields)),
                 node_order=np.array(order if isinstance(order, str) else json.dumps(order)))
    else:
        raise ValueError(f"{out}: the reference is written as .npz or .json, not {out.suffix!r}")
    return ref


# --- command line ----------------------------------------------------------------------------------------------

HELP = """\
Check an element force vector f and stiffness matrix K against what dolfinx assembles on that one cell
from the project's UFL forms: f_a = int P : grad N_a dX (the internal force dW/du), K = df/du (node-major
dofs: x, y, z of node 0, then node 1, ...). Exit codes: 0 agrees, 1 out of tolerance, 2 bad input.

cells: tet4 (P1, 1 quadrature point), tet10 (P2 isoparametric, default quadrature degree 2: 4 points),
       hex8 (Q1, 2x2x2 Gauss points = quadrature degree 3)
node orders (--node-order, or node_order in the file; default vtk):
  tet4: vertices 0-3 in every convention
  tet10 edge nodes 4-9: vtk (0,1) (1,2) (0,2) (0,3) (1,3) (2,3); gmsh (0,1) (1,2) (0,2) (0,3) (2,3) (1,3);
        dolfinx (2,3) (1,3) (1,2) (0,3) (0,2) (0,1)
  hex8: vtk = gmsh: (0,0,0) (1,0,0) (1,1,0) (0,1,0), then the same at z = 1; dolfinx: tensor order
        (0,0,0) (1,0,0) (0,1,0) (1,1,0) (0,0,1) (1,0,1) (0,1,1) (1,1,1)
  or a permutation p (JSON list): dolfinx node j is your node p[j]
file (.json object or .npz arrays): cell, node_order, material, params (object; params_json in .npz),
  fields (S 3x3, a0 3, s0 3, alpha scalar: one value per element; arrays S, a0, ... in .npz),
  quadrature_degree (optional), or quadrature_points (m,3) and quadrature_weights (m) of your own rule on
  the reference cell (tetrahedron 0, e_x, e_y, e_z, weights summing to 1/6; cube [0,1]^3, summing to 1;
  not with laws that use the polar rotation), X (n,3) reference node coordinates, u (n,3) displacements,
  f (3n) and/or K (3n,3n) yours, W (optional, the element energy)
"""


def _parse_order(text: str | None) -> NodeOrder | None:
    if text is None or not text.strip().startswith("["):
        return text
    try:
        return [int(i) for i in json.loads(text)]
    except (json.JSONDecodeError, TypeError, ValueError):
        raise ValueError(f"--node-order {text!r}: a name (vtk, gmsh, dolfinx) or a JSON list of integers") from None


def add_parser(subparsers: Any) -> None:
    """``verify element FILE [--rtol] [--material] [--param KEY=VALUE] [--node-order] [--quadrature-degree]
    [--emit OUT]`` on the verify subcommands."""
    from model.helptext import Formatter
    from model.verify.commands import laws_help

    epilog = (laws_help("laws (--material NAME, or FILE.py:FUNCTION, a UFL energy of your own):")
              + "\nexit codes: 0 agrees, 1 out of tolerance, 2 bad input\n\nexamples:\n  softtissue verify element "
              "my_tet10.json\n  softtissue verify element my_hex8.npz --material neo_hookean --param mu=1 --param "
              "lmbda=10 --rtol 1e-10")
    parser = subparsers.add_parser("element", help="check an element's force vector f and stiffness matrix K "
                                   "(tet4, tet10, hex8) against dolfinx on that one cell", description=HELP,
                                   epilog=epilog, formatter_class=Formatter)
    parser.add_argument("file", type=Path, help="the element: .json or .npz (layout above)")
    parser.add_argument("--rtol", type=float, default=1e-8, help="relative Frobenius tolerance (default 1e-8)")
    parser.add_argument("--material", default=None, help="the law (a built-in name or FILE.py:FUNCTION), when the "
                        "file has none or to replace it")
    parser.add_argument("--param", action="append", default=[], metavar="KEY=VALUE",
                        help="a law parameter (numbers, or words such as isotropic=stvk); replaces the file's")
    parser.add_argument("--node-order", default=None, help="vtk, gmsh, dolfinx or a JSON permutation [p0, ...] "
                        "(replaces the file's node_order)")
    parser.add_argument("--quadrature-degree", type=int, default=None,
                        help="basix's default rule of this degree (default: tet4 1, tet10 2, hex8 3)")
    parser.add_argument("--emit", type=Path, default=None, metavar="OUT",
                        help="write the reference f, K, W for the file's element to OUT (.json or .npz) instead of "
                             "checking")


def main(args: argparse.Namespace) -> int:
    """Run ``verify element``: 0 agrees, 1 out of tolerance, 2 bad input ("error: ..." on stderr; rank 0 prints)."""
    import forms

    rank0 = MPI.COMM_WORLD.rank == 0
    try:
        from model.verify.commands import parse_params

        params = parse_params(args.param)
        order = _parse_order(args.node_order)
        if args.emit is not None:
            ref = write_element_reference(args.file, args.emit, args.material, params or None, order,
                                          args.quadrature_degree)
            if rank0:
                print(f"wrote {args.emit}: reference f ({len(ref.f)}), K ({len(ref.f)}x{len(ref.f)}), W of a "
                      f"{ref.cell} of {ref.law}, quadrature {ref.quadrature}")
            return 0
        report = check_element(args.file, args.rtol, args.material, params or None, order, args.quadrature_degree)
    except (ValueError, OSError, forms.ParameterError) as err:
        if rank0:
            print(f"error: {err}", file=sys.stderr)
        return 2
    if rank0:
        print(report.format())
    return 0 if report.ok else 1


__all__ = ["CELLS", "NODE_ORDERS", "CellType", "ElementAssembler", "ElementError",
            "ElementInput", "ElementReference", "ElementReport",
           "add_parser", "assemble_element", "cell_type", "check_element", "element_reference", "load_element",
           "main", "node_permutation", "quadrature_rule", "custom_rule", "write_element_reference"]
