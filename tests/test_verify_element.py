"""``verify element`` (model/verify/element.py) against elements written here in numpy.

Independent implementations: a P1 tetrahedron (B matrix from the shape-function gradients, f = V P B,
K from the closed-form neo-Hookean A), a 10-node tetrahedron in VTK order (quadratic shape functions,
isoparametric map, an exact conical-product Gauss rule for the polynomial StVK integrand and the classic
4-point rule for neo-Hookean) and a trilinear hexahedron with 2x2x2 Gauss points. Node orderings are
written here from the VTK, gmsh and basix documentation (edge tables), not taken from the module.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, environment, serial_only
from mpi4py import MPI

from model import compat
from model.verify import element as el

MU, LMBDA = 1.3, 2.1
I3 = np.eye(3)
REF_TET = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
#: edge nodes 4..9 of the 10-node tetrahedron, per convention (vtkQuadraticTetra docs; gmsh's node ordering
#: section; basix's reference tetrahedron edges)
EDGES = {"vtk": [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)],
         "gmsh": [(0, 1), (1, 2), (0, 2), (0, 3), (2, 3), (1, 3)],
         "dolfinx": [(2, 3), (1, 3), (1, 2), (0, 3), (0, 2), (0, 1)]}
#: the unit cube's corners: VTK_HEXAHEDRON (= gmsh), and basix's tensor-product order
HEX_CORNERS = {"vtk": [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)],
               "dolfinx": [(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0), (0, 0, 1), (1, 0, 1), (0, 1, 1), (1, 1, 1)]}
HEX_CORNERS["gmsh"] = HEX_CORNERS["vtk"]


# --- independent numpy elements -------------------------------------------------------------------------------

def neo_hookean(F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """P = mu (F - F^-T) + lmbda ln J F^-T and A_iKjL = mu d_ij d_KL + lmbda G_iK G_jL + (mu - lmbda ln J)
    Finv_Kj Finv_Li (G = F^-T), for psi = mu/2 (tr C - 3) - mu ln J + lmbda/2 (ln J)^2."""
    Finv = np.linalg.inv(F)
    G = Finv.T
    lnJ = np.log(np.linalg.det(F))
    P = MU * (F - G) + LMBDA * lnJ * G
    A = (MU * np.einsum("ij,KL->iKjL", I3, I3) + LMBDA * np.einsum("iK,jL->iKjL", G, G)
         + (MU - LMBDA * lnJ) * np.einsum("Kj,Li->iKjL", Finv, Finv))
    return P, A


def stvk(F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """P = F S, S = 2 mu E + lmbda tr E I; A_iKjL = d_ij S_KL + mu (F_iL F_jK + (F F^T)_ij d_KL) + lmbda F_iK F_jL."""
    E = 0.5 * (F.T @ F - I3)
    S = 2 * MU * E + LMBDA * np.trace(E) * I3
    A = (np.einsum("ij,KL->iKjL", I3, S) + MU * (np.einsum("iL,jK->iKjL", F, F) + np.einsum("ij,KL->iKjL", F @ F.T, I3))
         + LMBDA * np.einsum("iK,jL->iKjL", F, F))
    return F @ S, A


def element_numpy(law, grads: list[np.ndarray], weights: list[float], u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """f = sum_q w_q P_q B_q, K = sum_q w_q B_q^T A_q B_q with B_q the (9, 3n) matrix dF_iK/du_aj = d_ij dN_a/dX_K.

    grads[q]: (n, 3) physical gradients dN_a/dX at point q; weights include |det J|."""
    n = len(u)
    f = np.zeros(3 * n)
    K = np.zeros((3 * n, 3 * n))
    for g, w in zip(grads, weights):
        B = np.zeros((3, 3, n, 3))  # [i, K, a, j]
        for i in range(3):
            B[i, :, :, i] = g.T
        B = B.reshape(9, 3 * n)
        F = I3 + u.T @ g
        P, A = law(F)
        f += w * B.T @ P.reshape(9)
        K += w * B.T @ A.reshape(9, 9) @ B
    return f, K


def p1_numpy(law, X: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The P1 tetrahedron: gradients of N_1..N_3 are the rows of Dm^-1 (Dm = [X1-X0, X2-X0, X3-X0]), N_0 = -sum."""
    Dm = (X[1:] - X[0]).T
    Dinv = np.linalg.inv(Dm)
    g = np.vstack([-Dinv.sum(axis=0), Dinv])
    V = abs(np.linalg.det(Dm)) / 6.0
    return element_numpy(law, [g], [V], u)


