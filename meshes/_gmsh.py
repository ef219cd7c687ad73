"""A small, well-behaved wrapper around the global gmsh API state.

gmsh is a process-wide singleton.  :func:`gmsh_session` initialises it only when
nobody else has, always works in a fresh model, and on exit either finalises gmsh
(if it initialised it) or removes its model and restores the options it changed
(if the session belonged to somebody else).

gmsh takes SIGINT over: importing gmsh 4.8 sets Python's SIGINT handler to SIG_DFL, and ``gmsh.finalize()``
puts back the one of import time; gmsh 4.13's ``initialize`` sets SIG_DFL and ``finalize`` puts back the one it
replaced. Either way a program's own handler (a run's clean stop on Ctrl-C) was gone, or an ignored SIGINT came
back. So gmsh is imported here keeping Python's SIGINT and SIGTERM handlers, and a session keeps them across its
``initialize`` and ``finalize``: Ctrl-C during gmsh's own work takes effect, through the program's handler, when
the gmsh call returns. (meshes/__init__.py imports this module first, before any module that imports gmsh.)
"""

from __future__ import annotations

import itertools
import logging
import math
import signal
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from typing import Any

import numpy as np

from meshes.topology import SLIVER_RADIUS_RATIO, radius_ratio


@contextmanager
def keep_signal_handlers() -> Iterator[None]:
    """Python's SIGINT and SIGTERM handlers after the body as they were before it (module docstring). Outside the
    main thread, and for a handler Python did not install, nothing is put back."""
    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, handler in saved.items():
            if handler is not None and signal.getsignal(s) != handler:
                try:
                    signal.signal(s, handler)
                except ValueError:  # not the main thread
                    pass


with keep_signal_handlers():  # importing gmsh 4.8 sets SIGINT to SIG_DFL
    import gmsh

__all__ = ["DEFAULT_OPTIONS", "MESH_ATTEMPTS", "generate_tetrahedra", "gmsh_is_initialized", "gmsh_session",
           "keep_signal_handlers"]

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


#: gmsh.initialize / gmsh.finalize as this process called them last (gmsh 4.8 only: see gmsh_is_initialized)
_initialized = False


def _track(initialize: Callable[..., None], finalize: Callable[..., None]
           ) -> tuple[Callable[..., None], Callable[..., None]]:
    """gmsh's initialize and finalize, each also recording the state in ``_initialized``."""

    def tracked_initialize(*args: Any, **kwargs: Any) -> None:
        global _initialized
        initialize(*args, **kwargs)
        _initialized = True

    def tracked_finalize(*args: Any, **kwargs: Any) -> None:
        global _initialized
        finalize(*args, **kwargs)
        _initialized = False

    tracked_initialize.__doc__, tracked_finalize.__doc__ = initialize.__doc__, finalize.__doc__
    return tracked_initialize, tracked_finalize


if not hasattr(gmsh, "isInitialized"):  # gmsh 4.8 (Debian 12): gmsh.initialize / finalize report to this module
    gmsh.initialize, gmsh.finalize = _track(gmsh.initialize, gmsh.finalize)


def gmsh_is_initialized() -> bool:
    """Return whether the gmsh API is currently initialised.

    gmsh >= 4.9 has ``gmsh.isInitialized``. Debian 12's gmsh 4.8 has not, and no API call can stand in for it:
    after ``gmsh.finalize()`` every call reads gmsh's freed context, and ``gmsh.model.list()`` there (the test
    this function used before) raised its "not initialized" error through ``Msg::Error``, which at times found
    ``General.AbortOnError = 2`` in the freed memory and called ``exit(1)``: the process ended silently with
    status 1 (seen as 2-rank test runs that stopped without a word, about 1 in 8 for two membrane test files).
    So on 4.8 this module wraps ``gmsh.initialize`` and ``gmsh.finalize`` (whoever calls them after it is
    imported) and answers from that record.
    """
    checker = getattr(gmsh, "isInitialized", None)
    if checker is not None:
        return bool(checker())
    return _initialized


