"""Boundary conditions that contradict each other, found before any solve.

Two kinds of contradiction are silent in a finite element code, and both are refused here with a one-line
ConfigError naming both keys:

1. **Two Dirichlet conditions on the same dof with different values.** dolfinx applies the conditions in turn,
   so the last one wins at the dofs they share (u_x = 0 and u_x = 0.1 on one face: the face moves by 0.1,
   and nothing says so). For every pair of conditions (a bone's attachment is one) and every component both
   prescribe, the values at their shared dofs are compared at two load factors, t = 1 and t = 0.5 (a value
   scaled by the load factor is t g(x); an expression of t is evaluated there):

       conflict  <=>  |g_a(x_d, t) - g_b(x_d, t)| > 1e-9 (max |g| + L 1e-12)   at some shared dof d,

   with L the body's size. Agreeing conditions are common and fine: a clamped face and a symmetry plane
   share the edge between them, both with u = 0.

2. **A load on a face whose loaded direction is prescribed.** A Dirichlet condition replaces the equation of
   its dofs, so a traction t (or a pressure p, whose reference traction is -p J F^-T N, along the face's normal N
   at rest) on the same facets loses its components along the prescribed directions: a traction plus u_x = 0 on
   one face drops t_x. Refused when the load and a condition share whole facets (an edge shared by a loaded
   face and a clamped one is ordinary: its nodes' share of the load goes into the reaction) and

       traction: some prescribed component c has |t_c| > 1e-12 |t|;
       pressure: some shared facet has sum over prescribed c of N_c^2 > 1e-6 (a roller support
                 u_y = 0 under a pressure along x keeps the whole load).

A condition restricted to ``points`` constrains single nodes, never whole facets: it takes part in 1, not 2.
Collective: every rank takes the same decision (the counts are summed over the ranks).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from model import compat
from model.errors import ConfigError
from model.problem.elasticity import DirichletBoundary, ElasticityProblem

#: relative tolerance of two prescribed values at a shared dof
VALUE_TOLERANCE = 1e-9
#: load factors at which two conditions are compared
COMPARED_AT = (1.0, 0.5)
AXES = "xyz"


@dataclass(frozen=True)
class Condition:
    """A Dirichlet condition and the configuration key that asked for it (``boundary[2]``)."""

    key: str
    entry: DirichletBoundary
    whole_facets: bool  # False: restricted to points


@dataclass(frozen=True)
class Load:
    """A traction (``vector``) or a pressure (``vector`` None) on boundary ``on``, from configuration ``key``."""

    key: str
    on: str
    vector: tuple[float, ...] | None


def _values(problem: ElasticityProblem, entry: DirichletBoundary, i: int, t: float) -> np.ndarray:
    """The prescribed values of component i of ``entry`` at load factor t, over the collapsed space's dofs."""
    f = entry.of_load_factor[i] if i < len(entry.of_load_factor) else None
    if f is None:
        return t * entry.reference[i]
    g = fem.Function(entry.values[i].function_space)
    with np.errstate(all="ignore"):  # a value outside the expression's domain is reported (_finite), not warned
        g.interpolate(lambda x: f(x, t))
    return g.x.array.copy()


def _size(problem: ElasticityProblem) -> float:
    msh = problem.domain.mesh
    comm = msh.comm
    x = msh.geometry.x
    low, high = np.empty(3), np.empty(3)
    comm.Allreduce(x.min(axis=0) if len(x) else np.full(3, np.inf), low, op=MPI.MIN)
    comm.Allreduce(x.max(axis=0) if len(x) else np.full(3, -np.inf), high, op=MPI.MAX)
    return float(np.linalg.norm(high - low))


def _dirichlet_pairs(problem: ElasticityProblem, conditions: Sequence[Condition]) -> None:
    comm = problem.domain.mesh.comm
    space = problem.displacement_space
    owned = space.dofmap.index_map.size_local * space.dofmap.index_map_bs
    size = _size(problem)
    coordinates = None
    for a, first in enumerate(conditions):
        for second in conditions[a + 1:]:
            for c in sorted(set(first.entry.components) & set(second.entry.components)):
                i, j = first.entry.components.index(c), second.entry.components.index(c)
                if i >= len(first.entry.collapsed) or j >= len(second.entry.collapsed):
                    continue  # an entry built without its collapsed dofs (guided simulation): nothing to compare
                shared, ia, ib = np.intersect1d(first.entry.dofs[i], second.entry.dofs[j], return_indices=True)
                keep = shared < owned
                shared, ia, ib = shared[keep], ia[keep], ib[keep]
                if comm.allreduce(len(shared), op=MPI.SUM) == 0:
                    continue
                worst, where, values = 0.0, None, None
                for t in COMPARED_AT:
                    ga = _values(problem, first.entry, i, t)[first.entry.collapsed[i][ia]]
                    gb = _values(problem, second.entry, j, t)[second.entry.collapsed[j][ib]]
                    scale = comm.allreduce(float(max(np.abs(ga).max(initial=0.0), np.abs(gb).max(initial=0.0))),
                                           op=MPI.MAX)
                    gap = np.abs(ga - gb)
                    tolerance = VALUE_TOLERANCE * (scale + 1e-12 * size)
                    if len(gap) and gap.max() > tolerance and gap.max() - tolerance > worst:
                        k = int(np.argmax(gap))
                        worst = float(gap.max() - tolerance)
                        if coordinates is None:
                            coordinates = first.entry.values[i].function_space.tabulate_dof_coordinates()
                        where = coordinates[first.entry.collapsed[i][ia[k]]]
                        values = (t, float(ga[k]), float(gb[k]))
                found = comm.allgather((worst, where, values))
                worst, where, values = max(found, key=lambda w: w[0])
                if where is None:
                    continue
                count = comm.allreduce(len(shared), op=MPI.SUM)
                t, va, vb = values
                point = "[" + ", ".join(f"{v:.4g}" for v in where) + "]"
                raise ConfigError(
                    f"{first.key} and {second.key}: both prescribe u_{AXES[c]} at {count} shared dofs of "
                    f"{first.entry.name!r} and {second.entry.name!r}, with different values (at {point}: {va:.6g} "
                    f"and {vb:.6g} at load factor {t:g}); the last would silently win: make them agree, or "
                    "restrict one with points")


