"""The PNG's colour bar: titled with the quantity and its unit, and whole, inside the image.

render runs in a subprocess (it must never share a process with dolfinx), so the picture is made by
render_in_subprocess from a VTU written here with meshio: a tiny twisted tetrahedral block.
"""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np
import pytest
from mpi4py import MPI

from model.output.render import SCALAR_BAR, figure_title, render_in_subprocess, scalar_bar_title

pytestmark = pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="starts its own process; serial run only")


def test_scalar_bar_title_names_the_unit() -> None:
    assert scalar_bar_title("von Mises stress", "Pa") == "von Mises stress [Pa]"
    assert scalar_bar_title("von Mises stress", "MPa") == "von Mises stress [MPa]"
    assert scalar_bar_title("von Mises stress") == "von Mises stress"
    assert figure_title("load factor 1", 0.0123, "mm") == "load factor 1   max displacement 0.0123 mm"
    assert figure_title("t 0.5") == "t 0.5"


def tiny_vtu(path: Path) -> None:
    """A unit cube of 6 tetrahedra, sheared, with a stress varying over the cells."""
    corners = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], dtype=float)
    cells = np.array([[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]])
    u = 0.2 * corners[:, [2]] * np.array([1.0, 0.0, 0.0])
    stress = np.linspace(1.0e3, 2.5e5, len(cells))
    meshio.Mesh(corners, [("tetra", cells)], point_data={"u": u}, cell_data={"von_mises": [stress]}).write(path)


def test_colour_bar_is_whole_and_inside_the_image(tmp_path: Path) -> None:
    Image = pytest.importorskip("PIL.Image")
    vtu, png = tmp_path / "tiny.vtu", tmp_path / "tiny.png"
    tiny_vtu(vtu)
    try:
        render_in_subprocess(vtu, png, "load factor 1", "MPa", "mm", timeout=120)
    except RuntimeError as err:  # no off-screen OpenGL here: the writer then logs "no PNG written"
        pytest.skip(f"no off-screen rendering: {err}")
    image = np.asarray(Image.open(png).convert("RGB")).astype(int)
    height, width, _ = image.shape
    background = image[height - 1, 0]
    differs = np.abs(image - background).sum(axis=2) > 30
    x0, y0 = SCALAR_BAR["position_x"], SCALAR_BAR["position_y"]
    x1, y1 = x0 + SCALAR_BAR["width"], y0 + SCALAR_BAR["height"]
    assert 0 < x0 < x1 < 1 and 0 < y0 < y1 < 1  # the bar's region lies inside the image
    rows = slice(int((1 - y1) * height), int((1 - y0) * height))  # image rows run downwards
    region = differs[rows, int(x0 * width):int(x1 * width)]
    assert region.mean() > 0.05, "no colour bar drawn in its region"
    # the bar's colours run from viridis' dark purple (low) to its yellow (high), both inside the region
    pixels = image[rows, int(x0 * width):int(x1 * width)].reshape(-1, 3)
    assert np.any((pixels[:, 0] > 200) & (pixels[:, 1] > 200) & (pixels[:, 2] < 100)), "no yellow (maximum)"
    assert np.any((pixels[:, 0] < 90) & (pixels[:, 1] < 30) & (pixels[:, 2] > 60)), "no purple (minimum)"
    # nothing is cut off at the right edge: bar, labels and title end before the last 3 % of the width
    margin = differs[:, int(0.97 * width):]
    assert not margin.any(), f"{int(margin.sum())} drawn pixels in the right margin"
    # the title of the bar sits above it, inside the image, left of the margin
    above = differs[int((1 - y1) * height) - 40:int((1 - y1) * height), int(0.7 * width):]
    assert above.any(), "no colour bar title"


def test_magnification_makes_small_displacements_visible() -> None:
    from model.output.render import magnification

    assert magnification(0.000663, 0.146) == 20.0  # the demo: 0.66 mm on 146 mm -> x 20 (22 wanted)
    assert magnification(0.2, 1.0) == 1.0 and magnification(0.0, 1.0) == 1.0  # large enough, or none
    assert magnification(1e-6, 1.0) == 1e5 and magnification(3e-4, 1.0) == 200.0
    assert figure_title("load factor 1", 0.000663, "m", 20.0).endswith("displacements x 20")


def test_small_displacements_are_magnified_over_the_undeformed_outline_and_framed(tmp_path: Path) -> None:
    """A body that barely moves (0.07 % of its size) is drawn magnified (x 100), with the undeformed body's light grey
    silhouette showing beside it, the orientation triad in the lower left, and the body filling most of the
    width left of the colour bar."""
    Image = pytest.importorskip("PIL.Image")
    vtu, png = tmp_path / "tiny.vtu", tmp_path / "tiny.png"
    corners = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], dtype=float) * [3.0, 1.0, 1.0]
    cells = np.array([[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]])
    u = 0.002 * corners[:, [2]] * np.array([1.0, 0.0, 0.0])  # largest |u| 0.002 on a body 3 long: x 100
    meshio.Mesh(corners, [("tetra", cells)], point_data={"u": u},
                cell_data={"von_mises": [np.linspace(1.0, 2.0, len(cells))]}).write(vtu)
    try:
        render_in_subprocess(vtu, png, "load factor 1", "Pa", "m", timeout=120)
    except RuntimeError as err:
        pytest.skip(f"no off-screen rendering: {err}")
    image = np.asarray(Image.open(png).convert("RGB")).astype(int)
    height, width, _ = image.shape
    body = image[:, : int(SCALAR_BAR["position_x"] * width)]
    grey = (np.abs(body - body[..., [0]]).max(axis=2) < 6) & (body[..., 0] > 150) & (body[..., 0] < 235)
    coloured = np.abs(body - body[..., [0]]).max(axis=2) > 40  # viridis: not grey
    assert grey.sum() > 500, "no undeformed silhouette beside the deformed body"
    columns = np.flatnonzero(coloured[int(0.1 * height):int(0.85 * height)].any(axis=0))
    assert np.ptp(columns) > 0.6 * body.shape[1], "the body does not fill the width left of the colour bar"
    triad = np.abs(image[int(0.8 * height):, : int(0.2 * width)] - image[-1, 0]).sum(axis=2) > 60
    assert triad.sum() > 50, "no orientation triad in the lower left"
