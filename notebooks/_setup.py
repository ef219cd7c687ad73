"""The start every notebook shares: whether it runs in its short CI mode, its output folder, matplotlib.

    ROOT = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd().resolve().parent
    sys.path[:0] = [str(ROOT), str(ROOT / "notebooks")]
    from _setup import start
    CI, OUT, plt = start("name")

CI: the environment variable CI is set (the tests run every notebook so, with fewer meshes or runs).
OUT: $NOTEBOOK_OUT/name, else results/notebooks/name (created). plt: matplotlib.pyplot with the Agg backend
outside Jupyter, or None when matplotlib is missing (the pictures are then skipped).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]


def start(name: str) -> tuple[bool, Path, Any]:
    """(CI, OUT, plt) of the notebook ``name`` (module docstring)."""
    out = Path(os.environ.get("NOTEBOOK_OUT", ROOT / "results" / "notebooks")) / name
    out.mkdir(parents=True, exist_ok=True)
    try:
        import matplotlib

        if "ipykernel" not in sys.modules:
            matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # plots are optional
        plt = None
    return bool(os.environ.get("CI")), out, plt
