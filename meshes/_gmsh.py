"""A small, well-behaved wrapper around the global gmsh API state.

gmsh is a process-wide singleton.  :func:`gmsh_session` initialises it only when
nobody else has, always works in a fresh model, and on exit either finalises gmsh
(if it initialised it) or removes its model and restores the options it changed
(if the session belonged to somebody else).
"""

from __future__ import annotations

import itertools
import logging
import math
from collections.abc import Iterator, Mapping
from contextlib import contextmanager

import gmsh

__all__ = ["DEFAULT_OPTIONS", "gmsh_is_initialized", "gmsh_session"]

logger = logging.getLogger(__name__)

#: Options applied in every session: quiet, single-threaded and deterministic meshing.
DEFAULT_OPTIONS: Mapping[str, float] = {
    "General.Terminal": 0,
    "General.Verbosity": 2,
    "General.NumThreads": 1,
    "Mesh.MaxNumThreads1D": 1,
    "Mesh.MaxNumThreads2D": 1,
    "Mesh.MaxNumThreads3D": 1,
    "Mesh.Algorithm": 6,  # Frontal-Delaunay (2D)
    "Mesh.Algorithm3D": 1,  # Delaunay (3D)
    "Mesh.RandomSeed": 1,
    "Mesh.ElementOrder": 1,
}

_model_counter = itertools.count()


def gmsh_is_initialized() -> bool:
    """Return whether the gmsh API is currently initialised.

    gmsh >= 4.9 has ``gmsh.isInitialized``; for older versions (Debian's 4.8) we
    rely on ``gmsh.model.list()``, which returns an empty list before
    initialisation, at least one model after it, and raises after finalisation.
    """
    checker = getattr(gmsh, "isInitialized", None)
    if checker is not None:
        return bool(checker())
    try:
        return len(gmsh.model.list()) > 0
    except Exception:  # noqa: BLE001 - gmsh raises a bare Exception after finalize()
        return False


def _set_options(options: Mapping[str, float]) -> None:
    """Set numeric gmsh options."""
    for name, value in options.items():
        gmsh.option.setNumber(name, float(value))


@contextmanager
def gmsh_session(options: Mapping[str, float] | None = None, name: str = "meshes") -> Iterator[str]:
    """Run the body in a fresh, quiet gmsh model and clean up afterwards.

    Parameters
    ----------
    options:
        Extra numeric gmsh options applied after :data:`DEFAULT_OPTIONS`.
    name:
        Prefix of the temporary model's name.

    Yields
    ------
    str
        The name of the model that is current inside the ``with`` block.
    """
    merged = {**DEFAULT_OPTIONS, **(options or {})}
    owner = not gmsh_is_initialized()
    saved: dict[str, float] = {}
    previous_model = ""
    if owner:
        gmsh.initialize(readConfigFiles=False)
        gmsh.option.setNumber("General.Terminal", 0)
    else:
        previous_model = gmsh.model.getCurrent()
        saved = {key: gmsh.option.getNumber(key) for key in merged}
    model_name = f"{name}-{next(_model_counter)}"
    try:
        gmsh.model.add(model_name)
        _set_options(merged)
        logger.debug("gmsh session %s started (owner=%s)", model_name, owner)
        yield model_name
    finally:
        if owner:
            gmsh.finalize()
        else:
            if model_name in gmsh.model.list():
                gmsh.model.setCurrent(model_name)
                gmsh.model.remove()
            _set_options(saved)
            if previous_model in gmsh.model.list():
                gmsh.model.setCurrent(previous_model)
        logger.debug("gmsh session %s closed", model_name)


#: Elements per 2 pi radians of curvature on curved surfaces (gmsh Mesh.MeshSizeFromCurvature):
#: below about 16 a thin tendon loses several percent of its volume.
CURVATURE_ELEMENTS = 16


def curvature_elements(size: float, smallest_radius: float | None = None) -> int:
    """Elements per 2 pi radians of curvature for maximum element size ``size``.

    N = max(CURVATURE_ELEMENTS, ceil(CURVATURE_ELEMENTS r_min / size)): with the smallest radius of curvature
    r_min given, surfaces of radius r get elements of 2 pi r / N, which for size < r_min is
    (2 pi / CURVATURE_ELEMENTS) (r / r_min) size, proportional to ``size``: halving ``size`` halves every
    element (a mesh-convergence or scaling study refines the thin tendons too, not only the interior).
    Without ``smallest_radius``: CURVATURE_ELEMENTS.
    """
    if smallest_radius is None:
        return CURVATURE_ELEMENTS
    return max(CURVATURE_ELEMENTS, math.ceil(CURVATURE_ELEMENTS * smallest_radius / size - 1e-9))


def curved_size_options(size: float, smallest_radius: float | None = None) -> dict[str, float]:
    """gmsh options for a maximum element size ``size``, refined on curved surfaces
    (:func:`curvature_elements` elements per 2 pi radians)."""
    return {
        "Mesh.MeshSizeMax": size,
        "Mesh.MeshSizeMin": 0.0,
        "Mesh.MeshSizeFromCurvature": curvature_elements(size, smallest_radius),
    }
