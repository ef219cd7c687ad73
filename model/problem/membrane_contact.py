"""Contact of a membrane (model.problem.membrane.MembraneProblem) with rigid bones: penalty, nodal rule, UFL.

    contact = ObstacleContact(problem, Sphere((0, 0, 0), 1.2), k=1e3, inside=True)   # adds its energy to Pi
    inflate(problem, pressures); contact.report()   # penetration, force, contact fraction

A rigid obstacle (forms.obstacles: Plane, Sphere, Capsule; signed distance d > 0 on its free side) gives the gap
of the current point x = X + u of the membrane,

    g(x) = s d(x),   s = +1 (the membrane stays outside the obstacle: a bone) or -1 (``inside``: the membrane
                     stays inside it, e.g. a balloon in a rigid spherical cavity),

and the penalty energy, integrated over the reference membrane with the nodal ("vertex") rule (A/3) sum over
each triangle's vertices (a node-by-node constraint, P1),

    Pi_c = int_S0 (k/2) min(g, 0)^2 dA          (forms.obstacles.penalty_energy),

k > 0 a stiffness per reference area per length. UFL derives the residual and Newton matrix of Pi + Pi_c. The
contact pressure per reference area is p_c = k max(-g, 0) (forms.obstacles.contact_pressure), the force on the
membrane F = -dPi_c/du summed over the nodes (= int p_c grad d dA), and the contact fraction the share of the
reference area, lumped to the nodes (m_i = int phi_i dA), whose nodes touch (g_i < 0):

    fraction = sum_{g_i < 0} m_i / sum_i m_i.

Augmented Lagrangian (``augmented=True``, forms.obstacles.augmented_lagrangian_energy): Pi_c = int (k/2)
min(g - lambda/k, 0)^2 - lambda^2/(2k) dA with the nodal multiplier lambda >= 0 (the contact pressure per
reference area), updated by Uzawa, lambda <- max(lambda - k g, 0), between equilibria
(model.solvers.membrane.inflate) until max |min(g, lambda/k)| <= a tolerance: the penetration vanishes for any k.

Closed form (tests/test_membrane_contact.py): a thin spherical balloon of radius R in a rigid concentric
cavity of radius R_c > R is free until p = p_m(R_c/R) (p_m(lambda) = w'(lambda)/(R lambda^2),
model.problem.membrane.balloon_pressure); beyond it d/dr [4 pi R^2 (w + (k/2) delta^2) - p (4/3) pi r^3] = 0
with r = R_c + delta gives the penetration delta = lambda^2 (p - p_m(lambda)) / k, lambda = (R_c + delta)/R,
and the contact fraction jumps from 0 to 1; with the augmented Lagrangian delta -> 0 and the multiplier is
lambda_c = (R_c/R)^2 (p - p_m(R_c/R)) (the same balance with k delta -> lambda_c, r = R_c).
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc
from scipy.sparse import coo_matrix, csr_matrix

from forms.obstacles import Obstacle, augmented_lagrangian_energy, contact_pressure, penalty_energy
from forms.quadrature import vertex_rule
from model import compat
from model.problem.membrane import MembraneProblem

log = logging.getLogger(__name__)

__all__ = ["REST_SIDE", "MembranePairContact", "MembraneSelfContact", "ObstacleContact", "contact_fraction",
           "nodal_measure", "pair_contacts", "touching_nodes"]

def nodal_measure(problem: MembraneProblem, region: str | None = None) -> ufl.Measure:
    """dA over the membrane's cells (or its cell region ``region``) with the vertex rule.

    Always restricted to tagged cells: on dolfinx 0.5 FFCx merges two quadrature rules of the same (untagged)
    cell integral into one kernel that does not compile on a manifold (J declared twice)."""
    dx = ufl.Measure("dx", domain=problem.domain.mesh, subdomain_data=problem.domain.cell_tags,
                     metadata=vertex_rule("triangle"))
    regions = problem.domain.regions
    if region is not None:
        error = problem.domain.region_error(region)
        if error is not None:
            raise ValueError(f"membrane contact: region: {error}")
    codes = regions[region] if region is not None else tuple(sorted({c for v in regions.values() for c in v}))
    return dx(tuple(int(c) for c in codes))


class _NodalContact:
    """What the membrane contacts share: owned nodes, their lumped areas, the force from a contact energy, the
    nodal contact pressure and its Uzawa update."""

    def _setup(self, problem: MembraneProblem, energy: ufl.Form, dA: ufl.Measure) -> None:
        self.problem, self.comm = problem, problem.domain.mesh.comm
        V = problem.V
        self.n_owned = V.dofmap.index_map.size_local
        self.reference = V.tabulate_dof_coordinates()[:, :3]
        v = ufl.TestFunction(V)
        #: the reference area lumped to the owned nodes, over the contact's surface and over the whole membrane
        self.lumped_area, self.membrane_lumped = (self._lumped(v[0] * measure)
                                                  for measure in (dA, nodal_measure(problem)))
        self.energy = energy
        self._force = fem.form(ufl.derivative(energy, problem.u, v))
        problem.add_energy(energy)
        problem.contacts.append(self)

    def _lumped(self, form: ufl.Form) -> np.ndarray:
        vector = fem_petsc.assemble_vector(fem.form(form))
        vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        values = vector.array_r.reshape(-1, 3)[: self.n_owned, 0].copy()
        vector.destroy()
        return values

    def positions(self) -> np.ndarray:
        """x = X + u at the owned nodes (n, 3)."""
        u = self.problem.u.x.array.reshape(-1, 3)[: self.n_owned]
        return self.reference[: self.n_owned] + u

    def force(self) -> np.ndarray:
        """The contact force on the membrane, -dPi_c/du summed over all nodes (3,). Collective."""
        R = fem_petsc.assemble_vector(self._force)
        R.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        local = R.array_r.reshape(-1, 3).sum(axis=0)
        R.destroy()
        return -np.asarray(self.comm.allreduce(local, op=MPI.SUM))

    def touching(self) -> np.ndarray:
        """A bool per owned node of the membrane: True where it touches (g < 0)."""
        raise NotImplementedError

    # the nodal penalty / augmented Lagrangian, on the nodes the subclass checks: nodal_gaps() g, the multiplier
    # Function lambda at their dofs self._q, self.k, self.augmented

    def nodal_pressures(self) -> np.ndarray:
        """The contact pressure per reference area at the checked owned nodes, max(lambda - k g, 0) (lambda = 0
        for the plain penalty). Collective."""
        lam = self.multiplier.x.array[self._q] if self.augmented else 0.0
        return np.asarray(contact_pressure(self.nodal_gaps(), float(self.k.value), lam))

    def uzawa_residual(self) -> float:
        """max over the checked nodes of |min(g, lambda/k)|: 0 at the exact contact solution (g >= 0, lambda >= 0,
        lambda g = 0). Collective."""
        lam = self.multiplier.x.array[self._q]
        local = np.abs(np.minimum(self.nodal_gaps(), lam / float(self.k.value)))
        return float(self.comm.allreduce(float(local.max(initial=0.0)), op=MPI.MAX))

    def update_multiplier(self) -> None:
        """Uzawa: lambda_i <- max(lambda_i - k g_i, 0) at the checked nodes. Collective (ghosts updated)."""
        self.multiplier.x.array[self._q] = self.nodal_pressures()
        self.multiplier.x.scatter_forward()

    def contact_fraction(self) -> float:
        """The share of the reference area (lumped to the nodes) whose nodes touch, g < 0. Collective."""
        return _area_fraction(self.comm, self.lumped_area, self.touching())


def _area_fraction(comm: MPI.Comm, lumped: np.ndarray, mask: np.ndarray) -> float:
    touching = comm.allreduce(float(lumped[mask].sum()), op=MPI.SUM)
    return touching / comm.allreduce(float(lumped.sum()), op=MPI.SUM)


def touching_nodes(problem: MembraneProblem) -> np.ndarray:
    """A bool per owned node of the membrane: True where it touches any of its contacts (g < 0). Collective."""
    mask = np.zeros(problem.V.dofmap.index_map.size_local, dtype=bool)
    for contact in problem.contacts:
        mask |= contact.touching()
    return mask


def contact_fraction(problem: MembraneProblem) -> float:
    """The share of the membrane's reference area whose nodes touch any of its contacts (bones or other
    membranes; each node counted once), 0 without contacts. Collective."""
    if not problem.contacts:
        return 0.0
    return _area_fraction(problem.domain.mesh.comm, problem.contacts[0].membrane_lumped, touching_nodes(problem))


class ObstacleContact(_NodalContact):
    """Penalty contact of the whole membrane with a rigid ``obstacle`` (module docstring); ``inside``: the free
    side is the obstacle's interior (g = -d). Adds Pi_c to the problem's energy on construction."""

    def __init__(self, problem: MembraneProblem, obstacle: Obstacle, k: float, inside: bool = False,
                 name: str | None = None, augmented: bool = False) -> None:
        if not (isinstance(k, (int, float)) and np.isfinite(k) and k > 0):
            raise ValueError(f"membrane contact: k must be a finite number > 0, got {k!r}")
        self.obstacle, self.sign = obstacle, -1.0 if inside else 1.0
        self.name = name or type(obstacle).__name__.lower()
        self.augmented = bool(augmented)
        msh = problem.domain.mesh
        self.k = fem.Constant(msh, PETSc.ScalarType(k))
        x = ufl.SpatialCoordinate(msh) + problem.u
        self.gap = self.sign * obstacle.distance(x)
        # the augmented Lagrangian's multiplier (the contact pressure per reference area) at the nodes: a scalar
        # P1 Function, its dof of each node from the collapsed first component of the displacement space
        Q, to_v = problem.V.sub(0).collapse()
        self.multiplier = fem.Function(Q, name="contact_pressure")
        q_of_block = np.full(len(problem.u.x.array) // 3, -1, dtype=np.int64)
        q_of_block[np.asarray(to_v, dtype=np.int64) // 3] = np.arange(len(to_v))
        self._q = q_of_block
        psi = augmented_lagrangian_energy(self.gap, self.multiplier, self.k) if self.augmented \
            else penalty_energy(self.gap, self.k)
        self._setup(problem, psi * nodal_measure(problem), nodal_measure(problem))
        self._q = self._q[: self.n_owned]

    def nodal_gaps(self) -> np.ndarray:
        """g at the owned nodes."""
        return self.sign * np.asarray(self.obstacle.distance(self.positions()), dtype=np.float64)

    def touching(self) -> np.ndarray:
        return self.nodal_pressures() > 0.0

    def report(self) -> dict[str, Any]:
        """max_penetration = max(0, -min g), force (on the membrane), contact_fraction, active_points (nodes
        with a contact pressure); the same on every rank. Collective."""
        g = self.nodal_gaps()
        low = self.comm.allreduce(float(g.min(initial=np.inf)), op=MPI.MIN)
        return {"pair": self.name, "max_penetration": max(0.0, -low), "force": [float(f) for f in self.force()],
                "contact_fraction": self.contact_fraction(),
                "active_points": self.comm.allreduce(int(np.sum(self.touching())), op=MPI.SUM)}


class MembranePairContact(_NodalContact):
    """Penalty contact of the ``slave`` region of the membrane mesh against its ``master`` region (two membranes
    of one surface mesh, meshes.membrane.combine_surfaces), after model.problem.body_contact.BodyContact:

        g = n . (x_s - x*),   x* = sum_j b_j x_j the closest point of the deformed master surface to the slave
        node x_s (a triangle T, barycentric b_j, model.problem.body_contact.closest_points_on_triangles), n T's
        current unit normal, oriented as the master's rest normal (problem.normal): the slave stays on the side
        the master's normal points to;
        Pi_c = int_slave (k/2) min(g, 0)^2 dA (nodal rule),

    with z = Pi u (the master displacement at x*, Pi the barycentric interpolation) a Function of its own, so UFL
    derives every term and the Newton solver (model.solvers.membrane) adds R += Pi^T dPi_c/dz and
    K += K_uz Pi + Pi^T K_zu + Pi^T K_zz Pi. The pairing (T, b) and n are found again before every residual and
    Jacobian (``update``) and held fixed in the derivatives (what is lagged: the normal's rotation and the slip
    of x*). The master triangles are gathered on every rank once (their reference vertices and node indices;
    each update gathers the displacements of their vertices and of the slave nodes) and every rank pairs every
    slave node (the same pairing everywhere, and the whole Pi on every rank, a scipy matrix: no scatter of X*,
    n, z; each rank multiplies its owned rows, add_jacobian, _master_force).

    ``augmented``: Pi_c = int_slave (k/2) min(g - lambda/k, 0)^2 - lambda^2/(2k) dA with the multiplier lambda
    >= 0 at the slave nodes (the contact pressure per reference area), updated by Uzawa between equilibria
    (model.solvers.membrane.inflate), lambda <- max(lambda - k g, 0), as in ObstacleContact; the master's force
    is Pi^T of the same derivative, so action = reaction holds for the multipliers too.

    Newton (model.solvers.membrane.membrane_newton) uses the l2 line search here: backtracking on |R| took
    steps of 0.1 for dozens of iterations at the first contact (the overshoot through the other membrane)."""

    def __init__(self, problem: MembraneProblem, slave: str, master: str, k: float, neighbours: int = 8,
                 name: str | None = None, augmented: bool = False) -> None:
        if not (isinstance(k, (int, float)) and np.isfinite(k) and k > 0):
            raise ValueError(f"membrane contact: k must be a finite number > 0, got {k!r}")
        domain = problem.domain
        self._check_regions(problem, slave, master)
        self.slave, self.master, self.neighbours = slave, master, int(neighbours)
        self.name = name or f"{slave}-{master}"
        msh, V = domain.mesh, problem.V
        self.V, self.comm = V, msh.comm
        owned = V.dofmap.index_map.size_local
        blocks = np.unique(compat.cell_dofs(V.dofmap)[domain.region_cells(slave), :3]).astype(np.int32)
        self.slave_blocks = blocks[blocks < owned]
        #: the slave nodes of the rank's slave cells, owned first (np.unique: owned indices < ghosts')
        self.slave_all = blocks
        self.reference = V.tabulate_dof_coordinates()[:, :3]
        # every rank pairs every slave node (gathered once: reference points and global indices; each update
        # gathers their displacements with the master's): the same pairing on every rank, so X*, n and z need no
        # scatter, and every rank holds the whole Pi
        glob = np.asarray(V.dofmap.index_map.local_to_global(blocks), dtype=np.int64)
        parts = self.comm.allgather((glob, self.reference[blocks]))
        self._slave_global, self._slave_first = np.unique(np.concatenate([g for g, _ in parts]), return_index=True)
        self._slave_reference = np.concatenate([x for _, x in parts])[self._slave_first]
        self._slave_position = np.searchsorted(self._slave_global, glob)  # slave_all's rows of the global list
        self._master_setup(problem)
        self.X_star, self.contact_normal, self.z = (fem.Function(V, name=n) for n in ("X_star", "normal", "z"))
        self.k = fem.Constant(msh, PETSc.ScalarType(k))
        X = ufl.SpatialCoordinate(msh)
        self.gap = ufl.dot(self.contact_normal, X + problem.u - self.X_star - self.z)
        dA = nodal_measure(problem, None if slave == "all" else slave)
        # the augmented Lagrangian's multiplier at the slave nodes (a scalar P1 Function, as in ObstacleContact)
        self.augmented = bool(augmented)
        Q, to_v = V.sub(0).collapse()
        self.multiplier = fem.Function(Q, name="contact_pressure")
        q_of_block = np.full(len(problem.u.x.array) // 3, -1, dtype=np.int64)
        q_of_block[np.asarray(to_v, dtype=np.int64) // 3] = np.arange(len(to_v))
        self._q = q_of_block[self.slave_blocks]
        psi = augmented_lagrangian_energy(self.gap, self.multiplier, self.k) if self.augmented \
            else penalty_energy(self.gap, self.k)
        energy = psi * dA
        v, w = ufl.TestFunction(V), ufl.TrialFunction(V)
        dz = ufl.derivative(energy, self.z, v)
        self._ufl = {"Rz": dz, "Kuz": ufl.derivative(ufl.derivative(energy, problem.u, v), self.z, w),
                     "Kzz": ufl.derivative(dz, self.z, w)}
        self._compiled: dict[str, Any] = {}
        self._stamp: np.ndarray | None = None
        #: K_uz, K_zz (made once), the whole Pi (scipy), the Dirichlet dofs
        self._matrices: dict[str, PETSc.Mat] = {}
        self._pi_global: Any = None
        self._bc_dofs: tuple | None = None
        self._vector: PETSc.Vec | None = None  # dPi_c/dz
        #: (triangle, barycentric, normal) per slave node (all ranks') of the last pairing; ``frozen``: reuse one
        self.pairing: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self.frozen: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._setup(problem, energy, dA)
        self.slave_mask = np.zeros(self.n_owned, dtype=bool)
        self.slave_mask[self.slave_blocks] = True

    @staticmethod
    def _check_regions(problem: MembraneProblem, slave: str, master: str) -> None:
        """ValueError unless ``slave`` and ``master`` are two named regions."""
        for region in (slave, master):
            error = problem.domain.region_error(region)
            if error is not None or region == "all":
                raise ValueError(f"membrane contact: region: {error or 'a named membrane region, not all'}")
        if slave == master:
            raise ValueError("membrane contact: slave and master must be two regions")

    def _closest(self, xs: np.ndarray, x_tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The closest master triangle to each slave node (all ranks'; among its ``neighbours`` nearest by
        centroid) and the barycentric coordinates of the closest point on it."""
        from scipy.spatial import cKDTree

        from model.problem.body_contact import closest_points_on_triangles

        n, k = len(xs), min(self.neighbours, len(x_tri))
        best_d, best_t, best_b = np.full(n, np.inf), np.zeros(n, dtype=np.int64), np.zeros((n, 3))
        if n:
            # the k nearest triangles (by centroid) of every slave node, their closest points in one call
            near = np.asarray(cKDTree(x_tri.mean(axis=1)).query(xs, k=k)[1]).reshape(n, k)
            closest, bary = closest_points_on_triangles(np.repeat(xs, k, axis=0), x_tri[near.ravel()])
            dist = np.linalg.norm(np.repeat(xs, k, axis=0) - closest, axis=1).reshape(n, k)
            bary = bary.reshape(n, k, 3)
            for j in range(k):  # the first of the nearest within round-off
                d = dist[:, j]
                better = d < best_d - 1e-14 * np.maximum(d, 1.0)
                best_d[better], best_t[better], best_b[better] = d[better], near[better, j], bary[better, j]
        return best_t, best_b

    def _sides(self, best_t: np.ndarray, best_b: np.ndarray) -> np.ndarray | None:
        """A factor per slave node on the master's normal (None: 1 everywhere, the side the normal points to)."""
        return None

    def _master_setup(self, problem: MembraneProblem) -> None:
        """Owned master cells: their three block dofs, ordered so that (x1 - x0) x (x2 - x0) . N > 0 (N the rest
        normal), and their global block indices."""
        msh, V = problem.domain.mesh, self.V
        cells = problem.domain.region_cells(self.master)
        cells = cells[cells < msh.topology.index_map(2).size_local]
        tri = compat.cell_dofs(V.dofmap)[cells, :3].astype(np.int64)
        W = problem.normal.function_space
        N = problem.normal.x.array.reshape(-1, 3)[compat.cell_dofs(W.dofmap)[cells, 0]]
        x = self.reference
        normal = np.cross(x[tri[:, 1]] - x[tri[:, 0]], x[tri[:, 2]] - x[tri[:, 0]])
        flip = np.einsum("ij,ij->i", normal, N) < 0
        tri[flip] = tri[flip][:, [0, 2, 1]]
        self.master_local = tri
        self.master_global = np.asarray(V.dofmap.index_map.local_to_global(tri.ravel().astype(np.int32)),
                                        dtype=np.int64).reshape(-1, 3)
        if self.comm.allreduce(len(cells), op=MPI.SUM) == 0:
            raise ValueError(f"membrane contact: region {self.master!r} has no cell")
        # the master triangles of every rank, gathered once: their reference vertices and global block indices
        # (each update gathers only the displacements of their vertices), and each triangle's vertices as rows
        # of the master's node list (for the vertex normals)
        parts = self.comm.allgather((x[tri], self.master_global))
        self._X_tri, self._g_tri = (np.concatenate([p[i] for p in parts]) for i in range(2))
        nodes, index = np.unique(self._g_tri.ravel(), return_inverse=True)
        self._n_master_nodes, self._tri_nodes = len(nodes), index.reshape(-1, 3)

    def update(self) -> None:
        """Pair every owned slave node with its closest master point at the current u; set X*, n, z and Pi.
        Collective."""
        current = self.problem.u.x.array
        changed = self._stamp is None or not np.array_equal(self._stamp, current)
        u = current.reshape(-1, 3)
        # one collective: whether u changed on any rank, with the displacements of the master triangles and of
        # the slave nodes
        slave = self.slave_all
        parts = self.comm.allgather((changed, u[self.master_local], u[slave]))
        if not any(c for c, _, _ in parts):
            return
        X_tri, g_tri = self._X_tri, self._g_tri
        x_tri = X_tri + np.concatenate([d for _, d, _ in parts])
        xs = self._slave_reference + np.concatenate([d for _, _, d in parts])[self._slave_first]
        best_t, best_b = self._closest(xs, x_tri)
        # the master's vertex normals (area-weighted mean of its triangles' normals), interpolated at x*: a
        # normal continuous across the master's edges, so the gap does not jump when x* changes triangle
        face = np.cross(x_tri[:, 1] - x_tri[:, 0], x_tri[:, 2] - x_tri[:, 0])
        index = self._tri_nodes
        vertex = np.zeros((self._n_master_nodes, 3))
        for j in range(3):
            np.add.at(vertex, index[:, j], face)
        vertex /= np.maximum(np.linalg.norm(vertex, axis=1, keepdims=True), 1e-300)
        normal = np.einsum("ij,ijk->ik", best_b, vertex[index[best_t]])
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
        sides = self._sides(best_t, best_b)
        if sides is not None:
            normal *= sides[:, None]
        if self.frozen is not None:  # the pairing of the last update, z from the current u (derivative checks)
            best_t, best_b, normal = self.frozen
        self.pairing = (best_t, best_b, normal)
        # the whole Pi (every slave node's rows, global indices) for the coupling terms
        N = 3 * self.V.dofmap.index_map.size_global
        rows = np.repeat((3 * self._slave_global[:, None] + np.arange(3)).ravel(), 3)
        cols = (3 * g_tri[best_t][:, None, :] + np.arange(3)[None, :, None]).ravel()
        self._pi_global = csr_matrix((np.repeat(best_b, 3, axis=0).ravel(), (rows, cols)), shape=(N, N))
        here = self._slave_position
        best_t, best_b, normal = best_t[here], best_b[here], normal[here]
        values = (np.einsum("ij,ijk->ik", best_b, X_tri[best_t]), normal,
                  np.einsum("ij,ijk->ik", best_b, x_tri[best_t] - X_tri[best_t]))
        for function, value in zip((self.X_star, self.contact_normal, self.z), values, strict=True):
            array = function.x.array.reshape(-1, 3)
            array[:] = 0.0
            array[slave] = value
        self._stamp = current.copy()

    def _form(self, key: str) -> Any:
        if key not in self._compiled:
            self._compiled[key] = fem.form(self._ufl[key])
        return self._compiled[key]

    def destroy(self) -> None:
        """Free the PETSc objects the pair made once (K_uz, K_zz, dPi_c/dz; made again when needed): a parallel
        object the collector frees waits on its communicator's garbage list (model.solvers.newton.free_garbage).
        model.solvers.membrane.CoupledNewton.destroy calls this. Collective."""
        for obj in [*self._matrices.values(), self._vector]:
            if obj is not None:
                obj.destroy()
        self._matrices, self._vector = {}, None

    def _master_force(self, pair: bool = True) -> np.ndarray:
        """Pi^T dPi_c/dz at the owned dofs: each rank's owned rows of dPi_c/dz through its rows of the whole Pi,
        summed over the ranks (one reduction). ``pair``: pair again if u changed (else the caller has).
        Collective."""
        if pair:
            self.update()
        if self._vector is None:
            self._vector = fem_petsc.create_vector(self._form("Rz"))
        Rz = self._vector
        with Rz.localForm() as local:
            local.set(0.0)
        fem_petsc.assemble_vector(Rz, self._form("Rz"))
        Rz.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        imap = self.V.dofmap.index_map
        start, m = 3 * imap.local_range[0], 3 * imap.size_local
        mine = np.ascontiguousarray(self._pi_global[start:start + m].T @ Rz.array_r[:m], dtype=np.float64)
        total = np.empty_like(mine)
        self.comm.Allreduce(mine, total, op=MPI.SUM)
        return total[start:start + m]

    def add_residual(self, b: PETSc.Vec) -> None:
        """b += Pi^T dPi_c/dz (b assembled and reverse-scattered) at the pairing of the last ``update`` (the
        Newton solver's before_assembly). Collective."""
        out = self._master_force(pair=False)
        with b.localForm() as local:
            local.array[: len(out)] += out

    def add_jacobian(self, A: PETSc.Mat, bcs: list) -> None:
        """A += K_uz Pi + Pi^T K_zu + Pi^T K_zz Pi, the rows and columns of the Dirichlet dofs zeroed. Collective;
        A is assembled again by the caller (which sends the rows other ranks own); the pairing is the last
        ``update``'s (the Newton solver's before_assembly).

        K_uz and K_zz are assembled into matrices made once; each rank multiplies its owned rows of them with the
        whole Pi (every rank has the whole pairing, scipy): K_uz,r Pi and its transpose, Pi_r^T K_zz,r Pi (Pi_r
        Pi's owned rows; summed over the ranks they are the three terms), no parallel matrix product; the owned
        rows go into A in one CSR call, the others in one row-mapped CSR call, sent at A's assembly (new nonzeros
        allocated as the pairing brings them: MatAXPY with the union pattern leaves a matrix that dolfinx 0.9's
        next assembly cannot use, DIVERGED_LINEAR_SOLVE)."""
        for key in ("Kuz", "Kzz"):
            if self._matrices.get(key) is None:
                self._matrices[key] = fem_petsc.create_matrix(self._form(key))
            M = self._matrices[key]
            M.zeroEntries()
            fem_petsc.assemble_matrix(M, self._form(key))
            M.assemble()
        m, N = A.getLocalSize()[0], A.getSize()[1]
        start = A.getOwnershipRange()[0]
        P = self._pi_global
        Kuz, Kzz = (csr_matrix(self._matrices[key].getValuesCSR()[::-1], shape=(m, N)) for key in ("Kuz", "Kzz"))
        C1 = (Kuz @ P).tocoo()  # owned rows (local), global columns
        C3 = (P[start:start + m].T @ (Kzz @ P)).tocoo()  # global rows and columns
        C = coo_matrix((np.concatenate([C1.data, C1.data, C3.data]),
                        (np.concatenate([C1.row + start, C1.col, C3.row]),
                         np.concatenate([C1.col, C1.row + start, C3.col]))), shape=(N, N)).tocsr()
        C.sum_duplicates()
        dirichlet = np.zeros(N, dtype=bool)
        dirichlet[self._dirichlet(bcs)] = True
        row = np.repeat(np.arange(N), np.diff(C.indptr))
        C.data[dirichlet[row] | dirichlet[C.indices]] = 0.0
        A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
        owned = C[start:start + m]
        A.setValuesCSR(owned.indptr.astype(PETSc.IntType), owned.indices.astype(PETSc.IntType), owned.data,
                       addv=PETSc.InsertMode.ADD_VALUES)
        rows = np.flatnonzero(np.diff(C.indptr))
        others = rows[(rows < start) | (rows >= start + m)]  # rows another rank owns: one CSR call, row-mapped
        if others.size:
            block = C[others]
            A.setValuesIJV(block.indptr.astype(PETSc.IntType), block.indices.astype(PETSc.IntType), block.data,
                           addv=PETSc.InsertMode.ADD_VALUES, rowmap=others.astype(PETSc.IntType))

    def _dirichlet(self, bcs: list) -> np.ndarray:
        """The global indices of every rank's Dirichlet dofs (sorted)."""
        key = tuple(id(bc) for bc in bcs)
        if self._bc_dofs is None or self._bc_dofs[0] != key:
            imap = self.V.dofmap.index_map
            owned = imap.size_local * 3
            dofs = [np.asarray(bc.dof_indices()[0], dtype=np.int64) for bc in bcs]
            local = np.unique(np.concatenate(dofs)) if dofs else np.empty(0, dtype=np.int64)
            local = local[local < owned]
            glob = np.asarray(imap.local_to_global((local // 3).astype(np.int32)), dtype=np.int64) * 3 + local % 3
            self._bc_dofs = (key, np.unique(np.concatenate(self.comm.allgather(glob))))
        return self._bc_dofs[1]

    def nodal_gaps(self) -> np.ndarray:
        """g at the owned slave nodes (paired again if u changed). Collective."""
        self.update()
        u = self.problem.u.x.array.reshape(-1, 3)
        s = self.slave_blocks
        return np.einsum("ij,ij->i", self.contact_normal.x.array.reshape(-1, 3)[s],
                         self.reference[s] + u[s] - self.X_star.x.array.reshape(-1, 3)[s]
                         - self.z.x.array.reshape(-1, 3)[s])

    def touching(self) -> np.ndarray:
        mask = np.zeros(self.n_owned, dtype=bool)
        mask[self.slave_blocks] = self.nodal_pressures() > 0.0
        return mask

    def report(self) -> dict[str, Any]:
        """max_penetration (max(0, -min g)), force on the slave (-dPi_c/du at fixed z, summed), force on the
        master (-Pi^T dPi_c/dz, summed), contact_fraction (of the slave region's area), active_points."""
        g = self.nodal_gaps()
        low = self.comm.allreduce(float(g.min(initial=np.inf)), op=MPI.MIN)
        out = self._master_force()
        master = -np.asarray(self.comm.allreduce(out.reshape(-1, 3).sum(axis=0), op=MPI.SUM))
        lumped = self.lumped_area[self.slave_blocks]
        active = self.nodal_pressures() > 0.0
        return {"pair": self.name, "max_penetration": max(0.0, -low), "force": [float(f) for f in self.force()],
                "master_force": [float(f) for f in master],
                "contact_fraction": _area_fraction(self.comm, lumped, active),
                "active_points": self.comm.allreduce(int(np.sum(active)), op=MPI.SUM)}


#: a node pairs with a point x* of a triangle only when, at rest, X_s - X* makes an angle of more than 30 degrees with
#: the triangle's tangent plane there: |N* . (X_s - X*)| >= REST_SIDE |X_s - X*|
REST_SIDE = 0.5


class MembraneSelfContact(MembranePairContact):
    """Penalty self-contact of one membrane: the ``region`` (default "all", the whole membrane) both the slave and
    the master of a MembranePairContact (the same gap, energy, chain rule R += Pi^T dPi_c/dz and UFL-derived
    coupling matrices; module docstring there), after model.problem.self_contact.SelfContact for the choice of the
    partner. Every node s of the region is a slave; its master point x* is the closest point of the deformed
    region among the triangles T that pass

        (1) neighbourhood: T has no vertex within ``rings`` - 1 edges of s (rings = 1: T does not contain s; the
            default 2: T touches neither s nor a node joined to s by an edge);
        (2) reach: |x_s - x*| <= ``reach`` (default: the mean rest edge length of the region's triangles);
        (3) a side at rest: |c| >= 1/2 (REST_SIDE), c = N* . (X_s - X*) / |X_s - X*|, X* = sum_j b_j X_j the rest
            position of the paired point (the same barycentric b_j) and N* the rest vertex normals interpolated
            there (normalised): the node lay at rest clearly on one side of the triangle's tangent plane (more
            than 30 degrees off it), not beside it in the same sheet;

    the closest of them (ties, equal distances to 1e-14 relative, to the smallest global triangle: the same pairing
    on any partition). A membrane has two faces, so the side is not the normal's: the gap is

        g = s n . (x_s - x*),   s = sign(c) (the side of T the node started on, at rest),

    n the current master normal of MembranePairContact (the vertex normals interpolated at x*, oriented by the rest
    normals), i.e. the factor s on n makes the pair's rule "stay on the side the normal points to" into "stay on
    the side you came from" (with s = +1, as for two facing membranes, it is MembranePairContact's gap). A node
    with no partner has n = 0: g = 0, no energy, force or tangent. Pi_c = int_region (k/2) min(g, 0)^2 dA (nodal
    rule; the penalty only: ``augmented`` is refused).
    The contact is internal: the slave force and the master force (report) cancel (sum_j b_j = 1).

    What the rule cannot see: a surface flat at rest that folds onto itself (every c = 0: no pair); a fold
    sharper than rings - 1 edges; a penetration deeper than ``reach`` (choose k so that p/k stays well below it)."""

    def __init__(self, problem: MembraneProblem, k: float, region: str = "all", rings: int = 2,
                 reach: float | None = None, neighbours: int = 8, name: str | None = None,
                 augmented: bool = False) -> None:
        if isinstance(rings, bool) or not isinstance(rings, int) or rings < 1:
            raise ValueError(f"membrane self-contact: rings: {rings!r} must be an integer >= 1")
        if reach is not None and not (isinstance(reach, (int, float)) and np.isfinite(reach) and reach > 0):
            raise ValueError(f"membrane self-contact: reach: {reach!r} must be a finite number > 0")
        if augmented:
            raise ValueError("membrane self-contact: penalty only (augmented: both sides' nodes held exactly "
                             "over-constrain, as with two_pass)")
        self.rings, self._reach = int(rings), reach
        self._side: np.ndarray = np.zeros(0)
        super().__init__(problem, region, region, k, neighbours=neighbours, name=name or f"{region}-self",
                         augmented=augmented)
        self._topology()

    @staticmethod
    def _check_regions(problem: MembraneProblem, slave: str, master: str) -> None:
        error = problem.domain.region_error(slave)
        if error is not None:
            raise ValueError(f"membrane self-contact: region: {error}")

    def _topology(self) -> None:
        """The neighbourhood relation of the region's nodes (within rings - 1 edges: the nonzeros of (I + A)^(rings
        - 1), A the edge adjacency) as sorted keys row * n + column, the rest vertex normals and the reach."""
        count, tri = self._n_master_nodes, self._tri_nodes
        if not np.array_equal(np.unique(self._g_tri), self._slave_global):
            raise RuntimeError("membrane self-contact: the slave nodes are not the nodes of the region's triangles")
        from model.problem.self_contact import neighbourhood_keys

        self.neighbourhood = neighbourhood_keys(tri, count, self.rings)
        X = self._X_tri
        face = np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0])
        vertex = np.zeros((count, 3))
        for j in range(3):
            np.add.at(vertex, tri[:, j], face)
        self._rest_vertex = vertex / np.maximum(np.linalg.norm(vertex, axis=1, keepdims=True), 1e-300)
        edges = np.linalg.norm(X - np.roll(X, 1, axis=1), axis=2)
        self.reach = float(edges.mean()) if self._reach is None else float(self._reach)
        self._stamp = None  # pair again with the rule
        log.info("membrane self-contact %s: %d triangles, %d nodes, rings %d, reach %.3g", self.name, len(tri),
                 count, self.rings, self.reach)

    def _closest(self, xs: np.ndarray, x_tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The partner of each node by the rule (class docstring), its barycentric coordinates; the side s (0: no
        partner) kept for ``_sides``."""
        from model.problem.body_contact import closest_points_on_triangles
        from model.problem.self_contact import candidate_pairs, closest_candidates

        n = len(xs)
        best_t, best_b, side = np.zeros(n, dtype=np.int64), np.zeros((n, 3)), np.zeros(n)
        self._side = side
        if n == 0 or not hasattr(self, "neighbourhood"):  # the first pairing, before _topology: none
            return best_t, best_b
        count, tri = self._n_master_nodes, self._tri_nodes
        # (1) neighbourhood: no vertex of T within rings - 1 edges of the node (slave row i is master node i)
        rows, cols = candidate_pairs(xs, x_tri, self.reach, np.arange(n), tri, self.neighbourhood, count)
        closest, bary = closest_points_on_triangles(xs[rows], x_tri[cols])
        d = np.linalg.norm(xs[rows] - closest, axis=1)
        # (2) reach; (3) a side at rest
        X_star = np.einsum("ij,ijk->ik", bary, self._X_tri[cols])
        N_star = np.einsum("ij,ijk->ik", bary, self._rest_vertex[tri[cols]])
        N_star /= np.maximum(np.linalg.norm(N_star, axis=1, keepdims=True), 1e-300)
        offset = self._slave_reference[rows] - X_star
        c = np.einsum("ij,ij->i", N_star, offset) / np.maximum(np.linalg.norm(offset, axis=1), 1e-300)
        keep = (d <= self.reach) & (np.abs(c) >= REST_SIDE)
        rows, cols, bary, d, c = rows[keep], cols[keep], bary[keep], d[keep], c[keep]
        if len(rows) == 0:
            return best_t, best_b
        chosen = closest_candidates(n, rows, cols, d, self._g_tri)  # ties to the smallest global triangle
        best_t[rows[chosen]], best_b[rows[chosen]] = cols[chosen], bary[chosen]
        side[rows[chosen]] = np.sign(c[chosen])
        return best_t, best_b

    def _sides(self, best_t: np.ndarray, best_b: np.ndarray) -> np.ndarray | None:
        return self._side

    def report(self) -> dict[str, Any]:
        """MembranePairContact.report (force: on the slave nodes, master_force: its reaction on the triangles; they
        cancel) and paired_points (nodes with a partner, pressed or not), the same on every rank. Collective."""
        report = super().report()
        report["paired_points"] = int(np.count_nonzero(self._side))  # every rank pairs every node
        return report


def pair_contacts(problem: MembraneProblem, slave: str, master: str, k: float, augmented: bool = False,
                  two_pass: bool = False, name: str | None = None, neighbours: int = 8
                  ) -> list[MembranePairContact]:
    """The contact of two membranes (regions ``slave`` and ``master``): one MembranePairContact (one pass: the
    slave's nodes stay out of the master's triangles, the master's nodes may enter the slave's) or, ``two_pass``
    (FEBio's two_pass of its sliding contacts), also the master against the slave: each membrane is slave and
    master in turn, the two passes' energies summed,

        Pi_c = int_slave (k/2) min(g_s, 0)^2 dA + int_master (k/2) min(g_m, 0)^2 dA,

    g_s the slave nodes' gap to the master's triangles and g_m the master nodes' gap to the slave's, each pass
    with its penalty k (and, ``augmented``, its own multiplier at its slave's nodes), so that neither surface's
    nodes penetrate the other's triangles on non-matching meshes. Names: ``name`` (default "<slave>-<master>")
    and, for the second pass, "<name>:reverse" when named, else "<master>-<slave>"."""
    if two_pass and augmented:
        raise ValueError("membrane contact: two_pass is penalty only (both membranes' nodes held exactly on the "
                         "other's triangles over-constrain non-matching meshes: Uzawa stalls)")
    first = MembranePairContact(problem, slave, master, k, neighbours=neighbours, name=name, augmented=augmented)
    if not two_pass:
        return [first]
    second = MembranePairContact(problem, master, slave, k, neighbours=neighbours,
                                 name=f"{name}:reverse" if name else None, augmented=augmented)
    return [first, second]
