"""Pictures for the notebooks: several result meshes side by side in one off-screen pyvista scene.

Not a notebook (the leading underscore keeps tests/test_notebooks.py from running it). The notebooks
call :func:`render`, which writes the picture's description as JSON and renders it in a fresh
interpreter (``python notebooks/_pictures.py SPEC.json``): pyvista/VTK must never be imported in a
process that imported dolfinx (see model/render.py), so this file imports neither at module level.

A spec is a dict::

    {"png": "out.png", "window": [1600, 700], "view": "xz", "zoom": 1.0, "elevation": 0, "azimuth": 0, "parallel": true,
     "scalars": "name", "clim": [lo, hi], "cmap": "viridis", "bar": "title of the colour bar",
     "panels": [{"vtu": "file.vtu", "offset": [dx, dy, dz], "label": "t = 0.5", "deformed": true,
                 "cells": [optional list of cell indices to show], "reference": false}]}

Every panel shows the mesh of its VTU (tetrahedra, or else triangles; deformed by the point data ``u``
unless ``deformed`` is false) moved by ``offset``, coloured by the cell data ``scalars`` (its first
component) or in one ``color``, with ``opacity``; ``arrows``: the name of a cell vector field drawn as
arrows of length ``arrow_scale`` at the centroids of the shown cells (or of ``arrow_cells``); ``reference`` adds the
undeformed outline as a faint wireframe. A panel may override ``scalars``, ``cmap``, ``clim``,
``bar`` and ``bar_position`` ([x, y, width] as fractions of the window); each distinct scalar
field gets one colour bar. ``texts`` is a list of [text, x, y] (fractions of the window).
All panels share one camera (parallel projection unless ``parallel`` is false), so sizes compare.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any


def deformation_gradients(points: Any, cells: Any, u: Any) -> Any:
    """F = Ds Dm^-1 of every linear tetrahedron (n, 3, 3) from reference points, cells and displacements."""
    import numpy as np

    X = np.asarray(points, dtype=float)[cells]
    x = X + np.asarray(u, dtype=float)[cells]
    Dm = np.swapaxes(X[:, 1:] - X[:, :1], 1, 2)
    Ds = np.swapaxes(x[:, 1:] - x[:, :1], 1, 2)
    return Ds @ np.linalg.inv(Dm)


def cell_fibre_state(mesh: Any) -> dict[str, Any]:
    """Per tetrahedron of a result VTU (meshio.Mesh with point data u and cell data fibre_direction):
    reference ``volume`` and ``centroid``, ``F``, ``J``, ``Fa`` = F a0 and the isochoric fibre stretch
    ``fibre_stretch`` = J^(-1/3) |F a0|."""
    import numpy as np

    tets = mesh.cells_dict["tetra"]
    X = mesh.points[tets]
    F = deformation_gradients(mesh.points, tets, mesh.point_data["u"])
    J = np.linalg.det(F)
    Fa = np.einsum("nij,nj->ni", F, mesh.cell_data["fibre_direction"][0])
    return {"volume": np.abs(np.linalg.det(X[:, 1:] - X[:, :1])) / 6.0, "centroid": X.mean(axis=1), "F": F, "J": J,
            "Fa": Fa, "fibre_stretch": J ** (-1.0 / 3.0) * np.linalg.norm(Fa, axis=1)}


def surface_cut(points, u, tets, axis, value):
    """Where the plane x[axis] = value cuts the boundary triangles of the tetrahedra: reference points and u."""
    import numpy as np

    faces = np.sort(tets[:, [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]].reshape(-1, 3), axis=1)
    unique, count = np.unique(faces, axis=0, return_counts=True)
    triangles = unique[count == 1]
    d = points[triangles, axis] - value
    crossing = triangles[(d.min(axis=1) < 0) & (d.max(axis=1) > 0)]
    cut_points, cut_u = [], []
    for tri in crossing:
        for i, j in ((0, 1), (1, 2), (2, 0)):
            di, dj = points[tri[i], axis] - value, points[tri[j], axis] - value
            if di * dj < 0:
                s = di / (di - dj)
                cut_points.append(points[tri[i]] + s * (points[tri[j]] - points[tri[i]]))
                cut_u.append(u[tri[i]] + s * (u[tri[j]] - u[tri[i]]))
    return np.array(cut_points), np.array(cut_u)


def small_png(source: Path, target: Path, limit: int = 280_000) -> None:
    """A copy of a PNG for docs/: optimised RGB, or with a 256-colour palette if that is over ``limit`` bytes."""
    from PIL import Image

    image = Image.open(source).convert("RGB")
    image.save(target, optimize=True)
    if Path(target).stat().st_size > limit:
        image.quantize(256, dither=Image.Dither.NONE).save(target, optimize=True)


def render(spec: dict[str, Any], timeout: float = 300.0) -> Path:
    """Render a spec (see the module docstring) in a subprocess; returns the PNG path."""
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(spec, f)
        path = f.name
    proc = subprocess.run([sys.executable, str(Path(__file__).resolve()), path], capture_output=True, text=True,
                          timeout=timeout)
    Path(path).unlink(missing_ok=True)
    png = Path(spec["png"])
    if proc.returncode != 0 or not png.is_file():
        raise RuntimeError(f"rendering {png.name} failed: {proc.stderr.strip()[-2000:]}")
    return png


def _main(spec_path: str) -> None:
    import warnings

    import meshio
    import numpy as np
    import pyvista

    warnings.filterwarnings("ignore")
    pyvista.OFF_SCREEN = True
    spec = json.loads(Path(spec_path).read_text())
    plotter = pyvista.Plotter(off_screen=True, window_size=tuple(spec.get("window", (1600, 700))))
    plotter.set_background("white")
    window = tuple(spec.get("window", (1600, 700)))
    labels, positions, bars = [], [], set()
    for panel in spec["panels"]:
        name = panel.get("scalars", spec.get("scalars"))
        x, y, width = panel.get("bar_position", spec.get("bar_position", (0.3, 0.04, 0.4)))
        bar = {"title": panel.get("bar", spec.get("bar", name)), "vertical": False, "position_x": x, "position_y": y,
               "width": width, "height": 0.06, "color": "black", "title_font_size": 18, "label_font_size": 16,
               "fmt": "%.3g"}
        data = meshio.read(panel["vtu"])
        kind, vtk_type = ("tetra", 10) if "tetra" in data.cells_dict else ("triangle", 5)
        cells = data.cells_dict[kind]
        offset = np.asarray(panel.get("offset", (0.0, 0.0, 0.0)), dtype=float)
        points = np.asarray(data.points, dtype=float)
        current = points + (data.point_data["u"] if panel.get("deformed", True) else 0.0)
        vtk_cells = np.hstack([np.full((len(cells), 1), cells.shape[1]), cells]).reshape(-1)
        types = np.full(len(cells), vtk_type, dtype=np.uint8)
        grid = pyvista.UnstructuredGrid(vtk_cells, types, current + offset)
        if panel.get("color") is None:
            grid.cell_data[name] = np.asarray(data.cell_data[name][0], dtype=float).reshape(len(cells), -1)[:, 0]
        if panel.get("arrows"):  # a cell vector field as arrows at the centroids (of the shown cells)
            shown = np.asarray(panel.get("arrow_cells", panel.get("cells", np.arange(len(cells)))), dtype=np.int64)
            centres = (current + offset)[cells[shown]].mean(axis=1)
            vectors = np.asarray(data.cell_data[panel["arrows"]][0], dtype=float)[shown]
            plotter.add_arrows(centres, vectors, mag=panel.get("arrow_scale", 0.1), color="black")
        if panel.get("cells") is not None:
            grid = grid.extract_cells(np.asarray(panel["cells"], dtype=np.int64))
        if panel.get("reference", False):
            reference = pyvista.UnstructuredGrid(vtk_cells, types, points + offset)
            plotter.add_mesh(reference.extract_feature_edges(45.0), color="grey", opacity=0.35, line_width=1)
        if panel.get("color") is not None:
            plotter.add_mesh(grid, color=panel["color"], show_edges=spec.get("edges", True), edge_color="#404040",
                             line_width=0.3, opacity=panel.get("opacity", 1.0), smooth_shading=False)
        else:
            plotter.add_mesh(grid, scalars=name, cmap=panel.get("cmap", spec.get("cmap", "viridis")),
                             clim=panel.get("clim", spec.get("clim")), show_edges=spec.get("edges", True),
                             edge_color="#404040", line_width=0.3, show_scalar_bar=name not in bars,
                             scalar_bar_args=bar, smooth_shading=False, opacity=panel.get("opacity", 1.0))
            bars.add(name)
        if panel.get("label"):
            top = current + offset
            labels.append(panel["label"])
            anchor = spec.get("label_anchor", "top")
            z = top[:, 2].max() if anchor == "top" else top[:, 2].min()
            positions.append([top[:, 0].mean(), top[:, 1].mean(), z])
    if labels:
        plotter.add_point_labels(np.array(positions), labels, font_size=spec.get("label_size", 20), show_points=False,
                                 shape=None, text_color="black", always_visible=True)
    if spec.get("title"):
        plotter.add_text(spec["title"], font_size=12, color="black")
    for text, fx, fy in spec.get("texts", []):
        plotter.add_text(text, position=(int(fx * window[0]), int(fy * window[1])), font_size=12, color="black")
    view = spec.get("view", "iso")
    {"xz": plotter.view_xz, "yz": plotter.view_yz, "xy": plotter.view_xy, "iso": plotter.view_isometric}[view]()
    if spec.get("negative"):
        {"xz": lambda: plotter.view_xz(negative=True), "yz": lambda: plotter.view_yz(negative=True),
         "xy": lambda: plotter.view_xy(negative=True), "iso": lambda: None}[view]()
    camera = plotter.camera
    if spec.get("elevation"):
        camera.elevation = spec["elevation"]
    if spec.get("azimuth"):
        camera.azimuth = spec["azimuth"]
    if spec.get("parallel", True):
        plotter.enable_parallel_projection()
    plotter.reset_camera()
    plotter.camera.zoom(spec.get("zoom", 1.0))
    plotter.screenshot(spec["png"])
    plotter.close()


if __name__ == "__main__":
    _main(sys.argv[1])
