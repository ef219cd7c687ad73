"""PNG of a deformed body coloured by von Mises stress, rendered off screen by pyvista.

Run as ``python -m model.output.render RESULT.vtu OUT.png [TITLE]``. It runs in its own
process on purpose: dolfinx loads its libraries with RTLD_GLOBAL, after which
VTK's std::regex instantiations bind to ABI-incompatible copies and VTK crashes
while formatting the scalar bar. A process that never imports dolfinx is safe.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np


def render(vtu: Path, png: Path, title: str = "") -> None:
    """Deformed mesh (points + u) coloured by the cell data von_mises, reference surface as wireframe."""
    import warnings

    import meshio
    import pyvista

    warnings.filterwarnings("ignore", category=pyvista.PyVistaFutureWarning)

    pyvista.OFF_SCREEN = True
    data = meshio.read(vtu)
    cells = data.cells_dict["tetra"]
    vtk_cells = np.hstack([np.full((len(cells), 1), 4), cells]).reshape(-1)
    celltypes = np.full(len(cells), 10, dtype=np.uint8)  # VTK_TETRA
    points = np.asarray(data.points, dtype=np.float64)
    grid = pyvista.UnstructuredGrid(vtk_cells, celltypes, points + data.point_data["u"])
    stress = np.asarray(data.cell_data["von_mises"][0]).reshape(-1)
    grid.cell_data["von Mises stress"] = stress
    low, high = float(stress.min()), float(stress.max())
    if high - low <= 1e-6 * max(abs(high), 1e-300):  # homogeneous: don't colour rounding noise
        low, high = 0.9 * low, 1.1 * high if high > 0 else 1.0
    reference = pyvista.UnstructuredGrid(vtk_cells, celltypes, points)
    plotter = pyvista.Plotter(off_screen=True, window_size=(1200, 900))
    plotter.add_mesh(reference.extract_surface(), style="wireframe", color="grey", opacity=0.15)
    plotter.add_mesh(grid, scalars="von Mises stress", cmap="viridis", show_edges=True, edge_color="#303030",
                     line_width=0.5, clim=(low, high), scalar_bar_args={"title": "von Mises stress"})
    if title:
        plotter.add_text(title, font_size=10)
    extent = np.ptp(points + data.point_data["u"], axis=0)
    thin = int(np.argmin(extent))
    if extent[thin] < 0.15 * extent.max():  # a plate: look along its thin axis
        (plotter.view_yz, plotter.view_xz, plotter.view_xy)[thin]()
    else:
        plotter.view_isometric()
    plotter.reset_camera()
    plotter.screenshot(str(png))
    plotter.close()


def render_in_subprocess(vtu: Path, png: Path, title: str = "", timeout: float = 300.0) -> None:
    """Run ``render`` in a fresh interpreter; raises RuntimeError with its stderr on failure."""
    proc = subprocess.run([sys.executable, "-m", "model.output.render", str(vtu), str(png), title],
                          capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0 or not png.is_file():
        raise RuntimeError(f"rendering {png.name} failed: {proc.stderr.strip().splitlines()[-1:] or proc.returncode}")


if __name__ == "__main__":
    render(Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3] if len(sys.argv) > 3 else "")
