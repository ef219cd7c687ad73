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


def test_make_notebooks_builds_every_notebook_into_an_ignored_folder() -> None:
    """`make notebooks` converts and executes each notebook into results/notebooks/NAME.ipynb, which git ignores."""
    dry = subprocess.run(["make", "-n", "notebooks"], cwd=ROOT, env=environment(), capture_output=True, text=True,
                         timeout=120)
    assert dry.returncode == 0, dry.stderr
    for notebook in NOTEBOOKS:
        assert f"notebooks/{notebook.name}" in dry.stdout, notebook.name
    assert "jupytext --to ipynb --execute --run-path notebooks" in dry.stdout and "'.[notebooks]'" in dry.stdout
    ignored = subprocess.run(["git", "check-ignore", "-q", "results/notebooks/isometric.ipynb",
                              "notebooks/isometric.ipynb"], cwd=ROOT, capture_output=True)
    assert ignored.returncode in (0, 128), ignored  # 128: not a git checkout (an unpacked release)


def test_a_notebook_executes_in_jupyter(tmp_path: Path) -> None:
    """Where the extra [notebooks] is installed: jupytext executes a notebook in a Jupyter kernel, as `make
    notebooks` does, and the .ipynb holds its outputs, none an error."""
    pytest.importorskip("jupytext")
    pytest.importorskip("ipykernel")
    out = tmp_path / "screened_poisson.ipynb"
    env = environment()
    env.update(CI="true", NOTEBOOK_OUT=str(tmp_path))
    source = ROOT / "notebooks" / "screened_poisson.py"
    proc = subprocess.run([sys.executable, "-m", "jupytext", "--to", "ipynb", "--execute", "--run-path",
                           str(ROOT / "notebooks"), "--output", str(out), str(source)], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    import json

    cells = [c for c in json.loads(out.read_text())["cells"] if c["cell_type"] == "code"]
    outputs = [o for c in cells for o in c.get("outputs", [])]
    assert outputs and not [o for o in outputs if o.get("output_type") == "error"]
