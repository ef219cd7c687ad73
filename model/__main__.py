"""``python -m model ...``: the same command line as the ``softtissue`` console script (model.cli).

``python -m`` puts the working directory first on sys.path, and this project's top-level packages are named
``meshes`` and ``forms``: a user's own folder ``meshes/`` or ``forms/`` in the working directory would be found
first (an installed, editable project is found after every sys.path entry, so even an empty folder, a namespace
package, wins) and every run would fail to import. So the working directory is taken off sys.path here, before
anything imports meshes or forms (model/__init__.py imports neither), unless it is the folder this ``model``
package itself was found in (a checkout run from its root: its meshes/ and forms/ are the project's). The console
script has the script's folder there instead, never the working directory. Files a configuration names (user
laws, shape targets, meshes, .geo scripts) are read by their paths, relative to the configuration's folder
(model.config.userfiles), not through sys.path.
"""

import os
import sys
from pathlib import Path


def _without_working_directory(path: list[str]) -> list[str]:
    """``path`` without the entries that name the working directory ("" among them), unless the model package was
    found there."""
    here = Path.cwd().resolve()
    if Path(__file__).resolve().parents[1] == here:
        return path
    return [p for p in path if Path(os.path.abspath(p or os.curdir)).resolve() != here]


sys.path[:] = _without_working_directory(sys.path)

from model.cli import main  # noqa: E402 - after sys.path is cleaned

sys.exit(main(prog="python -m model"))
