"""The one place that knows dolfinx versions: Debian 12's 0.5.2 and Debian 13's 0.9.

Everything else in the project calls these functions instead of version-specific names. Each
function does one thing and returns dolfinx's own objects (no wrapper classes).

What differs between the two releases, and where it is handled here:

- elements: ``ufl.FiniteElement``/``VectorElement``/``TensorElement``/``MixedElement`` (0.5) or
  ``basix.ufl.element(..., shape=)``, ``mixed_element``, ``quadrature_element`` (0.9);
- function spaces: ``fem.FunctionSpace`` and its Vector/Tensor variants (0.5) or ``fem.functionspace`` (0.9);
- a mesh from arrays: ``create_mesh`` takes ``ufl.Mesh`` of a ufl (0.5) or basix.ufl (0.9) element;
- tags from entities: ``cpp.io.distribute_entity_data(mesh._mesh, ...)`` with ``AdjacencyList_int32`` (0.5)
  or ``io.distribute_entity_data(mesh, ...)`` with ``graph.adjacencylist`` (0.9);
- dofmaps: ``AdjacencyList`` (``.array``, 0.5) or 2D numpy arrays (0.9);
- the PETSc vector of a Function: ``u.vector`` (0.5) or ``u.x.petsc_vec`` (0.9);
- ``Expression.eval(cells)`` (0.5) or ``eval(mesh, cells)`` (0.9);
- ``apply_lifting``/``set_bc`` scale the lifting with ``scale=`` (0.5) or ``alpha=`` (0.9);
- gmsh's node order to dolfinx's: ``cpp.io.perm_gmsh`` (0.5) or ``io.gmshio.cell_perm_array`` (0.9);
- point location: ``BoundingBoxTree``/``compute_collisions`` (0.5) or ``bb_tree``/``compute_collisions_points``;
- the geometry nodes of entities (facets, cells): ``cpp.mesh.entities_to_geometry(mesh._mesh, ...)`` (0.5) or
  ``mesh.entities_to_geometry`` (0.9);
- class names: ``FormMetaClass``, ``DirichletBCMetaClass``, ``MeshTagsMetaClass`` (0.5) or ``Form``,
  ``DirichletBC``, ``MeshTags`` (0.9).
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import platform
import subprocess
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import dolfinx
import dolfinx.jit
import numpy as np
import ufl
from dolfinx import fem, geometry
from dolfinx import mesh as dmesh
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

#: dolfinx's version as a tuple of integers, e.g. (0, 9, 0)
DOLFINX_VERSION: tuple[int, ...] = tuple(int(part) for part in dolfinx.__version__.split(".")[:3] if part.isdigit())
#: the API of dolfinx 0.5/0.6 (ufl elements, AdjacencyList dofmaps, Function.vector)
LEGACY = DOLFINX_VERSION < (0, 7)


#: Seconds a rank waits for another rank's JIT compilation of the same form before it gives up. dolfinx's
#: default, 10 s, is shorter than the C compiler takes for the fibre laws' large expression kernels on a
#: loaded 2-core machine (a TimeoutError on the waiting rank); a user's dolfinx_jit_options.json still wins.
JIT_TIMEOUT = 600
_JIT_DEFAULTS = getattr(dolfinx.jit, "DOLFINX_DEFAULT_JIT_OPTIONS", None) or \
    dolfinx.jit.DOLFINX_DEFAULT_JIT_PARAMETERS  # 0.9 or 0.5
_JIT_DEFAULTS["timeout"] = (max(JIT_TIMEOUT, _JIT_DEFAULTS["timeout"][0]), _JIT_DEFAULTS["timeout"][1])
#: SOFTTISSUE_JIT_CFLAGS="-O0 -g0": the C compiler's flags for the generated kernels in place of dolfinx's "-O2 -g0"
#: (a user's dolfinx_jit_options.json still wins). `make test` sets it: the suite compiles ~1,800 small-mesh
#: kernels from a cold cache, and gcc -O0 compiles a fibre law's Jacobian about 3.5x faster while its assembly is
#: 1.3-2.6x slower (docs/releases.md); runs, benchmarks and notebooks outside the tests keep -O2. The flags are
#: part of the kernels' cache key, so the two never share compiled modules.
if os.environ.get("SOFTTISSUE_JIT_CFLAGS", "").split():
    _JIT_DEFAULTS["cffi_extra_compile_args"] = (os.environ["SOFTTISSUE_JIT_CFLAGS"].split(),
                                                _JIT_DEFAULTS["cffi_extra_compile_args"][1])

if LEGACY:
    Form = fem.FormMetaClass
    DirichletBC = fem.DirichletBCMetaClass
    MeshTags = dmesh.MeshTagsMetaClass
else:
    import basix.ufl

    Form = fem.Form
    DirichletBC = fem.DirichletBC
    MeshTags = dmesh.MeshTags

Shape = tuple[int, ...]


# --- elements and function spaces -----------------------------------------------------------------

def element(family: str, cell: str, degree: int, shape: Shape = ()) -> Any:
    """A finite element: ``family`` ("Lagrange", "DG", ...) of ``degree`` on ``cell`` ("tetrahedron"),
    scalar (shape ()), vector ((3,)) or tensor ((3, 3))."""
    shape = tuple(shape)
    if not LEGACY:
        return basix.ufl.element(family, cell, degree, shape=shape or None)
    ucell = getattr(ufl, cell) if isinstance(cell, str) else cell  # a ufl.Cell: a manifold's (gdim 3 triangle)
    if shape == ():
        return ufl.FiniteElement(family, ucell, degree)
    if len(shape) == 1:
        return ufl.VectorElement(family, ucell, degree, dim=shape[0])
    return ufl.TensorElement(family, ucell, degree, shape=shape)


def mixed_element(elements: Sequence[Any]) -> Any:
    """The mixed element of several elements (e.g. Taylor-Hood: vector P2 and scalar P1)."""
    if LEGACY:
        return ufl.MixedElement(list(elements))
    return basix.ufl.mixed_element(list(elements))


def quadrature_element(cell: str, degree: int, shape: Shape = ()) -> Any:
    """Values at the points of the default quadrature rule of ``degree`` (basix's, which the forms use)."""
    shape = tuple(shape)
    if not LEGACY:
        return basix.ufl.quadrature_element(cell, value_shape=shape, scheme="default", degree=degree)
    ucell = getattr(ufl, cell)
    if shape == ():
        return ufl.FiniteElement("Quadrature", ucell, degree, quad_scheme="default")
    if len(shape) == 1:
        return ufl.VectorElement("Quadrature", ucell, degree, dim=shape[0], quad_scheme="default")
    return ufl.TensorElement("Quadrature", ucell, degree, shape=shape, quad_scheme="default")


def function_space(msh: dmesh.Mesh, family: Any, degree: int | None = None, shape: Shape = ()) -> fem.FunctionSpace:
    """A function space on ``msh``: ``function_space(msh, "Lagrange", 1, (3,))``, or of an element made
    here (``function_space(msh, mixed_element([...]))``)."""
    if degree is not None:
        family = element(family, msh.ufl_cell() if LEGACY else cell_name(msh), degree, shape)
    if LEGACY:
        return fem.FunctionSpace(msh, family)
    return fem.functionspace(msh, family)


def quadrature_space(msh: dmesh.Mesh, degree: int, shape: Shape = ()) -> fem.FunctionSpace:
    """Values at the quadrature points of the default rule of ``degree`` (quadrature-point state)."""
    return function_space(msh, quadrature_element(cell_name(msh), degree, shape))


def quadrature_points(msh: dmesh.Mesh, degree: int) -> np.ndarray:
    """Reference points of basix's default rule of ``degree`` on the mesh's cell (the rule the forms and
    quadrature_space use)."""
    import basix

    points, _ = basix.make_quadrature(getattr(basix.CellType, cell_name(msh)), degree)
    return points


def cell_name(msh: dmesh.Mesh) -> str:
    """The cell's name, e.g. "tetrahedron"."""
    return msh.ufl_cell().cellname() if LEGACY else msh.topology.cell_name()


# --- meshes and tags ----------------------------------------------------------------------------------

def create_mesh(comm: Any, cells: np.ndarray, points: np.ndarray, degree: int = 1,
                cell: str = "tetrahedron", gdim: int = 3, facet_ghosts: bool = False) -> dmesh.Mesh:
    """A tetrahedral mesh with Lagrange geometry of ``degree`` (cells in dolfinx's node order);
    every rank but the one holding the data passes empty arrays. ``cell="triangle"``: a surface
    (manifold) mesh of triangles in 3D (gdim 3, tdim 2); with ``gdim=2`` a plane triangle mesh (the
    first two columns of ``points``). ``facet_ghosts``: the cells across the rank border are ghosts
    (GhostMode.shared_facet: interior-facet integrals, dS, need them there); dolfinx 0.5 ghosts them
    always (its default), 0.9 only when asked (its default is GhostMode.none)."""
    points = np.asarray(points, dtype=np.float64)[:, :gdim]
    if LEGACY:
        # The equispaced variant from the start: FFCx 0.5 sets it on the mesh's coordinate element (in place) when it
        # compiles the first form of the mesh that is not in the JIT cache, which changes the repr, so the hash,
        # of every Argument made after it on the mesh's spaces: a form combining test functions made before and
        # after such a compile failed with "Found different Arguments with same number and part" (cold cache only)
        sub = ufl.FiniteElement("Lagrange", ufl.Cell(cell, geometric_dimension=gdim), degree, variant="equispaced")
        domain = ufl.Mesh(ufl.VectorElement(sub, dim=gdim))
    else:
        domain = ufl.Mesh(basix.ufl.element("Lagrange", cell, degree, shape=(gdim,)))
    cells, points = np.asarray(cells, dtype=np.int64), np.ascontiguousarray(points)
    if facet_ghosts and not LEGACY and comm.size > 1:
        partitioner = dmesh.create_cell_partitioner(dmesh.GhostMode.shared_facet)
        return dmesh.create_mesh(comm, cells, points, domain, partitioner=partitioner)
    return dmesh.create_mesh(comm, cells, points, domain)


def gmsh_node_order(cell: str, num_nodes: int) -> np.ndarray:
    """p such that a cell's nodes in dolfinx's order are its gmsh nodes [p]; ``cell`` "tetrahedron" or
    "triangle" (e.g. tetrahedron, 10: gmsh's edges 01 12 20 30 32 31 become dolfinx's 23 13 12 03 02 01)."""
    if LEGACY:
        from dolfinx import cpp

        perm = cpp.io.perm_gmsh(getattr(cpp.mesh.CellType, cell), num_nodes)
    else:
        from dolfinx.io import gmshio

        perm = gmshio.cell_perm_array(getattr(dmesh.CellType, cell), num_nodes)
    return np.asarray(perm, dtype=np.int64)


def geometry_degree(msh: dmesh.Mesh) -> int:
    """The degree of the mesh's coordinate element (1 straight-sided, 2 curved tet10)."""
    return int(msh.geometry.cmap.degree)


def meshtags_from_input(msh: dmesh.Mesh, dim: int, entities: np.ndarray, values: np.ndarray) -> MeshTags:
    """Mesh tags of entities given by their input node numbers on any rank (distributed here): all the
    entity's geometry nodes in dolfinx's order (4 or 10 for a tetrahedron, 3 or 6 for a triangle)."""
    entities = np.asarray(entities, dtype=np.int64)
    values = np.asarray(values, dtype=np.int32)
    msh.topology.create_connectivity(dim, 0)
    if LEGACY:
        from dolfinx import cpp

        local, local_values = cpp.io.distribute_entity_data(msh._mesh, dim, entities, values)
        adjacency = cpp.graph.AdjacencyList_int32(local)
    else:
        from dolfinx import graph, io

        local, local_values = io.distribute_entity_data(msh, dim, entities, values)
        adjacency = graph.adjacencylist(np.asarray(local, dtype=np.int32))
    return dmesh.meshtags_from_entities(msh, dim, adjacency, np.asarray(local_values, dtype=np.int32))


def cell_dofs(dofmap: Any) -> np.ndarray:
    """A dofmap (a space's, or the geometry's) as a (num_cells, dofs_per_cell) array."""
    table = dofmap.list if hasattr(dofmap, "list") else dofmap
    if isinstance(table, np.ndarray):
        return table
    return table.array.reshape(table.num_nodes, -1)


def geometry_dofs(msh: dmesh.Mesh) -> np.ndarray:
    """The geometry dofmap: (num_cells, nodes_per_cell) indices into ``msh.geometry.x``."""
    return cell_dofs(msh.geometry.dofmap)


def entity_geometry(msh: dmesh.Mesh, dim: int, entities: np.ndarray) -> np.ndarray:
    """Indices into ``msh.geometry.x`` of the nodes of each entity of dimension ``dim``: (len(entities), nodes)."""
    entities = np.asarray(entities, dtype=np.int32)
    if len(entities) == 0:  # dolfinx 0.9 divides by zero on an empty list (SIGFPE)
        d = geometry_degree(msh)
        nodes = {0: 1, 1: d + 1, 2: (d + 1) * (d + 2) // 2, 3: (d + 1) * (d + 2) * (d + 3) // 6}[dim]
        return np.empty((0, nodes), dtype=np.int32)
    if LEGACY:
        from dolfinx.cpp.mesh import entities_to_geometry

        return entities_to_geometry(getattr(msh, "_mesh", msh), dim, entities, False)
    return dmesh.entities_to_geometry(msh, dim, entities, False)


def colliding_cells(msh: dmesh.Mesh, points: np.ndarray) -> Any:
    """The cells (local indices, an AdjacencyList per point) that contain each point."""
    points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    tdim = msh.topology.dim
    if LEGACY:
        tree = geometry.BoundingBoxTree(msh, tdim)
        candidates = geometry.compute_collisions(tree, points)
    else:
        tree = geometry.bb_tree(msh, tdim)
        candidates = geometry.compute_collisions_points(tree, points)
    return geometry.compute_colliding_cells(msh, candidates, points)


def exterior_facet_vertices(msh: dmesh.Mesh) -> np.ndarray:
    """The vertex coordinates of this rank's exterior facets (those of one cell of the whole mesh, not
    the facets between ranks): (num_facets, 3, 3) for triangles, owned and ghost facets alike."""
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, tdim)
    facets = np.asarray(dmesh.exterior_facet_indices(msh.topology), dtype=np.int32)
    if LEGACY:
        from dolfinx import cpp

        nodes = cpp.mesh.entities_to_geometry(msh._mesh, tdim - 1, facets, False)
    else:
        nodes = dmesh.entities_to_geometry(msh, tdim - 1, facets)
    nodes = np.asarray(nodes).reshape(len(facets), -1)[:, :tdim]  # the vertices (first nodes of each facet)
    return msh.geometry.x[nodes][:, :, :3].copy()


def jit_cache_dir() -> Path:
    """The JIT cache dolfinx compiles into (its defaults, or a user's dolfinx_jit_options.json)."""
    options = dolfinx.jit.get_parameters() if LEGACY else dolfinx.jit.get_options()
    return Path(options["cache_dir"]).expanduser()


@contextlib.contextmanager
def self_jit_lock(comm: Any) -> Iterator[None]:
    """Compile forms of a mesh on ``comm`` = MPI.COMM_SELF one process at a time when COMM_WORLD has several.

    dolfinx compiles a form of a parallel mesh on rank 0 first and raises on every rank together when that fails;
    a COMM_SELF mesh (the verify tool's cells) has no such guard: every rank compiles the same module into the
    shared cache, one creates the C file and the others wait for its ``.c.cached`` marker, which never comes
    when that compile fails (FFCx renames the file ``.c.failed``), until the JIT timeout (``JIT_TIMEOUT``, 600 s).
    Under this lock (an exclusive ``fcntl.flock`` on ``model-self-jit.lock`` in the cache) the next process finds
    the module cached, or no C file and fails the same way at once. A no-op on one process or a parallel mesh.
    """
    if comm.size > 1 or MPI.COMM_WORLD.size == 1:
        yield
        return
    cache = jit_cache_dir()
    cache.mkdir(parents=True, exist_ok=True)
    with open(cache / "model-self-jit.lock", "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def compile_form(form: Any, cache_dir: str | None = None) -> Any:
    """fem.form(form), compiled into the JIT cache ``cache_dir`` (None: dolfinx's usual one).

    The keyword is ``jit_params`` in dolfinx 0.5 and ``jit_options`` in 0.9.
    """
    if cache_dir is None:
        return fem.form(form)
    if LEGACY:
        return fem.form(form, jit_params={"cache_dir": cache_dir})
    return fem.form(form, jit_options={"cache_dir": cache_dir})


# --- evaluation, PETSc --------------------------------------------------------------------------------

def evaluate(expression: fem.Expression, msh: dmesh.Mesh, cells: np.ndarray) -> np.ndarray:
    """An Expression's values on local cells: (len(cells), points * value size)."""
    cells = np.asarray(cells, dtype=np.int32)
    if LEGACY:
        return expression.eval(cells)
    return expression.eval(msh, cells)


def petsc_vector(function: fem.Function) -> PETSc.Vec:
    """The PETSc vector that shares a Function's memory (owned and ghost entries)."""
    return function.vector if LEGACY else function.x.petsc_vec


def apply_lifting(b: PETSc.Vec, forms: list[Any], bcs: list[list[Any]], x0: list[PETSc.Vec] | None = None,
                  alpha: float = 1.0) -> None:
    """b -= alpha A (g - x0) at the Dirichlet dofs of each (form, bcs) (dolfinx's apply_lifting)."""
    key = "scale" if LEGACY else "alpha"
    fem_petsc.apply_lifting(b, forms, bcs=bcs, x0=x0 or [], **{key: alpha})


def set_bc(b: PETSc.Vec, bcs: list[Any], x0: PETSc.Vec | None = None, alpha: float = 1.0) -> None:
    """b = alpha (g - x0) at the Dirichlet dofs (dolfinx's set_bc)."""
    key = "scale" if LEGACY else "alpha"
    fem_petsc.set_bc(b, bcs, x0, **{key: alpha})


# --- provenance ---------------------------------------------------------------------------------------

def versions() -> dict[str, str | bool]:
    """The versions a result was computed with: dolfinx, PETSc, UFL, basix, numpy, Python, the OS
    release, and the project's git revision when the checkout has one: ``git_revision`` (the commit, with
    "-dirty" when the work tree has changes), ``git_commit`` and ``git_dirty`` (a boolean)."""
    import basix

    petsc = ".".join(str(v) for v in PETSc.Sys.getVersion())
    out = {"dolfinx": dolfinx.__version__, "petsc": petsc, "ufl": ufl.__version__, "basix": basix.__version__,
           "numpy": np.__version__, "python": platform.python_version(), "os": _os_release()}
    revision = git_revision()
    if revision:
        out["git_revision"] = revision
        out["git_commit"], out["git_dirty"] = revision.removesuffix("-dirty"), revision.endswith("-dirty")
    return out


def host() -> dict[str, int | None]:
    """The host's cores: ``cpu_count`` (os.cpu_count()) and, where the OS says (Linux), ``cpu_affinity``, the
    cores this process may run on (os.sched_getaffinity)."""
    affinity = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None
    return {"cpu_count": os.cpu_count(), "cpu_affinity": affinity}


def _os_release() -> str:
    try:
        for line in Path("/etc/os-release").read_text().splitlines():
            if line.startswith("PRETTY_NAME="):
                return line.split("=", 1)[1].strip('"')
    except OSError:
        pass
    return platform.platform()


def git_revision() -> str | None:
    """The project's git commit (with "-dirty" when the work tree has changes), or None."""
    root = Path(__file__).resolve().parents[1]
    if not (root / ".git").exists():
        return None
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True,
                              timeout=10, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return head + ("-dirty" if dirty else "")
