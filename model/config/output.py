"""[output]: where the results go and which files are written."""

from __future__ import annotations

from pathlib import Path

from pydantic import field_validator

from model.config.base import ExistingFile, Flag, Section, fail, key


class OutputConfig(Section):
    """[output]: the results folder (summary.json is always written) and the optional file formats."""

    dir: Path = key("folder of the results, relative to the working directory (the command line's --out wins)",
                    default=Path("results"))

    @field_validator("dir")
    @classmethod
    def _folder(cls, path: Path) -> Path:
        if path.exists() and not path.is_dir():
            fail(f"{path} is a file, not a folder: give a folder for the results")
        return path
    xdmf: Flag = key("write the displacement and cell fields per step as XDMF + HDF5", default=True)
    vtu: Flag = key("write one VTU file per step", default=True)
    png: Flag = key("render deformed.png, a picture of the deformed body at the last step", default=True)
    render_mesh: ExistingFile | None = key(
        "a surface mesh (OBJ, STL, PLY or any file meshio reads), relative to the configuration file's folder, "
        "embedded in the body (each vertex moves with the cell around it, or the nearest cell) and written deformed "
        "at every step in its own format as render/<name>_NNNN.<suffix>", default=None)
