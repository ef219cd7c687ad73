"""Two boxes stacked along z as one mesh of two separate bodies (contact between deformable bodies).

The lower box is [0, Lx] x [0, Ly] x [0, Lz], the upper one the same box moved up by Lz + gap; they share no
node (meshes.combine): the upper block's face zmin rests on (or, gap > 0, hovers above) the lower block's zmax.
"""

from __future__ import annotations

from collections.abc import Sequence

from meshes._validate import ParameterError, positive_floats, positive_ints
from meshes.box import BOX_FACES, box
from meshes.combine import combine, moved
from meshes.data import MeshData

__all__ = ["BLOCK_BODIES", "stacked_blocks"]

#: the bodies of :func:`stacked_blocks`, bottom to top
BLOCK_BODIES = ("lower", "upper")


def stacked_blocks(size: Sequence[float] = (1.0, 1.0, 1.0), cells: Sequence[int] = (2, 2, 2),
                   gap: float = 0.0) -> MeshData:
    """Two boxes of edge lengths ``size`` and ``cells`` hexahedra (6 tetrahedra each), one on the other.

    Returns
    -------
    MeshData
        Volumes ``lower`` and ``upper``; boundaries ``<body>_<face>`` for every face of each box
        (``lower_zmax``, ``upper_zmin``, ... as in meshes.box: xmin xmax ymin ymax zmin zmax) and
        ``<body>_surface`` (its whole boundary).
    """
    lengths = positive_floats("stacked_blocks", "size", size, 3)
    counts = positive_ints("stacked_blocks", "cells", cells, 3)
    if isinstance(gap, bool) or not isinstance(gap, (int, float)) or not 0.0 <= gap < float("inf"):
        raise ParameterError(f"stacked_blocks: gap must be a finite number >= 0, got {gap!r}")
    block = box(lengths, counts)
    assert tuple(block.boundary_names) == BOX_FACES
    return combine({"lower": block, "upper": moved(block, (0.0, 0.0, lengths[2] + float(gap)))})
