"""Quadrature metadata for UFL measures that the automatic degree estimate does not give.

The vertex (nodal) rule on a reference simplex with n vertices and volume |T|:

    int_T f dX  ~  sum_{i=1..n} (|T| / n) f(X_i),   X_i the vertices

the lumped mass of P1: exact for a P1 x P0 product, and a contact or sliding energy integrated with it acts node
by node (the penalty at each slave node, not at interior points of a facet).

The points and weights are tuples of Python floats, not numpy arrays: UFL puts str() of every metadata value into
the form's signature (the JIT cache key), which is exact for a float (its repr) but rounds an array to 8 digits,
and warns ("Applying str() to a metadata value of type ndarray") for each form.
"""

from __future__ import annotations

__all__ = ["vertex_rule"]

#: the vertices of the reference simplices (basix / FIAT numbering) and their volumes
_VERTICES: dict[str, tuple[tuple[float, ...], ...]] = {
    "interval": ((0.0,), (1.0,)),
    "triangle": ((0.0, 0.0), (1.0, 0.0), (0.0, 1.0)),
    "tetrahedron": ((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
}
_VOLUME = {"interval": 1.0, "triangle": 0.5, "tetrahedron": 1.0 / 6.0}


def vertex_rule(cell: str) -> dict[str, object]:
    """The metadata of the vertex rule on the reference ``cell`` ("interval", "triangle", "tetrahedron"): points
    the vertices X_i, weights |T| / n (module docstring), for ``ufl.dx(metadata=...)`` or ``ufl.ds(...)`` (on a
    tetrahedron's facets: cell "triangle")."""
    if cell not in _VERTICES:
        raise ValueError(f"vertex_rule: cell must be one of {sorted(_VERTICES)}, got {cell!r}")
    points = _VERTICES[cell]
    weight = _VOLUME[cell] / len(points)
    return {"quadrature_rule": "custom", "quadrature_degree": 1, "quadrature_points": points,
            "quadrature_weights": tuple(weight for _ in points)}