def tet10_shape_gradients(xi: np.ndarray) -> np.ndarray:
    """(10, 3) dN/dxi of the quadratic tetrahedron in VTK order at reference point xi: vertices
    L_a (2 L_a - 1), edge (a, b) 4 L_a L_b, with L = (1 - xi - eta - zeta, xi, eta, zeta)."""
    L = np.array([1 - xi.sum(), *xi])
    dL = np.vstack([-np.ones(3), I3])
    dN = [(4 * L[a] - 1) * dL[a] for a in range(4)]
    dN += [4 * (L[a] * dL[b] + L[b] * dL[a]) for a, b in EDGES["vtk"]]
    return np.array(dN)


def conical_rule(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre on the cube mapped to the tetrahedron (xi = s, eta = (1-s) t, zeta = (1-s)(1-t) w,
    Jacobian (1-s)^2 (1-t)): exact for polynomials of degree <= 2n - 3."""
    x, w = np.polynomial.legendre.leggauss(n)
    x, w = 0.5 * (x + 1), 0.5 * w
    pts, wts = [], []
    for s, ws in zip(x, w):
        for t, wt in zip(x, w):
            for r, wr in zip(x, w):
                pts.append([s, (1 - s) * t, (1 - s) * (1 - t) * r])
                wts.append(ws * wt * wr * (1 - s) ** 2 * (1 - t))
    return np.array(pts), np.array(wts)


def four_point_rule() -> tuple[np.ndarray, np.ndarray]:
    """The classic symmetric 4-point rule of degree 2: (a, a, a) and its permutations with b = 1 - 3a,
    a = (5 - sqrt 5)/20."""
    a = (5 - np.sqrt(5)) / 20
    b = 1 - 3 * a
    return np.array([[b, a, a], [a, b, a], [a, a, b], [a, a, a]]), np.full(4, 1 / 24)


def isoparametric_numpy(law, X: np.ndarray, u: np.ndarray, rule, shape_gradients) -> tuple[np.ndarray, np.ndarray]:
    grads, weights = [], []
    for xi, w in zip(*rule):
        dN = shape_gradients(xi)
        J = X.T @ dN  # dX/dxi
        grads.append(dN @ np.linalg.inv(J))
        weights.append(w * abs(np.linalg.det(J)))
    return element_numpy(law, grads, weights, u)


def hex8_shape_gradients(xi: np.ndarray) -> np.ndarray:
    """(8, 3) gradients of the trilinear shape functions prod_k (c_k xi_k + (1 - c_k)(1 - xi_k)), VTK corners."""
    out = []
    for c in np.array(HEX_CORNERS["vtk"]):
        f = np.where(c == 1, xi, 1 - xi)
        df = np.where(c == 1, 1.0, -1.0)
        out.append([df[0] * f[1] * f[2], f[0] * df[1] * f[2], f[0] * f[1] * df[2]])
    return np.array(out)


def gauss_2x2x2() -> tuple[np.ndarray, np.ndarray]:
    g = np.array([(1 - 1 / np.sqrt(3)) / 2, (1 + 1 / np.sqrt(3)) / 2])
    return np.array([[a, b, c] for a in g for b in g for c in g]), np.full(8, 1 / 8)


# --- elements used below ------------------------------------------------------------------------------------------

def tet4_element(seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    X = 2.0 * REF_TET + 0.2 * rng.standard_normal((4, 3))
    return X, 0.15 * rng.standard_normal((4, 3))


def tet10_element(order: str = "vtk", curved: bool = False, seed: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Nodes of one straight (or curved) 10-node tet in the given convention; displacements asymmetric (each
    node its own random vector, so that exchanging any two edge nodes changes f and K)."""
    rng = np.random.default_rng(seed)
    V = REF_TET @ np.array([[1.2, 0.1, 0.0], [0.0, 0.9, 0.2], [0.1, 0.0, 1.1]]) + [0.3, -0.2, 0.5]
    u_v = 0.1 * rng.standard_normal((4, 3))
    bump = {e: (0.04 * rng.standard_normal(3) if curved else np.zeros(3), 0.1 * rng.standard_normal(3))
            for e in EDGES["vtk"]}
    X = [*V]
    u = [*u_v]
    for a, b in EDGES[order]:
        key = (min(a, b), max(a, b))
        X.append(0.5 * (V[a] + V[b]) + bump[key][0])
        u.append(bump[key][1])
    return np.array(X), np.array(u)


def hex8_element(order: str = "vtk", seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    corners = np.array(HEX_CORNERS["vtk"], dtype=float)
    X0 = corners * [1.5, 1.0, 0.8] + 0.08 * rng.standard_normal((8, 3))  # a distorted (non-affine) hexahedron
    u0 = 0.08 * rng.standard_normal((8, 3))
    index = [HEX_CORNERS["vtk"].index(c) for c in HEX_CORNERS[order]]
    return X0[index], u0[index]


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


# --- the reference against the numpy elements ---------------------------------------------------------------------

def test_tet4_neo_hookean_against_hand_derived_element() -> None:
    X, u = tet4_element()
    f, K = el.element_reference("neo_hookean", {"mu": MU, "lmbda": LMBDA}, X, u, "tet4")
    f_np, K_np = p1_numpy(neo_hookean, X, u)
    assert rel(f, f_np) < 1e-10 and rel(K, K_np) < 1e-10
    assert np.linalg.norm(f_np) > 0.1  # a real deformation, not the rest state


def test_tet10_stvk_exact_quadrature_against_numpy() -> None:
    """Straight-sided tet10, StVK: the integrands are polynomials of degree 4, exact in both (degree 4; 5^3 conical)."""
    X, u = tet10_element()
    f, K = el.element_reference("stvk", {"mu": MU, "lmbda": LMBDA}, X, u, "tet10", quadrature_degree=4)
    f_np, K_np = isoparametric_numpy(stvk, X, u, conical_rule(5), tet10_shape_gradients)
    assert rel(f, f_np) < 1e-10 and rel(K, K_np) < 1e-10


def test_tet10_neo_hookean_curved_default_rule() -> None:
    """Curved (isoparametric) tet10, neo-Hookean, the default rule = the classic 4-point rule."""
    X, u = tet10_element(curved=True)
    points, weights = el.quadrature_rule("tet10")
    a = (5 - np.sqrt(5)) / 20
    assert len(weights) == 4 and np.allclose(np.sort(points, axis=None), np.sort(four_point_rule()[0], axis=None))
    assert np.isclose(np.sort(points[:, 0])[0], a)
    f, K = el.element_reference("neo_hookean", {"mu": MU, "lmbda": LMBDA}, X, u, "tet10")
    f_np, K_np = isoparametric_numpy(neo_hookean, X, u, four_point_rule(), tet10_shape_gradients)
    assert rel(f, f_np) < 1e-10 and rel(K, K_np) < 1e-10
    # the edge nodes matter: exchanging the vtk nodes 8 (edge 1-3) and 9 (edge 2-3) in the numpy element disagrees
    swap = [0, 1, 2, 3, 4, 5, 6, 7, 9, 8]
    f_swapped, _ = isoparametric_numpy(neo_hookean, X[swap], u[swap], four_point_rule(), tet10_shape_gradients)
    assert rel(f_swapped[(3 * np.array(swap)[:, None] + np.arange(3)).reshape(-1)], f) > 1e-2


def test_tet10_custom_rule_against_numpy(tmp_path: Path) -> None:
    """A rule of the user's own (27-point conical Gauss, not basix's) on a curved neo-Hookean tet10: the reference
    uses exactly those points; the 4-point rule given as points equals the default degree 2; bad rules are refused."""
    X, u = tet10_element(curved=True, seed=4)
    params = {"mu": MU, "lmbda": LMBDA}
    rule = conical_rule(3)
    f, K = el.element_reference("neo_hookean", params, X, u, "tet10", quadrature=rule)
    f_np, K_np = isoparametric_numpy(neo_hookean, X, u, rule, tet10_shape_gradients)
    assert rel(f, f_np) < 1e-10 and rel(K, K_np) < 1e-10
    # a rule that differs in the 9th digit is a different rule (not a cached kernel of the first one)
    moved = (rule[0] + np.where(np.arange(len(rule[1]))[:, None] == 0, 3e-9, 0.0), rule[1])
    f_moved, _ = el.element_reference("neo_hookean", params, X, u, "tet10", quadrature=moved)
    f_moved_np, _ = isoparametric_numpy(neo_hookean, X, u, moved, tet10_shape_gradients)
    assert rel(f_moved, f_moved_np) < 1e-13 < rel(f_moved, f)
    f4, K4 = el.element_reference("neo_hookean", params, X, u, "tet10", quadrature=four_point_rule())
    f2, K2 = el.element_reference("neo_hookean", params, X, u, "tet10")
    assert rel(f4, f2) < 1e-12 and rel(K4, K2) < 1e-12 and rel(f4, f) > 1e-8  # the rule matters here
    path = _file(tmp_path, "custom", X, u, f_np, K_np, cell="tet10", quadrature_points=rule[0].tolist(),
                 quadrature_weights=rule[1].tolist())
    report = el.check_element(path)
    assert report.ok and "custom rule of 27 points" in report.format(), report.format()
    with pytest.raises(ValueError, match="quadrature_weights: they sum to 1, must sum"):
        el.element_reference("neo_hookean", params, X, u, "tet10", quadrature=(rule[0], 6 * rule[1]))
    with pytest.raises(ValueError, match="quadrature_points: point 0"):
        el.element_reference("neo_hookean", params, X, u, "tet10", quadrature=(rule[0] + 1.0, rule[1]))
    with pytest.raises(ValueError, match="polar rotation"):
        el.element_reference("corotated", params, X, u, "tet10", quadrature=rule)


def test_hex8_gauss_2x2x2_against_numpy() -> None:
    points, weights = el.quadrature_rule("hex8")
    gp, gw = gauss_2x2x2()
    assert np.allclose(np.sort(points, axis=0), np.sort(gp, axis=0), atol=1e-14) and np.allclose(weights, gw)
    assert {tuple(p) for p in np.round(points, 12)} == {tuple(p) for p in np.round(gp, 12)}
    X, u = hex8_element()
    f, K = el.element_reference("neo_hookean", {"mu": MU, "lmbda": LMBDA}, X, u, "hex8")
    f_np, K_np = isoparametric_numpy(neo_hookean, X, u, (gp, gw), hex8_shape_gradients)
    assert rel(f, f_np) < 1e-10 and rel(K, K_np) < 1e-10


def test_rotation_law_is_symmetric_and_consistent() -> None:
    """corotated (polar rotation) on a tet10: K symmetric and equal to central differences of f."""
    X, u = tet10_element(curved=True)
    params = {"mu": MU, "lmbda": LMBDA}
    f, K = el.element_reference("corotated", params, X, u, "tet10")
    assert np.linalg.norm(K - K.T) < 1e-12 * np.linalg.norm(K)
    h = 1e-6
    for k in (0, 13, 29):
        du = np.zeros(30)
        du[k] = h
        fp, _ = el.element_reference("corotated", params, X, u + du.reshape(10, 3), "tet10")
        fm, _ = el.element_reference("corotated", params, X, u - du.reshape(10, 3), "tet10")
        assert np.linalg.norm((fp - fm) / (2 * h) - K[:, k]) < 1e-6 * np.linalg.norm(K[:, k])


def test_assembler_reuses_one_cell_for_many_displacements_and_fields() -> None:
    """ElementAssembler (compiled once, as verify seeds uses it): each u against the numpy P1 element; a changed
    field S gives what a fresh assembly with that S gives."""
    X, _ = tet4_element()
    assembler = el.ElementAssembler("neo_hookean", {"mu": MU, "lmbda": LMBDA}, X, "tet4")
    rng = np.random.default_rng(11)
    for _ in range(3):
        u = 0.2 * rng.standard_normal((4, 3))
        ref = assembler.assemble(u)
        f_np, K_np = p1_numpy(neo_hookean, X, u)
        assert rel(ref.f, f_np) < 1e-10 and rel(ref.K, K_np) < 1e-10
    S1, S2 = np.diag([1.1, 0.9, 1.0]), np.array([[1.3, 0.2, 0.0], [0.2, 0.8, 0.1], [0.0, 0.1, 1.2]])
    target = el.ElementAssembler("shape_target", {"mu": 1.0, "kappa": 3.0}, X, "tet4", fields={"S": S1})
    u = 0.2 * rng.standard_normal((4, 3))
    first = target.assemble(u)
    second = target.assemble(u, fields={"S": S2})
    fresh = el.assemble_element("shape_target", {"mu": 1.0, "kappa": 3.0}, X, u, "tet4", fields={"S": S2})
    assert rel(second.f, fresh.f) < 1e-13 and rel(second.K, fresh.K) < 1e-13 and rel(first.f, second.f) > 1e-3
    with pytest.raises(ValueError, match="fields: S has shape"):
        target.assemble(u, fields={"S": np.eye(2)})


# --- node orderings ------------------------------------------------------------------------------------------------

def _match(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """m with a[m[i]] == b[i] (rows matched by coordinates)."""
    return np.array([int(np.argmin(np.linalg.norm(a - x, axis=1))) for x in b])


def _renumbered(f: np.ndarray, K: np.ndarray, m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    idx = (3 * m[:, None] + np.arange(3)).reshape(-1)
    return f[idx], K[np.ix_(idx, idx)]


@pytest.mark.parametrize("cell", ["tet10", "hex8"])
def test_every_node_order_round_trips(cell: str) -> None:
    make = tet10_element if cell == "tet10" else hex8_element
    X, u = make("vtk")
    params = {"mu": MU, "lmbda": LMBDA}
    f, K = el.element_reference("neo_hookean", params, X, u, cell, node_order="vtk")
    for order in ("gmsh", "dolfinx"):
        Xo, uo = make(order)
        fo, Ko = el.element_reference("neo_hookean", params, Xo, uo, cell, node_order=order)
        fr, Kr = _renumbered(f, K, _match(X, Xo))
        assert rel(fo, fr) < 1e-12 and rel(Ko, Kr) < 1e-12, order
    # an explicit permutation: a shuffled numbering, p[j] = the user's node of dolfinx node j
    Xd, ud = make("dolfinx")
    shuffle = np.random.default_rng(7).permutation(len(Xd))
    p = np.argsort(shuffle)  # user node k is dolfinx node shuffle[k]
    fp, Kp = el.element_reference("neo_hookean", params, Xd[shuffle], ud[shuffle], cell, node_order=p.tolist())
    fr, Kr = _renumbered(f, K, _match(X, Xd[shuffle]))
    assert rel(fp, fr) < 1e-12 and rel(Kp, Kr) < 1e-12
    # a wrong convention for the same numbers is a different (distorted) element
    if cell == "tet10":
        Xg, ug = make("gmsh")
        fw, _ = el.element_reference("neo_hookean", params, Xg, ug, cell, node_order="vtk")
        assert rel(fw, _renumbered(f, K, _match(X, Xg))[0]) > 1e-3


def test_gmsh_orders_agree_with_dolfinx_io() -> None:
    """The module's gmsh tables equal dolfinx's own gmsh -> dolfinx permutation (dolfinx.io)."""
    assert el.node_permutation("tet10", "gmsh").tolist() == compat.gmsh_node_order("tetrahedron", 10).tolist()
    assert el.node_permutation("tet4", "gmsh").tolist() == compat.gmsh_node_order("tetrahedron", 4).tolist()


# --- check_element ----------------------------------------------------------------------------------------------------

def _file(tmp_path: Path, name: str, X, u, f=None, K=None, cell="tet4", order="vtk", material="neo_hookean",
          fmt: str = "json", **extra) -> Path:
    content = {"cell": cell, "node_order": order, "material": material, "params": {"mu": MU, "lmbda": LMBDA},
               "X": np.asarray(X).tolist(), "u": np.asarray(u).tolist(), **extra}
    if f is not None:
        content["f"] = np.asarray(f).tolist()
    if K is not None:
        content["K"] = np.asarray(K).tolist()
    path = tmp_path / f"{name}.{fmt}"
    if fmt == "json":
        path.write_text(json.dumps(content))
    else:
        arrays = {k: np.asarray(v) for k, v in content.items() if k != "params"}
        np.savez(path, params_json=np.array(json.dumps(content["params"])), **arrays)
    return path


def test_check_accepts_a_right_element_and_catches_wrong_ones(tmp_path: Path) -> None:
    X, u = tet4_element()
    f, K = p1_numpy(neo_hookean, X, u)
    for fmt in ("json", "npz"):
        report = el.check_element(_file(tmp_path, "right", X, u, f, K, fmt=fmt))
        assert report.ok, report.format()
        assert all(r.rel_error < 1e-10 for r in report.rows)

    def half_mu(F):  # a tangent with mu/2 in its first term
        P, A = neo_hookean(F)
        return P, A - 0.5 * MU * np.einsum("ij,KL->iKjL", I3, I3)

    _, K_bad = p1_numpy(half_mu, X, u)
    report = el.check_element(_file(tmp_path, "half_mu", X, u, f, K_bad))
    rows = {r.quantity: r for r in report.rows}
    assert not report.ok and rows["f"].ok and not rows["K"].ok and rows["K"].rel_error > 1e-3

    def missing_term(F):  # P without the lmbda ln J term
        P, A = neo_hookean(F)
        return P - LMBDA * np.log(np.linalg.det(F)) * np.linalg.inv(F).T, A

    f_bad, _ = p1_numpy(missing_term, X, u)
    report = el.check_element(_file(tmp_path, "missing", X, u, f_bad, K))
    assert not report.ok and "node" in {r.quantity: r for r in report.rows}["f"].worst


def test_check_hints(tmp_path: Path) -> None:
    X, u = tet4_element()
    f, K = p1_numpy(neo_hookean, X, u)
    report = el.check_element(_file(tmp_path, "sign", X, u, -f, -K))
    assert not report.ok and any("opposite sign" in h for h in report.hints), report.format()
    swap = [0, 2, 1, 3]  # the user's code returns f, K with nodes 1 and 2 exchanged
    fs, Ks = _renumbered(f, K, np.array(swap))
    report = el.check_element(_file(tmp_path, "swap", X, u, fs, Ks))
    assert not report.ok and any("nodes 1 and 2 swapped" in h for h in report.hints), report.format()
    blocked = np.array([3 * a + i for i in range(3) for a in range(4)])
    report = el.check_element(_file(tmp_path, "blocked", X, u, f[blocked], K[np.ix_(blocked, blocked)]))
    assert not report.ok and any("component-major" in h for h in report.hints), report.format()
    report = el.check_element(_file(tmp_path, "factor", X, u, f, 0.5 * K))
    assert any("0.5 times" in h for h in report.hints), report.format()
    # a tet10 numbered as gmsh does but declared vtk
    Xg, ug = tet10_element("gmsh")
    fg, Kg = el.element_reference("neo_hookean", {"mu": MU, "lmbda": LMBDA}, Xg, ug, "tet10", node_order="gmsh")
    report = el.check_element(_file(tmp_path, "gmsh", Xg, ug, fg, Kg, cell="tet10", order="vtk"))
    assert not report.ok and any("node_order = 'gmsh'" in h for h in report.hints), report.format()
    assert el.check_element(_file(tmp_path, "gmsh_ok", Xg, ug, fg, Kg, cell="tet10", order="gmsh")).ok


def test_undefined_tangent_leaves_K_out(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Where the law says its tangent is undefined at a quadrature point (Law.tangent_undefined), K is not
    compared (a note with the count) and f still is."""
    from forms.isotropic import NeoHookean

    X, u = tet4_element()
    f, K = p1_numpy(neo_hookean, X, u)
    seen = []

    def undefined(self, F, **fields):
        seen.append(np.array(F))
        return np.ones(len(F), dtype=bool)

    monkeypatch.setattr(NeoHookean, "tangent_undefined", undefined)
    report = el.check_element(_file(tmp_path, "undefined", X, u, f, 2 * K))
    assert report.ok and [r.quantity for r in report.rows] == ["f"], report.format()
    assert any("K not checked" in h and "1 of 1 quadrature points" in h for h in report.hints)
    F_expected = I3 + u.T @ np.vstack([-np.linalg.inv((X[1:] - X[0]).T).sum(axis=0), np.linalg.inv((X[1:] - X[0]).T)])
    assert np.allclose(seen[-1][0], F_expected, atol=1e-12)  # the law is asked at the element's own F
    with pytest.raises(ValueError, match="K not checked"):
        el.check_element(_file(tmp_path, "only_K", X, u, None, K))


def test_rotation_law_at_a_kink_leaves_f_and_K_out(tmp_path: Path) -> None:
    """corotated with the element inverted to F = diag(1, 1, -1) (its polar rotation is not unique, psi has a
    kink: Law.stress_undefined and tangent_undefined): neither f nor K is a derivative there, so neither is
    compared (each a note with the count) and, with nothing left, the check is bad input naming both; W
    (psi = min over SO(3), defined) still is. Slightly off the kink both are compared again."""
    X = REF_TET.copy()
    u = X @ (np.diag([1.0, 1.0, -1.0]) - I3).T
    ref = el.assemble_element("corotated", {"mu": MU, "lmbda": LMBDA}, X, u)
    with pytest.raises(ValueError, match="f not checked.*1 of 1 quadrature points.*K not checked"):
        el.check_element(_file(tmp_path, "kink", X, u, 3 * ref.f, 3 * ref.K, material="corotated",
                               W=ref.W))
    near = X @ (np.diag([1.0, 0.9, -1.0]) - I3).T
    ref = el.assemble_element("corotated", {"mu": MU, "lmbda": LMBDA}, X, near)
    report = el.check_element(_file(tmp_path, "near", X, near, ref.f, ref.K, material="corotated"))
    assert report.ok and [r.quantity for r in report.rows] == ["f", "K"], report.format()


def test_check_bad_input_names_the_key(tmp_path: Path) -> None:
    X, u = tet4_element()
    f, K = p1_numpy(neo_hookean, X, u)
    cases = {
        "'X'": {"cell": "tet4", "material": "neo_hookean", "u": u.tolist(), "f": f.tolist()},
        "K: shape (12, 11)": {"cell": "tet4", "X": X.tolist(), "u": u.tolist(), "K": K[:, :11].tolist(),
                              "material": "neo_hookean"},
        "X: shape (10, 3)": {"cell": "tet4", "X": np.zeros((10, 3)).tolist(), "u": u.tolist(), "f": f.tolist()},
        "unknown cell": {"cell": "tet8", "X": X.tolist(), "u": u.tolist()},
        "node_order": {"cell": "tet4", "node_order": "abaqus", "X": X.tolist(), "u": u.tolist(), "f": f.tolist()},
        "unknown law": {"cell": "tet4", "material": "hooke", "X": X.tolist(), "u": u.tolist(), "f": f.tolist()},
        "material": {"cell": "tet4", "X": X.tolist(), "u": u.tolist(), "f": f.tolist()},
        "neither": {"cell": "tet4", "material": "neo_hookean", "X": X.tolist(), "u": u.tolist()},
        "field 'S'": {"cell": "tet4", "material": "shape_target", "params": {"mu": 1.0}, "X": X.tolist(),
                      "u": u.tolist(), "f": f.tolist()},
    }
    for expected, content in cases.items():
        path = tmp_path / "bad.json"
        content.setdefault("params", {"mu": MU, "lmbda": LMBDA})
        path.write_text(json.dumps(content))
        with pytest.raises(ValueError, match=re.escape(expected)):
            el.check_element(path)
    path = tmp_path / "broken.json"
    path.write_text('{"cell": "tet4",')
    with pytest.raises(ValueError, match="invalid JSON"):
        el.check_element(path)


def test_fields_and_write_reference(tmp_path: Path) -> None:
    """shape_target with its field S per element; the emitted reference passes the check, in both formats."""
    X, u = tet4_element(5)
    S = np.array([[1.2, 0.1, 0.0], [0.1, 0.9, 0.05], [0.0, 0.05, 1.1]])
    source = {"cell": "tet4", "material": "shape_target", "params": {"mu": 1.5, "kappa": 2.0}, "fields": {"S": S},
              "X": X, "u": u}
    for fmt in ("json", "npz"):
        out = tmp_path / f"ref.{fmt}"
        ref = el.write_element_reference(source, out)
        assert np.linalg.norm(ref.f) > 0 and np.linalg.norm(ref.K - ref.K.T) < 1e-12 * np.linalg.norm(ref.K)
        report = el.check_element(out)
        assert report.ok and {r.quantity for r in report.rows} == {"f", "K", "W"}, report.format()


def _cli(argv: list[str]) -> int:
    parser = argparse.ArgumentParser()
    sub = parser.add_subparsers(dest="verify_command")
    el.add_parser(sub)
    return el.main(parser.parse_args(["element", *argv]))


def test_main_exit_codes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    X, u = tet4_element()
    f, K = p1_numpy(neo_hookean, X, u)
    right = _file(tmp_path, "right", X, u, f, K, material=None)
    rank0 = MPI.COMM_WORLD.rank == 0  # main prints on rank 0 only
    assert _cli([str(right)]) == 2
    assert ("error: material" in capsys.readouterr().err) == rank0
    assert _cli([str(right), "--material", "neo_hookean", "--param", f"mu={MU}", "--param", f"lmbda={LMBDA}"]) == 0
    assert _cli([str(right), "--material", "neo_hookean", "--param", f"mu={MU / 2}", "--param", f"lmbda={LMBDA}"]) == 1
    out = capsys.readouterr().out
    assert ("FAIL" in out and "node" in out) == rank0
    assert _cli([str(tmp_path / "none.json"), "--material", "stvk"]) == 2
    assert ("error:" in capsys.readouterr().err) == rank0
    emitted = tmp_path / "emitted.json"
    stvk_args = ["--material", "stvk", "--param", "mu=1", "--param", "lmbda=1"]
    assert _cli([str(right), *stvk_args, "--emit", str(emitted)]) == 0
    assert _cli([str(emitted)]) == 0


@serial_only
def test_cli_help_and_run(tmp_path: Path) -> None:
    X, u = tet4_element()
    f, K = p1_numpy(neo_hookean, X, u)
    path = _file(tmp_path, "mine", X, u, f, 1.001 * K, fmt="npz")
    code = ("import argparse, sys; from model.verify import element; p = argparse.ArgumentParser(prog='verify'); "
            "s = p.add_subparsers(dest='c'); element.add_parser(s); sys.exit(element.main(p.parse_args()))")
    run = [sys.executable, "-c", code, "element"]
    help_ = subprocess.run([*run, "--help"], capture_output=True, text=True, env=environment(), cwd=ROOT)
    assert help_.returncode == 0
    for word in ("tet4", "tet10", "hex8", "vtk", "gmsh", "dolfinx", "node-major", "params_json"):
        assert word in help_.stdout, word
    fail = subprocess.run([*run, str(path)], capture_output=True, text=True, env=environment(), cwd=ROOT)
    assert fail.returncode == 1, fail.stdout + fail.stderr
    assert "1.001 times" in fail.stdout
