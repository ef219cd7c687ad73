"""Every notebook in notebooks/ (jupytext percent-format .py files) runs top to bottom with plain Python.

Each runs in its own process with CI=true (its short mode) and NOTEBOOK_OUT pointing into a
temporary directory, serially only (they start processes of their own). Files whose name starts
with an underscore are helpers, not notebooks.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from conftest import ROOT, environment, serial_only

pytestmark = serial_only

NOTEBOOKS = sorted(p for p in (ROOT / "notebooks").glob("*.py") if not p.name.startswith("_"))


def test_notebooks_found() -> None:
    assert {p.stem for p in NOTEBOOKS} >= {"trunk", "guided", "muscle_targets", "skinning", "membrane"}


@pytest.mark.parametrize("notebook", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs(notebook: Path, tmp_path: Path) -> None:
    text = notebook.read_text()
    assert text.startswith("# ---\n# jupyter:") and "# %% [markdown]" in text, "not a jupytext percent notebook"
    env = environment()
    env.update(CI="true", NOTEBOOK_OUT=str(tmp_path), MPLBACKEND="Agg")
    env.pop("WRITE_DOCS", None)
    proc = subprocess.run([sys.executable, str(notebook)], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=600)
    if proc.returncode != 0:  # pytest.fail: an assert's message is cut to a few lines, the traceback lost with it
        def tail(text: str, n: int) -> str:  # without UFL's repeated warning on custom quadrature metadata
            return "\n".join([line for line in text.splitlines() if "Applying str() to a metadata" not in line][-n:])
        pytest.fail(f"{notebook.name} exited with {proc.returncode}\n--- stdout (end)\n{tail(proc.stdout, 20)}\n"
                    f"--- stderr (end)\n{tail(proc.stderr, 60)}", pytrace=False)
    assert list(tmp_path.rglob("*.png")), "the notebook made no picture"