def _set_options(options: Mapping[str, float]) -> None:
    """Set numeric gmsh options."""
    for name, value in options.items():
        gmsh.option.setNumber(name, float(value))


@contextmanager
def gmsh_session(options: Mapping[str, float] | None = None, name: str = "meshes") -> Iterator[str]:
    """Run the body in a fresh, quiet gmsh model and clean up afterwards; Python's SIGINT and SIGTERM handlers stay
    as they were before the session, inside it and after it (module docstring).

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
        with keep_signal_handlers():  # gmsh 4.13 sets SIGINT to SIG_DFL
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
            with keep_signal_handlers():  # gmsh puts back the SIGINT handler of its import or initialize
                gmsh.finalize()
        else:
            if model_name in gmsh.model.list():
                gmsh.model.setCurrent(model_name)
                gmsh.model.remove()
            _set_options(saved)
            if previous_model in gmsh.model.list():
                gmsh.model.setCurrent(previous_model)
        logger.debug("gmsh session %s closed", model_name)


#: How many seeds :func:`generate_tetrahedra` tries before it keeps the best mesh it made.
MESH_ATTEMPTS = 4


def _min_radius_ratio() -> float:
    """The smallest q = 3 r_in / r_circ over the current model's linear tetrahedra (1.0 without any)."""
    tags, coords, _ = gmsh.model.mesh.getNodes()
    if len(tags) == 0:
        return 1.0
    where = np.zeros(int(tags.max()) + 1, dtype=np.int64)
    where[tags.astype(np.int64)] = np.arange(len(tags))
    points = coords.reshape(-1, 3)
    worst = 1.0
    for kind, _, nodes in zip(*gmsh.model.mesh.getElements(3), strict=True):
        if kind == 4:  # 4-node tetrahedron
            cells = where[nodes.astype(np.int64).reshape(-1, 4)]
            worst = min(worst, float(radius_ratio(points[cells]).min()))
    return worst


def generate_tetrahedra(name: str, attempts: int = MESH_ATTEMPTS) -> float:
    """Mesh the current model in 3D; mesh it again with the next ``Mesh.RandomSeed`` while a sliver remains.

    Delaunay meshing of a curved body now and then leaves a flat tetrahedron whose four vertices all lie on
    the boundary (q = 3 r_in / r_circ ~ 0.007 against >= 0.05 elsewhere), which gmsh's optimiser cannot move;
    whether it appears depends on the last bits of the floating-point arithmetic, so on the machine. Any
    other seed removes it. Below :data:`SLIVER_RADIUS_RATIO` the mesh is made again with seeds 2, 3, ...
    (``attempts`` in all) and the best one kept; a mesh without a sliver is the first attempt's, unchanged.
    Returns the smallest radius ratio of the mesh kept.
    """
    seed = int(gmsh.option.getNumber("Mesh.RandomSeed"))
    gmsh.model.mesh.generate(3)
    quality = _min_radius_ratio()
    best = (quality, seed)
    for attempt in range(1, attempts):
        if quality >= SLIVER_RADIUS_RATIO:
            break
        logger.info("%s: a sliver (radius ratio %.3g) with Mesh.RandomSeed %d: meshing again with seed %d",
                    name, quality, seed + attempt - 1, seed + attempt)
        gmsh.option.setNumber("Mesh.RandomSeed", seed + attempt)
        gmsh.model.mesh.clear()
        gmsh.model.mesh.generate(3)
        quality = _min_radius_ratio()
        best = max(best, (quality, seed + attempt))
    if quality < best[0]:  # the last attempt was worse than an earlier one: make that one again
        gmsh.option.setNumber("Mesh.RandomSeed", best[1])
        gmsh.model.mesh.clear()
        gmsh.model.mesh.generate(3)
        quality = _min_radius_ratio()
    gmsh.option.setNumber("Mesh.RandomSeed", seed)
    if quality < SLIVER_RADIUS_RATIO:
        logger.warning("%s: %d seeds all leave a sliver; the best has radius ratio %.3g", name, attempts, quality)
    return quality


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