def _facet_normals(problem: ElasticityProblem, facets: np.ndarray) -> np.ndarray:
    """Unit normals at rest of the given local facets (3D: triangles or quadrilaterals by their first three
    nodes; 2D: edges), one row per facet."""
    msh = problem.domain.mesh
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, 0)
    if len(facets) == 0:
        return np.zeros((0, 3))
    nodes = compat.entity_geometry(msh, tdim - 1, facets)
    x = msh.geometry.x[nodes]
    if tdim == 3:
        n = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    else:
        e = x[:, 1] - x[:, 0]
        n = np.stack([e[:, 1], -e[:, 0], np.zeros(len(e))], axis=1)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def _dropped_loads(problem: ElasticityProblem, conditions: Sequence[Condition], loads: Sequence[Load]) -> None:
    comm = problem.domain.mesh.comm
    domain = problem.domain
    gdim = problem.domain.mesh.geometry.dim
    for load in loads:
        loaded = domain.boundary_facets(load.on)
        for condition in conditions:
            if not condition.whole_facets:
                continue
            shared = np.intersect1d(loaded, domain.boundary_facets(condition.entry.name))
            if comm.allreduce(len(shared), op=MPI.SUM) == 0:
                continue
            fixed = [c for c in condition.entry.components if c < gdim]
            if load.vector is not None:
                t = np.asarray(load.vector[:gdim], dtype=float)
                dropped = [c for c in fixed if abs(t[c]) > 1e-12 * np.linalg.norm(t)]
                if not dropped:
                    continue
                what = f"its t_{'/'.join(AXES[c] for c in dropped)}"
            else:
                normals = _facet_normals(problem, shared)[:, fixed]  # collective (the connectivity), even if empty
                along = float((normals**2).sum(axis=1).max(initial=0.0))
                if comm.allreduce(along, op=MPI.MAX) <= 1e-6:
                    continue
                what = "the part of the pressure along the prescribed " + "/".join(AXES[c] for c in fixed)
            owned = problem.domain.mesh.topology.index_map(problem.domain.mesh.topology.dim - 1).size_local
            count = comm.allreduce(int(np.count_nonzero(shared < owned)), op=MPI.SUM)  # ghosts counted once
            raise ConfigError(
                f"{load.key} and {condition.key}: the load on {load.on!r} and the condition on "
                f"{condition.entry.name!r} share {count} facets, where u_{'/'.join(AXES[c] for c in fixed)} is "
                f"prescribed, so {what} would be silently dropped: load another boundary, or prescribe only the "
                "components the load does not act on")


def _finite(problem: ElasticityProblem, conditions: Sequence[Condition]) -> None:
    """ConfigError naming the condition and a node where its prescribed value is not a finite number (an expression
    such as log(x[0] - 1) outside its domain), at the load factors compared."""
    comm = problem.domain.mesh.comm
    for condition in conditions:
        entry = condition.entry
        for i, c in enumerate(entry.components):
            if i >= len(entry.collapsed):
                continue
            where = None
            for t in COMPARED_AT:
                values = _values(problem, entry, i, t)[entry.collapsed[i]]
                bad = np.flatnonzero(~np.isfinite(values))
                if len(bad) and where is None:
                    x = entry.values[i].function_space.tabulate_dof_coordinates()[entry.collapsed[i][bad[0]]]
                    where = (t, [float(v) for v in x], float(values[bad[0]]))
            found = [w for w in comm.allgather(where) if w is not None]
            if found:
                t, x, value = found[0]
                point = "[" + ", ".join(f"{v:.4g}" for v in x) + "]"
                raise ConfigError(f"{condition.key}: u_{AXES[c]} on {entry.name!r} is {value} at {point} at load "
                                  f"factor {t:g}: a prescribed value must be a finite number at every node")


def check_conditions(problem: ElasticityProblem, conditions: Sequence[Condition], loads: Sequence[Load]) -> None:
    """ConfigError (one line naming both keys) on two Dirichlet conditions that give one dof different values,
    or a load whose prescribed directions a Dirichlet condition on the same facets would drop (module
    docstring); (one line naming the key) on a prescribed value that is not finite. Collective."""
    _finite(problem, conditions)
    _dirichlet_pairs(problem, conditions)
    _dropped_loads(problem, conditions, loads)
