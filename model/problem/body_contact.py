"""Contact and sliding between deformable bodies (surfaces of one mesh): penalty with closest-point search.

A node of the ``slave`` surface at x_s = X_s + u_s is paired with the closest point x* of the deformed ``master``
surface (a triangle T of it, barycentric coordinates b_j, x* = sum_j b_j x_j), where the outward unit normal is n:
for contact T's own (current configuration); for sliding (or ``smooth_normals=True``) the normalised
n = sum_j b_j N_j of the master nodes' normals N_j (the normalised sum of the normals of their master triangles,
area-weighted), continuous across the triangles' edges, so that the gap and the force do not jump when the closest
point moves on to the next triangle: with T's normal a node held on a faceted curved surface sees the normal turn
by the facets' angle at each edge, and Newton cycles between pairings without converging (the layered arm,
model.experiments.layered_arm: 8 facets per turn). The price: N is not T's normal, so the lagged slip of x* along
T (below) changes g by sin(N, n_T) times the slip, and Newton converges linearly (about halving the residual per
iteration there). The gap is

    g = n . (x_s - x*) = n . (X_s + u_s - X* - z),   X* = sum_j b_j X_j,  z = sum_j b_j u_j = (Pi u)_s,

and the energy, integrated over the slave surface with the nodal ("vertex") rule,

    contact:  Pi_c = int_slave (k/2) min(g, 0)^2 dA      (frictionless, non-penetration g >= 0),
    augmented: Pi_c = int_slave (k/2) min(g - lambda/k, 0)^2 - lambda^2/(2k) dA, the nodal multiplier lambda >= 0
              (the contact pressure) updated by model.solvers.contact.UzawaSolver, lambda <- max(lambda - k g, 0),
              until max |min(g, lambda/k)| <= tolerance x the body's size (as for rigid obstacles),
    sliding:  Pi_c = int_slave (k/2) g^2 dA              (the thesis' zero-length normal springs: the slave
                                                           surface stays on the master surface, free to slide).

UFL writes Pi_c(u, z) with z a Function of its own (the master displacement at the slave nodes' closest
points) and derives every derivative of it; the closest points enter through the linear interpolation z = Pi u
(Pi: one row per slave dof, the b_j of its master triangle's nodes), so by the chain rule

    R = dPi_c/du + Pi^T dPi_c/dz,     K = d2Pi_c/du2 + (d2Pi_c/dudz) Pi + Pi^T (d2Pi_c/dzdu) + Pi^T (d2Pi_c/dz2) Pi.

What is lagged: the pairing (T, b_j) and the normal n are found again from the deformed surfaces before every
residual and Jacobian evaluation (every Newton iteration) and held fixed in the derivatives, whose exact
linearisation would add terms proportional to g (the normal's rotation) and to the tangential slip of x*
(zero at a closest point where T is flat). Newton therefore converges quadratically once the pairing stops
changing, and superlinearly on curved surfaces (measured in tests/test_body_contact.py); where g != 0 and T turns
(the blocks from a distorted start, the slotted block's self-contact) linearly, at rates 0.03 and 0.36 (exact contact,
below, takes the rotation in and converges quadratically there).

Sliding with smoothed normals has no consistent potential (R = k g N is not d/du of (k/2) g^2: the lagged slip of
x* changes g by the tangential part of N), so such a pair gives a ``potential_reason`` and the Newton solver takes
full steps instead of a line search on the total potential (which failed on the touching layered arm, Debian 13's
mesh). A slave node of two sliding pairs (tied to two surfaces: the fat's nodes on the rim of the face that two
touching muscles share) is left out of both (``leave_shared``, on for sliding).

Exact sliding (``exact=True``, kind "sliding"; opt-in): Pi_c = int_slave (k/2) d^2 dA with d the distance of x_s to
the deformed faceted master surface, written in closed form in the Voronoi region of the closest point on T
(forms.obstacles.triangle_squared_distance; Ericson's classification, T's vertices ordered with the region's
vertex or edge first):

    face:   d^2 = (n . (x_s - x_1))^2 / (n . n),  n = (x_2 - x_1) x (x_3 - x_1)
    edge:   d^2 = |r|^2 - (r . e)^2 / (e . e),     r = x_s - x_1, e = x_2 - x_1
    vertex: d^2 = |x_s - x_1|^2,                   x_i = X_i + z_i.

The three vertices' displacements are Functions z_1, z_2, z_3 (at the slave nodes) with selection matrices P_i
(row (slave node, c) = e_(vertex i, c)), so

    R = dPi_c/du + sum_i P_i^T dPi_c/dz_i,
    K = d2Pi_c/du2 + sum_i (K_u,zi P_i + P_i^T K_zi,u) + sum_ij P_i^T K_zi,zj P_j

(every block UFL-assembled). Only T and the region are lagged; within a region d^2 is smooth, and across regions
it is C1 on the convex side (its gradient is 2 (x_s - x*), the envelope theorem), so R is dPi_c/du exactly, with
the normal's rotation and the closest point's slip, and the pair has no potential_reason (bt on the total
potential). Tested: R . d and J d against central differences of Pi and R (O(h^2)), and Newton's quadratic rate
once the regions settle (tests/test_body_contact.py). Not the default: on the layered arm, whose fat nodes start
on the muscles' vertices, d^2's Hessian jumps between the regions (k n n^T on a face, k (I - e e^T) on an edge,
k I at a vertex) right where the nodes are, and below the surface d is only C0 across a convex edge's bisector
(the closest face switches): full Newton steps cycle there, and bt converges, not quadratically (more iterations
than the interpolated normals at 10 degrees of flexion, but 24 of 30 degrees reached against 13; docs/layers.md,
"Contact and sliding between deformable bodies"). Ties in the closest-triangle search go to the smallest global
triangle (the same pairing on any partition); the layered arm's exact answer still differs by
1-3 % between 1 and 2 ranks (several equilibria within the tolerance at those kinks).

Exact contact (``exact=True``, kind "contact"; opt-in, the penalty only, not ``augmented``): the gap is the signed
distance to the paired triangle's plane, in every region of the closest point,

    g = n . (x_s - x_1) / |n|,   n = (x_2 - x_1) x (x_3 - x_1),   x_i = X_i + z_i (T's own, outward order),

Pi_c = int_slave (k/2) min(g, 0)^2 dA (forms.obstacles.penalty_energy, the same touching tolerance), with the vertex
slots z_i and P_i of exact sliding and every block of R and K from UFL: only T is lagged, the normal's rotation is in
R and K. At a pairing its value is the default's gap (n_T . (x_s - x*), x* in T's plane), so where x* is inside T
(the face region) the answers agree; in an edge or vertex region the default's R (the b_j of x* on the edge, not of
the projection on T's plane) is not the derivative of its own energy and the answers differ at the penalty's scale
(the slot: 8.2e-5 against a penetration of 5.7e-4). The signed distance itself, +-sqrt(d^2) in the edge and vertex
regions with the side of T's normal, jumps where that side flips at d > 0 (a node beside the master surface's open
edge, in T's plane): Newton stalled there, so the plane is used. Tested: R . d and J d against central differences
(O(h^2)) with every slave node pressed in vertex, edge and face regions, Newton quadratic on the pressed blocks and
the slotted block's self-contact (tests/test_body_contact.py, tests/test_self_contact.py). The price: the
rotation's term k g (d2 g/du2) makes the tangent indefinite where nodes start deep (k |g| comparable to the
stiffness): from the blocks sunk 1e-3 into each other (k = 1e7, E = 1e4) Newton diverges where the default
converges in 10 iterations (3e-4: 15 iterations, 1e-4: 9, the default 10).

P1 displacement formulation only (the nodal rule); the master surface's triangles are gathered on every rank
(each rank pairs its own slave nodes), so the search is MPI-correct with the same result on any number of ranks.
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
from scipy.sparse import csr_matrix

from forms.obstacles import (
    augmented_lagrangian_energy,
    contact_pressure,
    penalty_energy,
    sliding_energy,
    triangle_squared_distance,
)
from model import compat
from model.problem.bones import surface_measure
from model.problem.elasticity import ElasticityProblem

log = logging.getLogger(__name__)

KINDS = ("contact", "sliding")
#: gaps up to this x the body's size count as touching in the tangent (forms.obstacles.penalty_energy)
TOUCHING = 1e-12


def closest_points_on_triangles(points: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For points (n, 3) and one triangle each (n, 3, 3): the closest points (n, 3) and their barycentric
    coordinates (n, 3) (Ericson, Real-Time Collision Detection, 5.1.5: vertex, edge or face region)."""
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    ab, ac, ap = b - a, c - a, points - a
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp = points - b
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    cp = points - c
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    bary = np.zeros((len(points), 3))
    done = np.zeros(len(points), dtype=bool)

    def assign(mask: np.ndarray, w: np.ndarray) -> None:
        mask = mask & ~done
        bary[mask] = w[mask]
        done[mask] = True

    one, zero = np.ones(len(points)), np.zeros(len(points))
    assign((d1 <= 0) & (d2 <= 0), np.c_[one, zero, zero])
    assign((d3 >= 0) & (d4 <= d3), np.c_[zero, one, zero])
    with np.errstate(divide="ignore", invalid="ignore"):
        v = d1 / (d1 - d3)
        assign((vc <= 0) & (d1 >= 0) & (d3 <= 0), np.c_[1 - v, v, zero])
        assign((d6 >= 0) & (d5 <= d6), np.c_[zero, zero, one])
        w = d2 / (d2 - d6)
        assign((vb <= 0) & (d2 >= 0) & (d6 <= 0), np.c_[1 - w, zero, w])
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        assign((va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0), np.c_[zero, 1 - w, w])
        denom = 1.0 / (va + vb + vc)
        v, w = vb * denom, vc * denom
        assign(np.ones(len(points), dtype=bool), np.c_[1 - v - w, v, w])
    closest = np.einsum("ij,ijk->ik", bary, triangles)
    return closest, bary


