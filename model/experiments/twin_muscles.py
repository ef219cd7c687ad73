"""Curved bellies in contact (issue 14 item 3; docs/layers.md "Curved bellies in contact"; examples/twin_muscles.toml).

Two fusiform muscles side by side (meshes.twin_muscles: a the mirror image of b about x = 0, node for node), both
activated alike with their ends clamped: the bellies bulge sideways, close the gap between them and press against
each other. The contact is frictionless penalty contact both ways (:data:`PAIRS`: a_lateral's nodes against
b_lateral's triangles and b_lateral's nodes against a_lateral's), the energy

    Pi_c = sum over both pairs of int_slave (k/2) min(g, 0)^2 dA   (nodal rule, g the signed distance to the
                                                                    paired deformed master triangle's plane),

a pair of pairs that the mirror maps onto itself: the answer is mirror-symmetric, u_a(-x, y, z) = M u_b(x, y, z),
M = diag(-1, 1, 1), and the contact surface is the plane x = 0. So each muscle presses on that plane as on a rigid
frictionless wall (:func:`plane_raw`: the same mesh and loads, the pairs replaced by each muscle's lateral surface
against the rigid plane x = 0, obstacle = "plane", penalty k_w, the nodal rule). Where a node s of b is pressed
into the plane by d (its x = -d) its mirror twin of a is at x = +d, so its gap to a's (locally plane) surface is
g = -2 d; the pair b-on-a pushes s by k 2 d A_s and the pair a-on-b's reaction on s (its master vertex) as much
again: the wall with k_w = 4 k gives the same nodal forces, :data:`WALL_FACTOR`. The two answers differ only where
the patch is not plane (a node's closest point off its twin), by terms of the penetration's order p / k.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from mpi4py import MPI

log = logging.getLogger(__name__)

__all__ = ["MESH", "PAIRS", "STEPS", "WALL_FACTOR", "TwinResult", "mirror_pairs", "plane_raw", "run_twin", "twin_raw"]

#: The coarse mesh of examples/twin_muscles.toml (meshes.twin_muscles' parameters).
MESH: dict[str, Any] = {"length": 0.04, "belly_radius": 0.006, "tendon_radius": 0.002, "tendon_length": 0.01,
                        "gap": 0.00005, "size": 0.006, "turn_elements": 8}
#: The bellies' Young's modulus (Pa) and peak active stress (Pa): soft and strong enough that the bulge closes the
#: gap and presses a patch several nodes wide.
E_BELLY, SIGMA_MAX = 3.0e6, 6.0e5
#: The two contact pairs (slave, master): each muscle's nodes against the other's triangles.
PAIRS = (("a_lateral", "b_lateral"), ("b_lateral", "a_lateral"))
#: The rigid wall's penalty per the pairs' k that gives the same nodal forces (module docstring).
WALL_FACTOR = 4.0
#: Load steps to full activation. Two pairs of node-to-surface contact of convex faceted bellies have an
#: asymmetric state too (one pair carrying all the load): with 4 steps, Debian 13's mesh of the same geometry
#: (gmsh 4.13) needs 13 Newton iterations in the first step and ends there (0.49 of max |u| off the mirror image,
#: one pair 0.59 N, the other none); with 8 steps Newton takes 5 iterations a step on both releases and stays on
#: the symmetric state (docs/layers.md, "Curved bellies in contact").
STEPS = 8


def _muscle(m: str, activation: float, E: float, sigma_max: float) -> list[dict[str, Any]]:
    fibres = {"type": "laplace", "origin": f"{m}_origin", "insertion": f"{m}_insertion",
              "regions": [f"{m}_belly", f"{m}_tendon"]}
    return [{"region": f"{m}_belly", "law": "muscle", "isotropic": "stvk", "E": E, "nu": 0.45, "sigma_max": sigma_max,
             "fibres": fibres, "activation": [[0.0, 0.0], [1.0, activation]]},
            {"region": f"{m}_tendon", "law": "tendon", "isotropic": "stvk", "E": 15.0e6, "nu": 0.45,
             "fibres": fibres}]


def _raw(contacts: list[dict[str, Any]], steps: int, activation: float, E: float, sigma_max: float,
         **mesh: Any) -> dict[str, Any]:
    return {"mesh": {"generator": "twin_muscles", **MESH, **mesh},
            "discretization": {"degree": 1, "quadrature_degree": "auto"},
            "material": _muscle("a", activation, E, sigma_max) + _muscle("b", activation, E, sigma_max),
            "boundary": [{"on": f"{m}_{end}", "type": "displacement", "value": [0.0, 0.0, 0.0]}
                         for m in "ab" for end in ("origin", "insertion")],
            "contact": contacts,
            "solver": {"petsc_options": {"snes_max_it": 80, "snes_rtol": 1e-9}},
            "loading": {"steps": steps}, "output": {"dir": "results/twin_muscles"}}


def twin_raw(k: float = 1e10, steps: int = STEPS, activation: float = 1.0, E: float = E_BELLY,
             sigma_max: float = SIGMA_MAX, contact: bool = True, augmented: bool = False, exact: bool = False,
             smooth_normals: bool = False, **mesh: Any) -> dict[str, Any]:
    """examples/twin_muscles.toml: the twin muscles (meshes.twin_muscles, :data:`MESH`'s parameters updated by
    ``mesh``), the bellies (Young's modulus ``E``, peak active stress ``sigma_max``) activated to ``activation``
    in ``steps`` steps, the ends clamped, the pairs :data:`PAIRS` with penalty ``k`` (``augmented``: Uzawa
    updates; ``exact``: BodyContact's exact contact; ``smooth_normals``: the masters' interpolated nodal normals,
    with the l2 line search on the residual's norm, as the pairs have no consistent potential; ``contact`` False:
    none)."""
    contacts = [{"surface": s, "master": m, "method": "penalty", "penalty": k,
                 **({"augmented": True} if augmented else {}), **({"exact": True} if exact else {}),
                 **({"smooth_normals": True} if smooth_normals else {})}
                for s, m in PAIRS] if contact else []
    raw = _raw(contacts, steps, activation, E, sigma_max, **mesh)
    if smooth_normals:
        raw["solver"]["petsc_options"]["snes_linesearch_type"] = "l2"
    return raw


def plane_raw(k_wall: float, steps: int = STEPS, activation: float = 1.0, E: float = E_BELLY,
              sigma_max: float = SIGMA_MAX, **mesh: Any) -> dict[str, Any]:
    """The mirror-symmetry reference (module docstring): :func:`twin_raw`'s run with each muscle's lateral surface
    against the rigid frictionless plane x = 0 (penalty ``k_wall``, nodal rule) instead of the pairs."""
    contacts = [{"surface": f"{m}_lateral", "obstacle": "plane", "point": [0.0, 0.0, 0.0],
                 "normal": [sign, 0.0, 0.0], "method": "penalty", "penalty": k_wall, "quadrature_degree": "vertex"}
                for m, sign in (("a", -1.0), ("b", 1.0))]
    return _raw(contacts, steps, activation, E, sigma_max, **mesh)


@dataclass
class TwinResult:
    """A run's answer, gathered on every rank: the nodes' reference positions X and displacements u (in the mesh
    generator's node order: a's nodes, then b's twins in the same order), Newton iterations per step, the pairs'
    (or walls') reports, each muscle's summed contact force from its pairs' nodal forces (``body_force``)."""

    X: np.ndarray
    u: np.ndarray
    dofs: int
    completed: bool
    iterations: list[int]
    reports: list[dict[str, Any]]
    body_force: dict[str, np.ndarray] = field(default_factory=dict)
    seconds: float = 0.0


def _gathered(problem: Any, comm: MPI.Comm) -> tuple[np.ndarray, np.ndarray]:
    """(X, u) at every node (P1: the dofs' blocks), every rank's owned ones, sorted by coordinates (the same arrays
    on every rank and partition). Collective."""
    V = problem.space
    owned = V.dofmap.index_map.size_local
    X = V.tabulate_dof_coordinates()[:owned, :3]
    u = problem.solution.x.array.reshape(-1, 3)[:owned]
    parts = comm.allgather((X, u))
    X = np.concatenate([p[0] for p in parts])
    u = np.concatenate([p[1] for p in parts])
    order = np.lexsort(np.round(X / MESH["length"], 9).T[::-1])
    return X[order], u[order]


def mirror_pairs(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Indices (ia, ib) of the twin nodes: X[ia] = M X[ib], M = diag(-1, 1, 1), b's nodes (x > 0) in order.
    KeyError if a node of b has no mirror twin."""
    keys = {tuple(np.round(x / MESH["length"], 9)): i for i, x in enumerate(X)}
    ib = np.flatnonzero(X[:, 0] > 0.0)
    ia = np.array([keys[tuple(np.round(X[i] * np.array([-1.0, 1.0, 1.0]) / MESH["length"], 9))] for i in ib])
    return ia, ib


def run_twin(raw: dict[str, Any], comm: MPI.Comm = MPI.COMM_WORLD) -> TwinResult:
    """Build and solve the configuration ``raw`` (:func:`twin_raw` or :func:`plane_raw`) to load factor 1 and
    gather its answer (:class:`TwinResult`). Collective."""
    from model.config import parse
    from model.pipeline import build, make_solver
    from model.problem.body_contact import BodyContact
    from model.solvers.loadstepping import step_loads

    start = time.perf_counter()
    config = parse(raw)
    setup = build(config, comm)
    problem = setup.problem
    solver = make_solver(problem, config, setup.contacts)
    records: list[Any] = []
    outcome = step_loads(solver, config.loading.steps, on_step=records.append)
    X, u = _gathered(problem, comm)
    reports = [c.report() if isinstance(c, BodyContact) else c.contact_report() for c in setup.contacts]
    body_force: dict[str, np.ndarray] = {}
    if setup.contacts and isinstance(setup.contacts[0], BodyContact):  # the pairs' nodal forces, -r, per muscle
        owned = problem.space.dofmap.index_map.size_local
        x_owned = problem.space.tabulate_dof_coordinates()[:owned, 0]
        forces = np.zeros((owned, 3))
        for pair in setup.contacts:
            r = pair.contact_residual()
            forces -= r.getArray().reshape(-1, 3)[:owned]
            r.destroy()
        for m, side in (("a", x_owned < 0.0), ("b", x_owned > 0.0)):
            body_force[m] = np.asarray(comm.allreduce(forces[side].sum(axis=0), op=MPI.SUM))
    result = TwinResult(X, u, problem.space.dofmap.index_map.size_global * 3, bool(outcome.completed),
                        [int(r.result.iterations) for r in records if r.result.converged], reports, body_force,
                        time.perf_counter() - start)
    solver.destroy()
    log.info("twin muscles: %d dofs, Newton %s, %s in %.1f s", result.dofs, result.iterations,
             [(r.get("normal_force"), r.get("max_penetration")) for r in reports], result.seconds)
    return result
