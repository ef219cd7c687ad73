"""PNG of a deformed body coloured by von Mises stress, rendered off screen by pyvista.

Run as ``python -m model.output.render RESULT.vtu OUT.png [--title T] [--stress-unit U] [--length-unit U]``.
It runs in its own process on purpose: dolfinx loads its libraries with RTLD_GLOBAL, after which
VTK's std::regex instantiations bind to ABI-incompatible copies and VTK crashes
while formatting the scalar bar. A process that never imports dolfinx is safe.

The colour bar is vertical, at the right edge, inside the image (SCALAR_BAR, in fractions of the
window), titled "von Mises stress [UNIT]" (scalar_bar_title); the title line names the step and the
largest displacement with its length unit, "load factor 1   max displacement 0.233 m" (figure_title;
VTK's text renderer reads "|" as mathtext, so the words are spelled out).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np

#: where the colour bar goes, in fractions of the window (x, y of its lower left corner, width, height):
#: bar, labels and title end left of x = 0.97, leaving a margin at the right edge
SCALAR_BAR = {"position_x": 0.82, "position_y": 0.15, "width": 0.12, "height": 0.7}
#: the part of the window the body is fitted into (left of the colour bar)
BODY_VIEWPORT = (0.0, 0.0, 0.82, 1.0)


def scalar_bar_title(quantity: str, unit: str = "") -> str:
    """"QUANTITY [UNIT]", or QUANTITY alone when no unit is given."""
    return f"{quantity} [{unit}]" if unit else quantity


def figure_title(title: str, max_displacement: float | None = None, length_unit: str = "") -> str:
    """The title line: TITLE, then "max displacement X UNIT" (the largest |u|) when it is given."""
    parts = [title] if title else []
    if max_displacement is not None:
        parts.append(f"max displacement {max_displacement:.3g}" + (f" {length_unit}" if length_unit else ""))
    return "   ".join(parts)


def render(vtu: Path, png: Path, title: str = "", stress_unit: str = "", length_unit: str = "") -> None:
    """Deformed mesh (points + u) coloured by the cell data von_mises, reference surface as wireframe;
    colour bar titled scalar_bar_title("von Mises stress", stress_unit), title line figure_title(...)."""
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
    u = np.asarray(data.point_data["u"], dtype=np.float64)
    grid = pyvista.UnstructuredGrid(vtk_cells, celltypes, points + u)
    bar_title = scalar_bar_title("von Mises stress", stress_unit)
    stress = np.asarray(data.cell_data["von_mises"][0]).reshape(-1)
    grid.cell_data[bar_title] = stress
    low, high = float(stress.min()), float(stress.max())
    if high - low <= 1e-6 * max(abs(high), 1e-300):  # homogeneous: don't colour rounding noise
        low, high = 0.9 * low, 1.1 * high if high > 0 else 1.0
    reference = pyvista.UnstructuredGrid(vtk_cells, celltypes, points)
    width, height = 1200, 900
    plotter = pyvista.Plotter(off_screen=True, window_size=(width, height))
    plotter.add_mesh(reference.extract_surface(), style="wireframe", color="grey", opacity=0.15)
    bar = {"title": bar_title, "vertical": True, "fmt": "%.3g", "n_labels": 5, "title_font_size": 18,
           "label_font_size": 16, "color": "black", "unconstrained_font_size": True, **SCALAR_BAR}
    plotter.add_mesh(grid, scalars=bar_title, cmap="viridis", show_edges=True, edge_color="#303030",
                     line_width=0.5, clim=(low, high), scalar_bar_args=bar)
    text = figure_title(title, float(np.linalg.norm(u, axis=1).max()) if len(u) else None, length_unit)
    if text:
        plotter.add_text(text, font_size=10)
    extent = np.ptp(points + u, axis=0)
    thin = int(np.argmin(extent))
    if extent[thin] < 0.15 * extent.max():  # a plate: look along its thin axis
        (plotter.view_yz, plotter.view_xz, plotter.view_xy)[thin]()
    else:
        plotter.view_isometric()
    plotter.reset_camera()
    # fit the body left of the colour bar: shift the picture by moving the camera sideways
    _shift_left(plotter, 1.0 - BODY_VIEWPORT[2], width / height)
    plotter.screenshot(str(png))
    plotter.close()


def _shift_left(plotter: object, fraction: float, aspect: float) -> None:
    """Move the camera (position and focal point together) so that the picture moves left by half of
    ``fraction`` of the window width, and zoom out so the body still fits in the remaining width."""
    camera = plotter.camera  # type: ignore[attr-defined]
    focal = np.array(camera.focal_point)
    position = np.array(camera.position)
    view_up = np.array(camera.up)
    direction = focal - position
    distance = float(np.linalg.norm(direction))
    right = np.cross(direction / distance, view_up)
    right /= np.linalg.norm(right)
    scale = 1.0 / (1.0 - fraction)
    if camera.parallel_projection:
        camera.parallel_scale = camera.parallel_scale * scale
        half_height = camera.parallel_scale
    else:
        camera.zoom(1.0 / scale)
        half_height = distance * np.tan(np.radians(camera.view_angle) / 2.0)
    offset = fraction / 2.0 * 2.0 * half_height * aspect  # window widths -> world length at the focal plane
    camera.focal_point = tuple(focal + offset * right)
    camera.position = tuple(position + offset * right)


def render_in_subprocess(vtu: Path, png: Path, title: str = "", stress_unit: str = "", length_unit: str = "",
                         timeout: float = 300.0) -> None:
    """Run ``render`` in a fresh interpreter; raises RuntimeError with its stderr on failure."""
    command = [sys.executable, "-m", "model.output.render", str(vtu), str(png), "--title", title,
               "--stress-unit", stress_unit, "--length-unit", length_unit]
    proc = subprocess.run(command, capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0 or not png.is_file():
        raise RuntimeError(f"rendering {png.name} failed: {proc.stderr.strip().splitlines()[-1:] or proc.returncode}")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m model.output.render", description=__doc__.splitlines()[0])
    parser.add_argument("vtu", type=Path)
    parser.add_argument("png", type=Path)
    parser.add_argument("--title", default="")
    parser.add_argument("--stress-unit", default="", help="unit of the colour bar's stress, e.g. Pa")
    parser.add_argument("--length-unit", default="", help="unit of the displacement in the title, e.g. m")
    args = parser.parse_args(argv)
    render(args.vtu, args.png, args.title, args.stress_unit, args.length_unit)


if __name__ == "__main__":
    main()