class BodyContact:
    """Penalty contact (``kind="contact"``) or sliding (``"sliding"``) of ``slave`` against ``master``, two named
    surfaces of the problem's mesh (module docstring). Adds its energy to the problem and registers itself as a
    coupling (ElasticityProblem.couplings: the Newton solver adds Pi^T R_z and the coupling matrices).
    ``exact``: every derivative by UFL with only the paired triangle lagged (module docstring): sliding (k/2) d^2, d
    the distance to the faceted master surface ("Exact sliding"), contact (k/2) min(g, 0)^2, g the signed distance
    to the paired triangle's plane ("Exact contact"; not ``augmented``); otherwise the lagged normal.
    ``smallest_ties``: equal distances (1e-14 relative) to the smallest global triangle (the same pairing on any
    partition; default: with ``exact`` only)."""

    #: slave and master are one surface (SelfContact: its search leaves out the node's own neighbourhood)
    self_contact = False

    def __init__(self, problem: ElasticityProblem, slave: str, master: str, k: float, kind: str = "contact",
                 neighbours: int = 8, name: str | None = None, augmented: bool = False, tolerance: float = 1e-8,
                 max_uzawa: int = 25, smooth_normals: bool | None = None, leave_shared: bool | None = None,
                 exact: bool = False, smallest_ties: bool | None = None) -> None:
        if kind not in KINDS:
            raise ValueError(f"kind: {kind!r} is not one of {', '.join(KINDS)}")
        if not (np.isfinite(k) and k > 0):
            raise ValueError(f"k: {k!r} must be a finite number > 0")
        if augmented and kind != "contact":
            raise ValueError("augmented: Uzawa updates are for kind = 'contact' (sliding holds both ways)")
        if not (np.isfinite(tolerance) and tolerance > 0):
            raise ValueError(f"tolerance: {tolerance!r} must be a finite number > 0")
        if isinstance(max_uzawa, bool) or not isinstance(max_uzawa, int) or max_uzawa < 1:
            raise ValueError(f"max_uzawa: {max_uzawa!r} must be an integer >= 1")
        self.augmented, self.tolerance, self.max_uzawa = augmented, float(tolerance), max_uzawa
        self.exact = bool(exact)
        #: ties in the closest-triangle search to the smallest global triangle (default: with exact only; else
        #: the first of the nearest centroids, which on aligned meshes may differ between partitions)
        self.smallest_ties = self.exact if smallest_ties is None else bool(smallest_ties)
        if self.exact and augmented:
            raise ValueError("augmented: not with exact = true (exact contact is the penalty only)")
        if self.exact and smooth_normals:
            raise ValueError("smooth_normals: the exact energies (signed distance to T) have no normal to smooth "
                             "(exact = False for the interpolated normals)")
        self.smooth_normals = (kind == "sliding" and not self.exact) if smooth_normals is None else bool(smooth_normals)
        if problem.formulation != "displacement" or problem.degree != 1:
            raise ValueError("contact between bodies: the P1 displacement formulation only (nodal pairing)")
        for surface in (slave, master):
            error = problem.domain.boundary_error(surface)
            if error:
                raise ValueError(f"surface: {error}")
        self.problem, self.slave, self.master, self.kind = problem, slave, master, kind
        self.name = name or f"{slave}-{master}"
        self.neighbours = neighbours
        msh = problem.domain.mesh
        self.comm: MPI.Comm = msh.comm
        V = problem.space
        self.V = V
        self.bs = V.dofmap.index_map_bs
        fdim = msh.topology.dim - 1
        msh.topology.create_connectivity(fdim, msh.topology.dim)
        # slave nodes: the owned block dofs on the slave facets
        blocks = np.asarray(fem.locate_dofs_topological(V, fdim, problem.domain.boundary_facets(slave)), dtype=np.int32)
        owned = V.dofmap.index_map.size_local
        self.slave_blocks = blocks[blocks < owned]
        self.reference = V.tabulate_dof_coordinates()[:, :3]
        self._master_setup(fdim)
        self.leave_shared = kind == "sliding" if leave_shared is None else bool(leave_shared)
        self.left_out = 0
        self.q_of_block: np.ndarray | None = None
        self.Pi: PETSc.Mat | None = None
        self.P: list[PETSc.Mat] = []  # exact sliding: the selection matrices of the three vertex slots
        if self.leave_shared and kind == "sliding":
            self._leave_shared()
        if slave == master and not self.self_contact:
            raise ValueError(f"master: {master!r} is the slave surface (self-contact: SelfContact)")
        shared = np.intersect1d(self.slave_blocks, self.master_local.ravel())
        if not self.self_contact and self.comm.allreduce(len(shared), op=MPI.SUM):
            raise ValueError(f"master: {master!r} shares nodes with {slave!r} (give a boundary of another body: "
                             "meshes.combine keeps bodies apart)")
        # the master point data at the slave nodes: X*, n and z (master displacement there)
        self.X_star, self.normal, self.z = (fem.Function(V, name=n) for n in ("X_star", "normal", "z_master"))
        self.k = fem.Constant(msh, PETSc.ScalarType(k))
        u = problem.solution
        X = ufl.SpatialCoordinate(msh)
        self.gap = ufl.dot(self.normal, X + u - self.X_star - self.z)
        ds = surface_measure(problem, slave, "vertex")
        self._ds = ds
        # the augmented Lagrangian's multiplier: the contact pressure at the nodes (scalar P1), its dof of each
        # slave node from the collapsed first component of V (dof q of the scalar space is V's block map[q] // bs)
        Q, to_v = V.sub(0).collapse()
        if self.exact:  # the paired triangle's three vertices at each slave node: reference X_i, displacement z_i
            self.vertices = [fem.Function(V, name=f"X_vertex{i}") for i in range(3)]
            self.slots = [fem.Function(V, name=f"z_vertex{i}") for i in range(3)]
            self.region = fem.Function(Q, name="closest_point_region")
            x = X + u
            x1, x2, x3 = (Xi + zi for Xi, zi in zip(self.vertices, self.slots))
            if kind == "contact":  # g = n . (x_s - x_1) / |n|, n = (x_2 - x_1) x (x_3 - x_1): T's plane, any region
                n_T = ufl.cross(x2 - x1, x3 - x1)
                self.plane_gap = ufl.dot(n_T, x - x1) / ufl.sqrt(ufl.dot(n_T, n_T))
            else:
                self.squared_distance = triangle_squared_distance(x, x1, x2, x3, self.region)
                # for the report: r = x_s - x*, the signed distance sign(n_T . r) |r|
                r = x - self.X_star - self.z
                self.gap = ufl.sign(ufl.dot(self.normal, r)) * ufl.sqrt(ufl.dot(r, r))
        self.multiplier = fem.Function(Q, name="contact_pressure")
        block_of_q = np.asarray(to_v, dtype=np.int64) // self.bs
        q_of_block = np.full(len(self.reference), -1, dtype=np.int64)
        q_of_block[block_of_q] = np.arange(len(block_of_q))
        self.slave_q = q_of_block[self.slave_blocks]
        self.q_of_block = q_of_block
        from model.problem.bones import body_size

        self.size = body_size(problem)
        # surfaces that coincide at rest have gaps of +-2e-16 (round-off, machine dependent): count them touching,
        # so that the first tangent holds them (else Newton's first step lets the bodies pass through each other)
        touching = TOUCHING * self.size
        if self.exact and kind == "contact":  # the nodes not paired (region 0, a filler triangle) carry no energy
            psi = ufl.conditional(ufl.gt(self.region, 0.5), penalty_energy(self.plane_gap, self.k, touching), 0.0)
        elif self.exact:
            psi = 0.5 * self.k * self.squared_distance
        elif kind == "sliding":
            psi = sliding_energy(self.gap, self.k)
        elif augmented:
            psi = augmented_lagrangian_energy(self.gap, self.multiplier, self.k, touching)
        else:
            psi = penalty_energy(self.gap, self.k, touching)
        energy = psi * ds
        self.energy = energy
        v, w = ufl.TestFunction(V), ufl.TrialFunction(V)
        dz = ufl.derivative(energy, self.z, v)
        pressure = contact_pressure(self.gap, self.k, self.multiplier) if kind == "contact" else -self.k * self.gap
        # compiled on first use, after the problem's own forms: compiling a form here, before the problem adds
        # this energy with a new TestFunction, gave that test function another hash than the problem's earlier
        # ones on dolfinx 0.5 ("Found different Arguments with same number and part")
        self._ufl = {"Rz": dz, "Kuz": ufl.derivative(ufl.derivative(energy, u, v), self.z, w),
                     "Kzz": ufl.derivative(dz, self.z, w), "normal_force": pressure * ds,
                     **{f"force{i}": pressure * self.normal[i] * ds for i in range(3)}}
        if self.exact:  # R_zi, K_u,zi and K_zi,zj (i <= j) of Pi_c(u, z1, z2, z3); the force -k (x_s - x*)
            du = ufl.derivative(energy, u, v)
            paired = ufl.conditional(ufl.gt(self.region, 0.5), 1.0, 0.0)  # not the nodes left out
            r = paired * (X + u - self.X_star - self.z)
            for i, zi in enumerate(self.slots):
                self._ufl[f"Rz{i}"] = ufl.derivative(energy, zi, v)
                self._ufl[f"Kuz{i}"] = ufl.derivative(du, zi, w)
                for j in range(i, 3):
                    self._ufl[f"Kzz{i}{j}"] = ufl.derivative(self._ufl[f"Rz{i}"], self.slots[j], w)
            if kind == "sliding":  # (contact: p n, the gap n . (x_s - x*) and T's unit normal n as without exact)
                self._ufl.update({f"force{i}": -self.k * r[i] * ds for i in range(3)})
            for key in ("Rz", "Kuz", "Kzz"):
                del self._ufl[key]
        self._compiled: dict[str, Any] = {}
        self._matrices: dict[str, PETSc.Mat] = {}  # the K forms' matrices, made once (_assembled)
        self._stamp: np.ndarray | None = None
        problem.add_energy(energy, "contact" if kind == "contact" else "sliding")
        problem.couplings.append(self)

    # --- the master surface -----------------------------------------------------------------------------
    def _master_setup(self, fdim: int) -> None:
        """Owned master facets: their three nodes (local block dofs) ordered so that (x1 - x0) x (x2 - x0) points
        out of the body (away from the facet's cell's fourth vertex), and their global block indices."""
        msh, V = self.problem.domain.mesh, self.V
        facets = np.asarray(self.problem.domain.boundary_facets(self.master), dtype=np.int32)
        facets = facets[facets < msh.topology.index_map(fdim).size_local]
        geometry_to_dof = np.empty(len(msh.geometry.x), dtype=np.int64)
        cell_nodes = compat.geometry_dofs(msh)[:, :4]
        cell_blocks = compat.cell_dofs(V.dofmap)[:, :4]
        geometry_to_dof[cell_nodes.ravel()] = cell_blocks.ravel()
        nodes = np.asarray(compat.entity_geometry(msh, fdim, facets), dtype=np.int64)
        nodes = nodes.reshape(len(facets), -1)[:, :3] if len(facets) else np.empty((0, 3), dtype=np.int64)
        f2c = msh.topology.connectivity(fdim, msh.topology.dim)
        cells = np.array([f2c.links(f)[0] for f in facets], dtype=np.int32)
        x = msh.geometry.x
        tri = nodes.copy()
        if len(facets):
            opposite = np.array([[n for n in cell_nodes[c] if n not in set(face)][0] for c, face in zip(cells, nodes)])
            normal = np.cross(x[tri[:, 1]] - x[tri[:, 0]], x[tri[:, 2]] - x[tri[:, 0]])
            inward = np.einsum("ij,ij->i", normal, x[opposite] - x[tri[:, 0]]) > 0
            tri[inward] = tri[inward][:, [0, 2, 1]]
        self.master_local = geometry_to_dof[tri]  # (facets, 3) local block dofs
        self.master_global = np.asarray(V.dofmap.index_map.local_to_global(self.master_local.ravel().astype(np.int32)),
                                        dtype=np.int64).reshape(-1, 3)
        self.master_count = self.comm.allreduce(len(facets), op=MPI.SUM)
        if self.master_count == 0:
            raise ValueError(f"surface: {self.master!r} has no facet")

    def _leave_shared(self) -> None:
        """Leave out of this pair and of every earlier sliding pair of the problem the slave nodes the two share: a
        node tied by sliding springs to two surfaces (the fat's nodes on the rim of the face two touching muscles
        share, tied to both muscles) follows neither; the muscles' own contact holds them together there.
        Collective."""
        for other in self.problem.couplings:
            if not (isinstance(other, BodyContact) and other.kind == "sliding" and other.leave_shared):
                continue
            both = np.intersect1d(self.slave_blocks, other.slave_blocks)
            count = int(self.comm.allreduce(len(both), op=MPI.SUM))
            if count == 0:
                continue
            for pair in (self, other):
                pair.slave_blocks = np.setdiff1d(pair.slave_blocks, both).astype(np.int32)
                pair.left_out += count
                pair._stamp = None  # paired before: pair again
            if other.q_of_block is not None:
                other.slave_q = other.q_of_block[other.slave_blocks]
            log.info("%s and %s: %d slave nodes tied to both left out of both", self.name, other.name, count)

    def potential_reason(self) -> str | None:
        """Why the residual is not the derivative of the pair's energy, or None (ElasticityProblem.potential_reason).
        With smoothed normals it is not: the lagged slip of x* along T changes g = N . (x_s - x*) by the tangential
        part of N (N is not T's normal), which R = k g N leaves out, so R is not dPi_c/du, and a line search on the
        total potential can fail along a Newton direction that does not descend it (the touching layered arm on
        Debian 13's mesh: DIVERGED_LINE_SEARCH from the first step, however small); the solver then takes full
        Newton steps (model.solvers.newton.default_line_search). With T's own normal, R is dPi_c/du where x* is
        inside T (the gap is the distance to T's plane)."""
        if self.smooth_normals:
            return (f"the pair {self.name} uses smoothed normals: its residual is not the derivative of its energy "
                    "(the slip of the closest point is lagged)")
        return None

    def symmetry_reason(self) -> str | None:
        """None: the matrix the pair adds to Newton's, K = d2Pi_c/du2 + C with C = K_uz Pi + Pi^T K_zu +
        Pi^T K_zz Pi (exact: the same with the vertex slots P_i), is the Hessian of Pi_c(u, z = Pi u) at the lagged
        pairing and normal: K_zu = K_uz^T and K_zz = K_zz^T, so K = K^T (ElasticityProblem.symmetry_reason). This
        holds with smoothed normals too: there the residual is not dPi_c/du (potential_reason) and K is not its
        exact derivative, but the matrix is still symmetric (measured: |K - K^T| / |K| ~ 1e-18,
        tests/test_symmetry.py)."""
        return None

    def _gather_master(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every rank's master triangles: reference (m, 3, 3), current (m, 3, 3) and global block dofs (m, 3)."""
        u = self.problem.solution.x.array.reshape(-1, self.bs)
        X = self.reference[self.master_local]
        x = X + u[self.master_local]
        parts = self.comm.allgather((X, x, self.master_global))
        return (np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]),
                np.concatenate([p[2] for p in parts]))

    # --- the pairing -------------------------------------------------------------------------------------
    def update(self, matrices: bool = False) -> None:
        """Pair every owned slave node with its closest master point at the current solution; set X*, n, z and
        the interpolation matrix Pi. ``matrices``: also pair again when Pi (the P_i) was destroyed (destroy) at
        the same solution (the residual and Jacobian need it; the gaps and reports do not). Collective."""
        current = self.problem.solution.x.array
        unmade = matrices and ((not self.P) if self.exact else self.Pi is None)
        changed = self._stamp is None or unmade or not np.array_equal(self._stamp, current)
        if not self.comm.allreduce(changed, op=MPI.LOR):  # decided together: the pairing is collective
            return
        X_tri, x_tri, g_tri = self._gather_master()
        u = current.reshape(-1, self.bs)
        slave = self.slave_blocks
        xs = self.reference[slave] + u[slave]
        best_t, best_b, paired = self._search(xs, x_tri, g_tri)
        best_b = best_b * paired[:, None]  # a node not paired: X* = z = 0, no row in Pi, n = 0 (below): g = 0
        self.paired = paired
        tri_x = x_tri[best_t]
        if self.smooth_normals:  # the area-weighted nodal normals of the master surface, interpolated at x*
            faces = np.cross(x_tri[:, 1] - x_tri[:, 0], x_tri[:, 2] - x_tri[:, 0])
            ids, inverse = np.unique(g_tri.ravel(), return_inverse=True)
            nodal = np.zeros((len(ids), 3))
            np.add.at(nodal, np.asarray(inverse).reshape(-1), np.repeat(faces, 3, axis=0))
            nodal /= np.maximum(np.linalg.norm(nodal, axis=1, keepdims=True), 1e-300)
            normal = np.einsum("ij,ijk->ik", best_b, nodal[np.asarray(inverse).reshape(-1, 3)[best_t]])
        else:
            normal = np.cross(tri_x[:, 1] - tri_x[:, 0], tri_x[:, 2] - tri_x[:, 0])
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
        normal[~paired] = 0.0
        X_star = np.einsum("ij,ijk->ik", best_b, X_tri[best_t])
        z = np.einsum("ij,ijk->ik", best_b, x_tri[best_t] - X_tri[best_t])
        for function, values in ((self.X_star, X_star), (self.normal, normal), (self.z, z)):
            array = function.x.array.reshape(-1, self.bs)
            array[:] = 0.0
            array[slave] = values
            function.x.scatter_forward()
        if self.exact:
            self._set_slots(best_b, X_tri[best_t], x_tri[best_t], g_tri[best_t])
        else:
            if self.Pi is not None:
                self.Pi.destroy()
            self.Pi = self._selection(best_b, g_tri[best_t])
        self._stamp = current.copy()

    def _search(self, xs: np.ndarray, x_tri: np.ndarray, g_tri: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The closest master triangle to each slave point xs (n, 3) among the current master triangles x_tri
        (m, 3, 3) (global block dofs g_tri): its index (n,), barycentric coordinates (n, 3) and whether the node
        is paired (n,; here always). The k = ``neighbours`` triangles of nearest centroids are tried."""
        from scipy.spatial import cKDTree

        n = len(xs)
        k = min(self.neighbours, len(x_tri))
        best_d = np.full(n, np.inf)
        best_t = np.zeros(n, dtype=np.int64)
        best_b = np.zeros((n, 3))
        best_key = np.full(n, np.iinfo(np.int64).max)
        ordered = np.sort(g_tri, axis=1)
        size = int(g_tri.max(initial=0)) + 1
        triangle_key = (ordered[:, 0] * size + ordered[:, 1]) * size + ordered[:, 2]
        if n:
            _, near = cKDTree(x_tri.mean(axis=1)).query(xs, k=k)
            near = np.asarray(near).reshape(n, k)
            for j in range(k):
                closest, bary = closest_points_on_triangles(xs, x_tri[near[:, j]])
                d = np.linalg.norm(xs - closest, axis=1)
                tol = 1e-14 * np.maximum(d, 1.0)
                better = d < best_d - tol
                if self.smallest_ties:  # ties (a node on an edge, a vertex, a bisector) to the smallest triangle:
                    key = triangle_key[near[:, j]]  # the same choice on any partition
                    better |= (np.abs(d - best_d) <= tol) & (key < best_key)
                best_key = np.where(better, triangle_key[near[:, j]], best_key)
                best_d[better], best_t[better], best_b[better] = d[better], near[better, j], bary[better]
        return best_t, best_b, np.ones(n, dtype=bool)

    def _set_slots(self, bary: np.ndarray, X_tri: np.ndarray, x_tri: np.ndarray, columns: np.ndarray) -> None:
        """Exact sliding: the region of each slave node's closest point (the number of nonzero b_j: 1 vertex,
        2 edge, 3 face; Ericson's regions give exact zeros), its triangle's vertices ordered with the region's
        vertex or edge first, their reference positions X_i and displacements z_i, and the selection matrices P_i
        (row (slave node, c) = e_(vertex i, c)). Nodes that are not paired (not slave, left out) get region 0 and a
        fixed non-degenerate triangle (the unused branches of the distance stay finite). Collective."""
        slave, n = self.slave_blocks, len(self.slave_blocks)
        nonzero = bary != 0.0
        order = np.argsort(~nonzero, axis=1, kind="stable") if self.kind == "sliding" else \
            np.tile(np.arange(3), (n, 1))  # contact: T's own order, (x_2 - x_1) x (x_3 - x_1) outward
        rows = np.arange(n)[:, None]
        X_o, u_o, cols = X_tri[rows, order], (x_tri - X_tri)[rows, order], columns[rows, order]
        filler = self.size * np.eye(3)
        for i in range(3):
            for function, values, rest in ((self.vertices[i], X_o[:, i], filler[i]), (self.slots[i], u_o[:, i], 0.0)):
                array = function.x.array.reshape(-1, self.bs)
                array[:] = rest
                array[slave] = values
                function.x.scatter_forward()
        self.region.x.array[:] = 0.0
        self.region.x.array[self.slave_q] = nonzero.sum(axis=1)
        self.region.x.scatter_forward()
        for P in self.P:
            P.destroy()
        self.P = [self._selection(np.ones((n, 1)), cols[:, i:i + 1]) for i in range(3)]

    def _selection(self, weights: np.ndarray, columns: np.ndarray) -> PETSc.Mat:
        """The matrix with row (slave node s, component c) = sum_j weights[s, j] e_(columns[s, j], component c)
        (global indices): Pi (the b_j of the closest point's triangle) or a vertex slot's P_i."""
        imap = self.V.dofmap.index_map
        bs = self.bs
        n_local, n_global = imap.size_local * bs, imap.size_global * bs
        Pi = PETSc.Mat().createAIJ(((n_local, n_global), (n_local, n_global)), nnz=(3, 3), comm=self.comm)
        Pi.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
        rows = np.asarray(imap.local_to_global(self.slave_blocks.astype(np.int32)), dtype=np.int64)
        index = PETSc.IntType
        for c in range(bs):
            for r, cols, w in zip(rows, columns, weights):
                Pi.setValues(np.array([r * bs + c], dtype=index), (cols * bs + c).astype(index), w,
                             addv=PETSc.InsertMode.INSERT)
        Pi.assemble()
        return Pi

    def _form(self, key: str) -> Any:
        if key not in self._compiled:
            self._compiled[key] = fem.form(self._ufl[key])
        return self._compiled[key]

    # --- the Newton solver's hooks ------------------------------------------------------------------------
    def add_residual(self, b: PETSc.Vec) -> None:
        """b += Pi^T dPi_c/dz (exact sliding: sum_i P_i^T dPi_c/dz_i; b: the assembled residual, reverse-scattered).
        Collective."""
        self.update(matrices=True)
        terms = [(f"Rz{i}", P) for i, P in enumerate(self.P)] if self.exact else [("Rz", self.Pi)]
        for key, P in terms:
            Rz = fem_petsc.assemble_vector(self._form(key))
            Rz.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            out = P.createVecRight()
            P.multTranspose(Rz, out)
            extra = out.array_r  # the owned entries (a vector without ghosts has no local form under MPI)
            with b.localForm() as local:
                local.array[: len(extra)] += extra
            Rz.destroy()
            out.destroy()

    def contact_residual(self) -> PETSc.Vec:
        """The pair's own nodal forces on the body's dofs, r = dPi_c/du + Pi^T dPi_c/dz at the current solution (minus
        the contact force on each node; owned entries summed over the ranks). Collective."""
        self.update(matrices=True)
        if "Ru" not in self._ufl:
            self._ufl["Ru"] = ufl.derivative(self.energy, self.problem.solution, ufl.TestFunction(self.V))
        r = fem_petsc.assemble_vector(self._form("Ru"))
        r.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        self.add_residual(r)
        return r

    def _assembled(self, key: str) -> PETSc.Mat:
        """The form's matrix K, assembled into the matrix made for it once (the forms live on the slave surface:
        their sparsity pattern never changes; a new matrix and pattern per call was half of the coupling's time).
        Owned by the pair: the caller does not destroy it."""
        K = self._matrices.get(key)
        if K is None:
            K = self._matrices[key] = fem_petsc.create_matrix(self._form(key))
        else:
            K.zeroEntries()
        fem_petsc.assemble_matrix(K, self._form(key))
        K.assemble()
        return K

    def _summed(self, terms: list[PETSc.Mat]) -> PETSc.Mat:
        """sum_t M_t (parallel AIJ matrices of V's layout) in one pass, the same numbers as a MatAXPY per term (each
        of which built a new union pattern): each term's owned rows (CSR, global columns) added with scipy in the
        given order (((M_0 + M_1) + M_2) ...), one matrix from the sum. scipy leaves out exact zeros: the
        vertex-measure forms' element pattern makes most of K's stored entries zero, and as MatAXPY kept them
        they grew A's pattern and its factorisation (A's values are the same; its factorisation's round-off
        not). The terms are destroyed. Collective."""
        sizes = terms[0].getSizes()
        shape = (sizes[0][0], sizes[1][1])
        total: csr_matrix | None = None
        for M in terms:
            indptr, indices, values = M.getValuesCSR()  # new arrays (copies)
            part = csr_matrix((values, indices, indptr), shape=shape)
            total = part if total is None else total + part
            M.destroy()
        assert total is not None
        total.eliminate_zeros()  # a single term's stored zeros (the sums leave out theirs)
        total.sort_indices()
        index = PETSc.IntType
        C = PETSc.Mat().createAIJ(sizes, csr=(total.indptr.astype(index), total.indices.astype(index), total.data),
                                  comm=self.comm)
        C.assemble()
        return C

    def _exact_coupling(self) -> PETSc.Mat:
        """sum_i (K_u,zi P_i + P_i^T K_zi,u) + sum_ij P_i^T K_zi,zj P_j (K_zj,zi = K_zi,zj^T: the i < j terms once,
        with their transposes), summed in one pass (_summed)."""
        terms: list[PETSc.Mat] = []

        def add(M: PETSc.Mat, symmetric: bool) -> None:
            terms.append(M)
            if symmetric:  # a new matrix (transpose() without one transposes M in place)
                terms.append(M.transpose(PETSc.Mat()))

        for i, Pi in enumerate(self.P):
            add(self._assembled(f"Kuz{i}").matMult(Pi), True)
            for j in range(i, 3):
                K = self._assembled(f"Kzz{i}{j}")
                if i == j:
                    add(K.PtAP(Pi), False)
                else:
                    KP = K.matMult(self.P[j])
                    add(Pi.transposeMatMult(KP), True)
                    KP.destroy()
        return self._summed(terms)

    def coupling_matrix(self) -> PETSc.Mat:
        """C = K_uz Pi + Pi^T K_zu + Pi^T K_zz Pi (exact sliding: _exact_coupling) with the rows and columns of the
        Dirichlet dofs zeroed; K_uz and K_zz assembled into matrices made once, the three products summed in one
        pass (_summed)."""
        self.update(matrices=True)
        if self.exact:
            C = self._exact_coupling()
        else:
            C1 = self._assembled("Kuz").matMult(self.Pi)
            C = self._summed([C1, C1.transpose(PETSc.Mat()), self._assembled("Kzz").PtAP(self.Pi)])
        C.zeroRowsColumns(self._dirichlet_rows(), diag=0.0)
        return C

    def _dirichlet_rows(self) -> np.ndarray:
        imap, bs = self.V.dofmap.index_map, self.bs
        owned = imap.size_local * bs
        dofs = [np.asarray(bc.dof_indices()[0], dtype=np.int64) for bc in self.problem.bcs]
        local = np.unique(np.concatenate(dofs)) if dofs else np.empty(0, dtype=np.int64)
        local = local[local < owned]
        blocks = np.asarray(imap.local_to_global((local // bs).astype(np.int32)), dtype=np.int64)
        return (blocks * bs + local % bs).astype(PETSc.IntType)

    def add_jacobian(self, A: PETSc.Mat) -> None:
        """A += C (coupling_matrix; A assembled), new nonzeros allowed (the master-slave couplings move): MatAXPY
        with a different nonzero pattern, which builds the union pattern at once (inserting C row by row into A
        reallocated A at every new nonzero: 5 s of a 10k-dof Hertz run). Collective."""
        C = self.coupling_matrix()
        A.axpy(1.0, C, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
        C.destroy()

    def destroy(self) -> None:
        """Free the pair's PETSc matrices: Pi (exact sliding: the P_i) and the K forms' matrices (_assembled).
        Under MPI petsc4py does not destroy a parallel object the garbage collector frees: it waits on its
        communicator's garbage list for a collective PETSc.garbage_cleanup, so without this each problem of a
        study left them allocated. They are made again when needed (the next pairing, the next assembly): the
        pair stays usable (model.solvers.newton.NewtonSolver.destroy calls this). Collective."""
        for M in [self.Pi, *self.P, *self._matrices.values()]:
            if M is not None:
                M.destroy()
        self.Pi, self.P, self._matrices = None, [], {}  # update pairs again (and makes them) before they are used

    # --- the augmented Lagrangian (model.solvers.contact.UzawaSolver drives it) -----------------------------
    def nodal_gaps(self) -> np.ndarray:
        """g at the owned slave nodes, at the current solution (paired again if it changed). Collective."""
        self.problem.update_state()
        u = self.problem.solution.x.array.reshape(-1, self.bs)
        slave = self.slave_blocks
        r = (self.reference[slave] + u[slave] - self.X_star.x.array.reshape(-1, self.bs)[slave]
             - self.z.x.array.reshape(-1, self.bs)[slave])
        normal = self.normal.x.array.reshape(-1, self.bs)[slave]
        if self.exact and self.kind == "sliding":  # the signed distance: |x_s - x*| on the side of T's normal
            return np.sign(np.einsum("ij,ij->i", normal, r)) * np.linalg.norm(r, axis=1)
        return np.einsum("ij,ij->i", normal, r)

    @property
    def absolute_tolerance(self) -> float:
        """The largest |min(g, lambda/k)| accepted: ``tolerance`` times the body's bounding-box diagonal."""
        return self.tolerance * self.size

    def uzawa_residual(self) -> float:
        """max_i |min(g_i, lambda_i / k)| over the slave nodes (all ranks): 0 at the exact solution."""
        lam = self.multiplier.x.array[self.slave_q]
        local = np.abs(np.minimum(self.nodal_gaps(), lam / float(self.k.value)))
        return float(self.comm.allreduce(float(local.max(initial=0.0)), op=MPI.MAX))

    def update_multiplier(self) -> None:
        """lambda_i <- max(lambda_i - k g_i, 0) at the slave nodes (Uzawa)."""
        gap = self.nodal_gaps()
        lam = self.multiplier.x.array
        lam[self.slave_q] = np.maximum(lam[self.slave_q] - float(self.k.value) * gap, 0.0)
        self.multiplier.x.scatter_forward()

    # --- report -------------------------------------------------------------------------------------------
    def report(self) -> dict[str, Any]:
        """max_penetration (max(0, -min g) over the slave nodes), max_gap (max(0, max g)), force on the slave body
        (int p n dA, p = -k min(g, 0), augmented max(lambda - k g, 0); sliding: p = -k g), normal_force (the total
        normal force int p dA: > 0 pressing), active_points (slave nodes with g < 0; augmented: p > 0), the same on
        every rank."""
        gap = self.nodal_gaps()
        low = self.comm.allreduce(float(gap.min(initial=np.inf)), op=MPI.MIN)
        high = self.comm.allreduce(float(gap.max(initial=-np.inf)), op=MPI.MAX)
        pressed = gap < 0.0 if not self.augmented else \
            contact_pressure(gap, self.k.value, self.multiplier.x.array[self.slave_q]) > 0.0
        active = self.comm.allreduce(int(np.sum(pressed)), op=MPI.SUM)
        force = [float(self.comm.allreduce(fem.assemble_scalar(self._form(f"force{i}")), op=MPI.SUM))
                 for i in range(3)]
        normal = float(self.comm.allreduce(fem.assemble_scalar(self._form("normal_force")), op=MPI.SUM))
        return {"pair": self.name, "kind": self.kind, "surface": self.slave, "master": self.master,
                "max_penetration": max(0.0, -low), "max_gap": max(0.0, high), "force": force,
                "normal_force": normal, "active_points": active}

    def contact_report(self) -> dict[str, Any]:
        """{"max_penetration", "force", "active_points"} as the rigid contacts give it
        (model.problem.contact.contact_report); ``report`` has the rest."""
        report = self.report()
        return {k: report[k] for k in ("max_penetration", "force", "active_points")}


__all__ = ["BodyContact", "KINDS", "closest_points_on_triangles"]
