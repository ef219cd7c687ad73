"""PNG of a deformed body coloured by von Mises stress, rendered off screen by pyvista.

Run as ``python -m model.output.render RESULT.vtu OUT.png [--title T] [--stress-unit U] [--length-unit U]``.
It runs in its own process on purpose: dolfinx loads its libraries with RTLD_GLOBAL, after which
VTK's std::regex instantiations bind to ABI-incompatible copies and VTK crashes
while formatting the scalar bar. A process that never imports dolfinx is safe.

The colour bar is vertical, at the right edge, inside the image (SCALAR_BAR, in fractions of the
window), titled "von Mises stress [UNIT]" (scalar_bar_title); the title line names the step, the
largest displacement with its length unit and the magnification, "load factor 1   max displacement
0.000663 m   displacements x 20" (figure_title; VTK's text renderer reads "|" as mathtext, so the words are
spelled out).

What the picture shows (every run's deformed.png): the body deformed with its displacements magnified so that
the largest is about a tenth of the body's size (magnification: a round number, 1 when they are that large
already), over the undeformed body as a light grey silhouette with its outline drawn; an orientation triad (x, y, z)
in the lower left; the body seen at an angle, its longest axis across the image, and framed (parallel
projection fitted to the body's projected extent, left of the colour bar).
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


def figure_title(title: str, max_displacement: float | None = None, length_unit: str = "",
                 magnification: float = 1.0) -> str:
    """The title line: TITLE, then "max displacement X UNIT" (the largest |u|) when it is given, then
    "displacements x M" when they are magnified."""
    parts = [title] if title else []
    if max_displacement is not None:
        parts.append(f"max displacement {max_displacement:.3g}" + (f" {length_unit}" if length_unit else ""))
    if magnification != 1.0:
        parts.append(f"displacements x {magnification:g}")
    return "   ".join(parts)


#: the magnified largest displacement aimed at, as a fraction of the body's largest extent
VISIBLE_FRACTION = 0.1


def magnification(max_displacement: float, size: float, fraction: float = VISIBLE_FRACTION) -> float:
    """The factor that makes the largest displacement about ``fraction`` of the body's size: the largest of
    1, 2, 5 x 10^k not above fraction x size / max_displacement; 1 when the displacements are that large already
    (or zero)."""
    if not (max_displacement > 0 and size > 0):
        return 1.0
    wanted = fraction * size / max_displacement
    if wanted <= 1.0:
        return 1.0
    exponent = int(np.floor(np.log10(wanted)))
    for step in (5.0, 2.0, 1.0):
        if step * 10.0**exponent <= wanted * (1 + 1e-12):
            return float(step * 10.0**exponent)
    return 1.0


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
    largest = float(np.linalg.norm(u, axis=1).max()) if len(u) else 0.0
    factor = magnification(largest, float(np.ptp(points, axis=0).max()) if len(points) else 0.0)
    grid = pyvista.UnstructuredGrid(vtk_cells, celltypes, points + factor * u)
    bar_title = scalar_bar_title("von Mises stress", stress_unit)
    stress = np.asarray(data.cell_data["von_mises"][0]).reshape(-1)
    grid.cell_data[bar_title] = stress
    low, high = float(stress.min()), float(stress.max())
    if high - low <= 1e-6 * max(abs(high), 1e-300):  # homogeneous: don't colour rounding noise
        low, high = 0.9 * low, 1.1 * high if high > 0 else 1.0
    both = np.vstack([points, points + factor * u])
    direction, up = view_of(both)
    # the undeformed body, moved away from the camera by a little (a parallel projection shows it where it is):
    # behind the deformed body where they overlap, not through it
    behind = 0.02 * float(np.ptp(both, axis=0).max()) * direction
    reference = pyvista.UnstructuredGrid(vtk_cells, celltypes, points - behind)
    width, height = 1200, 900
    plotter = pyvista.Plotter(off_screen=True, window_size=(width, height))
    outline = reference.extract_surface()
    # the undeformed body: a light silhouette behind the deformed one, and its outline drawn over it
    plotter.add_mesh(outline, color="#c8c8c8", opacity=0.35, lighting=False)
    plotter.add_silhouette(outline, color="#404040", line_width=1.5)
    bar = {"title": bar_title, "vertical": True, "fmt": "%.3g", "n_labels": 5, "title_font_size": 18,
           "label_font_size": 16, "color": "black", "unconstrained_font_size": True, **SCALAR_BAR}
    plotter.add_mesh(grid, scalars=bar_title, cmap="viridis", show_edges=True, edge_color="#303030",
                     line_width=0.5, clim=(low, high), scalar_bar_args=bar)
    text = figure_title(title, largest if len(u) else None, length_unit, factor)
    if text:
        plotter.add_text(text, font_size=10)
    plotter.add_axes(line_width=3, labels_off=False)  # the orientation triad, lower left
    plotter.camera_position = [tuple(both.mean(axis=0) + direction), tuple(both.mean(axis=0)), tuple(up)]
    plotter.enable_parallel_projection()
    _frame(plotter, both, BODY_VIEWPORT[2] * width / height)
    # fit the body left of the colour bar: shift the picture by moving the camera sideways
    _shift_left(plotter, 1.0 - BODY_VIEWPORT[2], width / height)
    plotter.screenshot(str(png))
    plotter.close()


def view_of(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(direction from the body to the camera, view-up) that shows a body at an angle with its longest axis across
    the image: a plate (thinnest extent below 0.15 of the largest) is seen along its thin axis; otherwise from
    the thinnest axis tilted towards the other two, with view-up the middle axis."""
    extent = np.ptp(points, axis=0)
    order = np.argsort(extent)  # thinnest, middle, longest
    axes = np.eye(3)
    thin, middle, longest = (axes[i] for i in order)
    if extent[order[0]] < 0.15 * extent[order[2]]:  # up: the in-plane axis of the higher index (xy: y; xz, yz: z)
        return thin, axes[max(order[1], order[2])]
    direction = thin + 0.45 * middle + 0.25 * longest
    up = middle - (middle @ direction) / (direction @ direction) * direction
    return direction / np.linalg.norm(direction), up / np.linalg.norm(up)


def _frame(plotter: object, points: np.ndarray, aspect: float, margin: float = 1.08) -> None:
    """Parallel projection fitted to the points' extent in the view plane (``aspect`` = width / height of the
    part of the window the body goes in), the focal point at its centre."""
    camera = plotter.camera  # type: ignore[attr-defined]
    focal = np.array(camera.focal_point)
    position = np.array(camera.position)
    forward = focal - position
    forward /= np.linalg.norm(forward)
    up = np.array(camera.up, dtype=float)
    up -= (up @ forward) * forward
    up /= np.linalg.norm(up)
    right = np.cross(forward, up)
    across, along = points @ right, points @ up
    centre = focal + ((across.max() + across.min()) / 2 - focal @ right) * right \
        + ((along.max() + along.min()) / 2 - focal @ up) * up
    distance = float(np.linalg.norm(focal - position)) or 1.0
    camera.focal_point = tuple(centre)
    camera.position = tuple(centre - forward * max(distance, 10.0 * float(np.ptp(points, axis=0).max())))
    half_height = max(np.ptp(along) / 2, np.ptp(across) / 2 / aspect)
    camera.parallel_scale = margin * half_height
    plotter.reset_camera_clipping_range()  # type: ignore[attr-defined]


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
