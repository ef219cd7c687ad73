"""A user's own gmsh geometry script (``.geo``) meshed with gmsh's Python API into :class:`MeshData`.

The script's physical groups name the regions (3D) and boundaries (2D), exactly as for a ``.msh`` file
(:func:`meshes.from_gmsh_model`). Its mesh size is the script's own business (``Mesh.MeshSizeMax`` and
the like, or sizes at points); a script that declares its numbers as parameters,

    DefineConstant[ size = {0.005, Name "Parameters/size"} ];

lets :func:`read_geo` set them, ``read_geo(path, {"size": 0.003})``: the values are defined before the
script runs, and ``DefineConstant`` keeps a value that is already defined (gmsh's ``-setnumber``).
"""

from __future__ import annotations

import json
import logging
import os
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping
from pathlib import Path

import gmsh
import numpy as np

from meshes._gmsh import gmsh_session
from meshes._validate import ParameterError
from meshes.data import MeshData, from_gmsh_model

__all__ = ["geo_parameters", "read_geo"]

logger = logging.getLogger(__name__)

#: size options a script typically sets, saved and restored around it (gmsh's defaults)
_SIZE_OPTIONS = {"Mesh.MeshSizeMax": 1e22, "Mesh.MeshSizeMin": 0.0, "Mesh.MeshSizeFactor": 1.0,
                 "Mesh.MeshSizeFromCurvature": 0, "Mesh.MeshSizeFromPoints": 1, "Mesh.MeshSizeExtendFromBoundary": 1}

_DEFINE = re.compile(r"DefineConstant\s*\[(.*?)\]\s*;", re.DOTALL)
_NAME = re.compile(r"(?:^|,)\s*([A-Za-z_][A-Za-z0-9_]*)\s*=")


def _strip_comments(text: str) -> str:
    return re.sub(r"//[^\n]*", "", re.sub(r"/\*.*?\*/", "", text, flags=re.DOTALL))


def geo_parameters(path: str | Path) -> list[str]:
    """The names a ``.geo`` script declares with ``DefineConstant[ name = {value, ...}, ... ];``, in order."""
    text = _strip_comments(Path(path).read_text(errors="replace"))
    names: list[str] = []
    for block in _DEFINE.findall(text):
        depth, flat = 0, []
        for ch in block:  # keep the top level of the list: name = {..}, name = value
            depth += ch == "{"
            flat.append(ch if depth == 0 else " ")
            depth -= ch == "}"
        names += [n for n in _NAME.findall("".join(flat)) if n not in names]
    return names


def read_geo(path: str | Path, parameters: Mapping[str, float] | None = None, isolated: bool = True) -> MeshData:
    """Run the gmsh script ``path`` (its own folder for the files it includes or merges), mesh it in 3D
    unless it meshed itself (``Mesh 3;``), and return the tetrahedra with its physical groups as named
    regions and boundaries (see :func:`meshes.from_gmsh_model`).

    ``parameters`` sets the script's ``DefineConstant`` parameters by name (ParameterError for a name
    it does not declare). A script gmsh cannot run raises ValueError with gmsh's message.

    ``isolated`` (default) runs gmsh in a fresh interpreter: gmsh 4.8's parser keeps the unread rest of
    a script with a syntax error and fails on every later script of the process, and a script's options
    stay set after it; neither then reaches this process. Otherwise gmsh runs here (initialised only if
    it is not already, and its model and the size options restored after).
    """
    path = Path(path).resolve()
    if not path.is_file():
        raise FileNotFoundError(f"read_geo: no such file: {path}")
    parameters = {name: float(value) for name, value in (parameters or {}).items()}
    declared = geo_parameters(path)
    for name in parameters:
        if name not in declared:
            raise ParameterError(f"read_geo: {path.name} declares no parameter {name!r} "
                                 f"(its DefineConstant parameters: {', '.join(declared) or 'none'})")
    start = time.perf_counter()
    mesh = _read_isolated(path, parameters) if isolated else _mesh_script(path, parameters)
    logger.info("meshed %s%s: %d points, %d tetrahedra in %.2f s", path.name,
                "".join(f", {k} = {v:g}" for k, v in parameters.items()), mesh.num_points, mesh.num_cells,
                time.perf_counter() - start)
    return mesh


def _mesh_script(path: Path, parameters: Mapping[str, float]) -> MeshData:
    """Run the script in this process's gmsh (see read_geo)."""
    with gmsh_session(_SIZE_OPTIONS, name="read_geo"), tempfile.TemporaryDirectory() as folder:
        script = path
        if parameters:
            script = Path(folder) / "parameters.geo"
            lines = [f"{name} = {value!r};" for name, value in parameters.items()]
            script.write_text("\n".join([*lines, f"Include \"{path}\";", ""]))
        gmsh.logger.start()
        try:
            gmsh.merge(str(script))
            if not gmsh.model.getEntities(3):
                raise ValueError(f"{path.name} defines no volume")
            if not any(len(gmsh.model.mesh.getElements(3, tag)[0]) for _, tag in gmsh.model.getEntities(3)):
                gmsh.model.mesh.generate(3)
            return from_gmsh_model(gmsh.model)
        except Exception as err:  # noqa: BLE001 - gmsh raises a bare Exception; report its own message
            errors = [m.removeprefix("Error: ") for m in gmsh.logger.get() if m.startswith("Error")]
            if isinstance(err, ValueError) and not errors:
                raise
            raise ValueError(f"gmsh: {errors[0] if errors else err}") from None
        finally:
            gmsh.logger.stop()


def _read_isolated(path: Path, parameters: Mapping[str, float]) -> MeshData:
    """_mesh_script in a fresh interpreter (``python -m meshes.geo``), the mesh passed back in an .npz."""
    root = str(Path(__file__).resolve().parents[1])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")]))}
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "mesh.npz"
        proc = subprocess.run([sys.executable, "-m", "meshes.geo", str(path), str(out), json.dumps(parameters)],
                              capture_output=True, text=True, env=env, cwd=folder)
        if proc.returncode != 0 or not out.is_file():
            lines = proc.stderr.strip().splitlines()
            raise ValueError(lines[-1].removeprefix("ValueError: ") if lines else f"gmsh exited with {proc.returncode}")
        with np.load(out) as saved:
            return MeshData(points=saved["points"], cells=saved["cells"], cell_tags=saved["cell_tags"],
                            facets=saved["facets"], facet_tags=saved["facet_tags"],
                            nodes=saved["nodes"] if "nodes" in saved.files else None,
                            **json.loads(str(saved["names"])))


def _main(argv: list[str]) -> int:
    """``python -m meshes.geo SCRIPT OUT.npz PARAMETERS_JSON``: mesh SCRIPT into OUT.npz (read_geo's child)."""
    path, out, parameters = Path(argv[0]), Path(argv[1]), json.loads(argv[2])
    try:
        mesh = _mesh_script(path, parameters)
    except ValueError as err:
        print(f"ValueError: {' '.join(str(err).split())}", file=sys.stderr)
        return 1
    names = json.dumps({"region_names": mesh.region_names, "boundary_names": mesh.boundary_names})
    curved = {} if mesh.nodes is None else {"nodes": mesh.nodes}  # 10-node tetrahedra keep their edge nodes
    np.savez(out, points=mesh.points, cells=mesh.cells, cell_tags=mesh.cell_tags, facets=mesh.facets,
             facet_tags=mesh.facet_tags, names=np.array(names), **curved)
    return 0


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1:]))
