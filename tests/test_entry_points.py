"""The command line's entry points: the ``softtissue`` console script and ``python -m model`` run from a folder that
holds a user's own ``meshes/`` and ``forms/`` (model/__main__.py); a bad configuration fails before mpi4py, PETSc
or dolfinx load (model/cli.py); ``--version``.

Subprocesses (serial run of the suite only), but for ``--version``. Where the installed project is this checkout
(``make``'s .venv), the children run without PYTHONPATH, as a user's would: the installed project then comes after
every sys.path entry, and an empty ``meshes/`` (a namespace package) in the working directory would win.
"""

from __future__ import annotations

import subprocess
import sys
import tomllib
from functools import cache
from pathlib import Path

import pytest

from model import cli
from tests.conftest import EXAMPLES, ROOT, environment, serial_only, write_toml

BAD_KEY = "loading.stpes"


@cache
def _user_environment() -> dict[str, str]:
    """environment() without this checkout on PYTHONPATH when the installed project is this checkout."""
    env = environment()
    bare = {k: v for k, v in env.items() if k != "PYTHONPATH"}
    found = subprocess.run([sys.executable, "-P", "-c", "import model; print(model.__file__)"], env=bare, cwd="/",
                           capture_output=True, text=True)
    if found.returncode == 0 and Path(found.stdout.strip()).resolve().parents[1] == ROOT:
        return bare
    return env


def _small_run(folder: Path) -> Path:
    """examples/uniaxial.toml, one load step on 1 x 1 x 1 cells, no VTU or PNG."""
    raw = tomllib.loads((EXAMPLES / "uniaxial.toml").read_text())
    raw["mesh"]["cells"] = [1, 1, 1]
    raw["loading"]["steps"] = 1
    raw["output"] = {"png": False, "vtu": False}
    raw.pop("probe", None)
    return write_toml(raw, folder / "small.toml")


@pytest.fixture
def user_folder(tmp_path: Path) -> Path:
    """A working directory with a user's ``meshes/`` (empty: a namespace package) and ``forms/`` (a package of
    its own), and a small run's configuration."""
    (tmp_path / "meshes").mkdir()
    (tmp_path / "forms").mkdir()
    (tmp_path / "forms" / "__init__.py").write_text('"""A user\'s own forms."""\n')
    _small_run(tmp_path)
    return tmp_path


def _script() -> Path:
    script = Path(sys.executable).parent / "softtissue"
    if not script.exists():
        pytest.skip(f"no console script {script}: the project is not installed in this environment "
                    "(pip install -e . installs it)")
    return script


@serial_only
@pytest.mark.parametrize("entry", ["softtissue", "python -m model"])
def test_runs_beside_a_users_meshes_and_forms(user_folder: Path, entry: str) -> None:
    command = [str(_script())] if entry == "softtissue" else [sys.executable, "-m", "model"]
    result = subprocess.run([*command, "run", "small.toml", "--out", "out"], cwd=user_folder,
                            env=_user_environment(), capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    assert (user_folder / "out" / "summary.json").is_file()


@serial_only
def test_bad_configuration_fails_before_mpi_and_dolfinx(tmp_path: Path) -> None:
    """A misspelt key: exit 2, one line naming it, and neither mpi4py, petsc4py nor dolfinx imported."""
    raw = tomllib.loads((EXAMPLES / "uniaxial.toml").read_text())
    raw["loading"] = {"stpes": 5}
    config = write_toml(raw, tmp_path / "bad.toml")
    probe = ("import sys\nfrom model.cli import main\ncode = main(['run', sys.argv[1]])\n"
             "print(sorted(m for m in ('mpi4py', 'petsc4py', 'dolfinx') if m in sys.modules))\nsys.exit(code)\n")
    result = subprocess.run([sys.executable, "-c", probe, str(config)], cwd=tmp_path, env=environment(),
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2, result.stderr[-3000:]
    assert result.stderr.startswith(f"error: {BAD_KEY}: unknown key") and result.stderr.count("\n") == 1, result.stderr
    assert result.stdout.strip() == "[]", result.stdout


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exited:
        cli.main(["--version"])
    assert exited.value.code == 0
    expected = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    assert capsys.readouterr().out == f"softtissue {expected} ({cli.DISTRIBUTION})\n"
