"""Calibration (model/studies/calibration.py): exact derivatives of the measured quantities with respect to law
parameters (Taylor tests of order 2, the adjoint gradient equal to the tangent one), the shipped example recovering
its parameters within the noise, the command line and its one-line errors. P1 and Taylor-Hood P2/P1, a built-in
law (E and nu mapped to the held mu and lmbda), a built-in fibre law and a user law with a fibre term; the whole
module also runs on 2 ranks (same answers)."""

from __future__ import annotations

import copy
import json
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import EXAMPLES, ROOT, environment, serial_only
from mpi4py import MPI

from model.config import parse
from model.errors import ConfigError
from model.studies.calibration import Calibration, calibrate, parse_quantity, read_data

SPECIMEN = EXAMPLES / "calibration" / "specimen.toml"
MEASURED = EXAMPLES / "calibration" / "measured.csv"


def specimen() -> dict:
    return tomllib.loads(SPECIMEN.read_text())


#: every kind of quantity, at two load factors, weights of each quantity's scale
def data(force: float, length: float) -> pd.DataFrame:
    return pd.DataFrame({
        "load_factor": [0.5, 1.0, 0.5, 1.0, 1.0, 1.0],
        "quantity": ["reaction.xmax.x", "reaction.xmax.x", "probe.top.z", "probe.top.y", "volume.all",
                     "reaction.xmin.y"],
        "value": [0.3 * force, 0.5 * force, -0.03 * length, 0.01 * length, 2.1 * length**3, 0.01 * force],
        "weight": [force**-2, force**-2, length**-2, length**-2, length**-6, force**-2]})


def taylor(cal: Calibration, p: dict[str, float], relative: float = 0.05) -> tuple[list[float], list[float]]:
    """(rates of |Phi(p + h dp) - Phi(p)|, rates of |Phi(p + h dp) - Phi(p) - h g.dp|) for h = 1, 1/2, 1/4, 1/8."""
    g = cal.gradient(p)
    phi = cal.misfit(p)
    direction = {k: relative * v * s for (k, v), s in zip(p.items(), (1.0, -0.7, 0.6))}
    zeroth, first = [], []
    for h in (1.0, 0.5, 0.25, 0.125):
        moved = cal.misfit({k: p[k] + h * direction[k] for k in p})
        zeroth.append(abs(moved - phi))
        first.append(abs(moved - phi - h * float(g @ np.array([direction[k] for k in p]))))
    rates = lambda e: [float(np.log2(e[i] / e[i + 1])) for i in range(len(e) - 1)]  # noqa: E731
    return rates(zeroth), rates(first)


def check(cal: Calibration, p: dict[str, float]) -> None:
    zeroth, first = taylor(cal, p)
    assert min(zeroth) > 0.8 and max(zeroth) < 1.2, zeroth
    assert min(first) > 1.85, first
    tangent, adjoint = cal.gradient(p), cal.adjoint_gradient(p)
    assert np.allclose(adjoint, tangent, rtol=1e-8, atol=1e-12 * np.abs(tangent).max()), (adjoint, tangent)


def test_taylor_a_built_in_law_through_E_and_nu() -> None:
    """neo_hookean given by E and nu (held as mu and lmbda): reactions of both boundaries, a probe, the volume."""
    cal = Calibration(parse(specimen(), SPECIMEN.parent), data(3000.0, 1.0), ["material.0.E", "material.0.nu"])
    check(cal, {"material.0.E": 8.0e3, "material.0.nu": 0.27})
    e = cal.evaluate({"material.0.E": 8.0e3, "material.0.nu": 0.27})
    assert np.all(np.isfinite(e.jacobian)) and e.jacobian[0, 0] > 0  # stiffer: pulls harder


def test_taylor_a_fibre_law_in_the_mixed_formulation() -> None:
    """holzapfel_ogden, Taylor-Hood P2/P1 (the probe's weights on the displacement block of the mixed space): the
    matrix stiffness a and the fibre exponent b_f."""
    raw = specimen()
    raw["mesh"]["cells"] = [2, 1, 1]
    raw["discretization"] = {"degree": 2, "formulation": "mixed"}
    raw["material"] = [{"law": "holzapfel_ogden", "a": 600.0, "b": 8.0, "a_f": 2000.0, "b_f": 10.0, "kappa": 1.0e5,
                        "fibres": {"type": "constant", "origin": [0.0, 0.0, 0.0], "insertion": [1.0, 0.0, 0.0]},
                        "sheets": {"type": "constant", "origin": [0.0, 0.0, 0.0], "insertion": [0.0, 1.0, 0.0]}}]
    raw["boundary"][1]["value"] = [0.2]
    cal = Calibration(parse(raw, SPECIMEN.parent), data(300.0, 1.0), ["material.0.a", "material.0.b_f"])
    check(cal, {"material.0.a": 650.0, "material.0.b_f": 9.0})


def test_taylor_a_user_law_with_a_fibre_term() -> None:
    """examples/fibre_neo_hookean_law.py: its shear modulus and fibre stiffness."""
    raw = specimen()
    raw["material"] = [{"law": "../fibre_neo_hookean_law.py:psi", "mu": 2000.0, "lmbda": 5000.0, "k1": 3000.0,
                        "k2": 0.5,
                        "fibres": {"type": "constant", "origin": [0.0, 0.0, 0.0], "insertion": [1.0, 0.0, 1.0]}}]
    raw["boundary"][1]["value"] = [0.4]
    cal = Calibration(parse(raw, SPECIMEN.parent), data(3000.0, 1.0), ["material.0.mu", "material.0.k1"])
    check(cal, {"material.0.mu": 2200.0, "material.0.k1": 2500.0})


def test_the_example_recovers_its_parameters_within_the_noise(shared_tmp: Path) -> None:
    """The shipped data (examples/calibration/make_data.py: E = 1e4, nu = 0.3, 1 % noise) fitted from E = 5e3,
    nu = 0.2: each value within 2 standard errors of the truth, the misfit near its expectation (m - n)/2, and
    the files written (fitted.toml runs to the fitted curve)."""
    result = calibrate(SPECIMEN, MEASURED, ["material.0.E", "material.0.nu"], out=shared_tmp)
    truth = {"material.0.E": 1.0e4, "material.0.nu": 0.3}
    for key, value in truth.items():
        assert abs(result.parameters[key] - value) < 2 * result.std[key], (key, result.parameters, result.std)
    assert result.std["material.0.E"] < 0.02 * 1e4 and result.absolute_sigma and result.success
    assert 0.5 < result.misfit < 10.0 and result.misfit < 1e-3 * result.misfit_start
    summary = json.loads((shared_tmp / "calibration.json").read_text())
    assert summary["parameters"] == pytest.approx(result.parameters) and len(summary["history"]) >= 3
    table = pd.read_csv(shared_tmp / "fit.csv")
    assert len(table) == 10 and {"measured", "fitted", "sensitivity.material.0.E"} <= set(table.columns)
    fitted = tomllib.loads((shared_tmp / "fitted.toml").read_text())
    assert fitted["material"][0]["E"] == pytest.approx(result.parameters["material.0.E"])
    assert (shared_tmp / "fit.png").stat().st_size > 10_000


@serial_only
def test_the_shipped_data_is_what_make_data_writes(tmp_path: Path) -> None:
    """measured.csv is make_data.py's output (not edited by hand, not stale)."""
    out = tmp_path / "measured.csv"
    proc = subprocess.run([sys.executable, str(EXAMPLES / "calibration" / "make_data.py"), str(out)], cwd=tmp_path,
                          env=environment(), capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    made, shipped = pd.read_csv(out), pd.read_csv(MEASURED)
    assert list(made["quantity"]) == list(shipped["quantity"])
    assert np.allclose(made["value"], shipped["value"], rtol=1e-6)


@pytest.mark.parametrize(("rows", "message"), [
    ({"quantity": ["force.xmax.x"]}, "line 2: quantity 'force.xmax.x': unknown quantity"),
    ({"quantity": ["probe.top.w"]}, "is not probe.NAME.x|y|z"),
    ({"load_factor": [1.5]}, "line 2: load_factor must be in (0, 1]"),
    ({"value": ["high"]}, "line 2: value must be a number, got 'high'"),
    ({"sigma": [0.0]}, "line 2: sigma must be > 0, got 0.0"),
])
def test_bad_data_is_one_line_naming_the_line(tmp_path: Path, rows: dict, message: str) -> None:
    frame = {"load_factor": [1.0], "quantity": ["probe.top.z"], "value": [1.0], "sigma": [1.0], **rows}
    path = tmp_path / "data.csv"
    pd.DataFrame(frame).to_csv(path, index=False)
    with pytest.raises(ConfigError, match=None) as err:
        read_data(path)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_bad_columns_and_repeats(tmp_path: Path) -> None:
    path = tmp_path / "data.csv"
    path.write_text("load_factor,quantity,val\n1,probe.top.z,1\n")
    with pytest.raises(ConfigError, match="no column 'value'"):
        read_data(path)
    path.write_text("load_factor,quantity,value,sigma,weight\n1,probe.top.z,1,1,1\n")
    with pytest.raises(ConfigError, match="sigma or weight, not both"):
        read_data(path)
    path.write_text("load_factor,quantity,value\n1,probe.top.z,1\n1,probe.top.z,2\n")
    with pytest.raises(ConfigError, match="line 2: probe.top.z at load_factor 1.0 is given twice"):
        read_data(path)
    assert parse_quantity("volume.all").kind == "volume"


@pytest.mark.parametrize(("fit", "message"), [
    (["material.0.G"], "fit: material.0.G: neo_hookean has no parameter 'G' (its parameters: E, nu, mu, lmbda)"),
    (["material.1.E"], "fit: material.1.E: there are 1 materials"),
    (["loading.steps"], "fit: 'loading.steps' is not material.I.NAME"),
    (["material.0.E", "material.0.E"], "named twice"),
])
def test_bad_fit_keys_before_any_build(fit: list[str], message: str) -> None:
    with pytest.raises(ConfigError) as err:
        Calibration(parse(specimen(), SPECIMEN.parent), MEASURED, fit)
    assert message in str(err.value)


def test_unknown_names_in_the_data_before_any_solve() -> None:
    frame = pd.read_csv(MEASURED)
    frame.loc[3, "quantity"] = "probe.tip.z"
    with pytest.raises(ConfigError, match=r"data, row 3: probe.tip.z: no probe named 'tip' \(the configuration has: "
                                          r"top\)"):
        Calibration(parse(specimen(), SPECIMEN.parent), frame, ["material.0.E"])


def test_a_parameter_out_of_ufl_or_on_a_curve_is_refused() -> None:
    raw = specimen()
    raw["material"][0]["E"] = [[0.0, 5.0e3], [1.0, 6.0e3]]
    with pytest.raises(ConfigError, match="material.0.E follows a load curve"):
        Calibration(parse(raw, SPECIMEN.parent), MEASURED, ["material.0.E"])
    raw = copy.deepcopy(specimen())
    raw["material"][0]["density"] = 1000.0
    raw["dynamics"] = {"scheme": "newmark", "dt": 0.1, "end_time": 1.0}
    with pytest.raises(ConfigError, match="calibrate: a dynamic run"):
        Calibration(parse(raw, SPECIMEN.parent), MEASURED, ["material.0.E"])


@serial_only
def test_command_line(tmp_path: Path) -> None:
    """softtissue calibrate: exit 0 and the fitted values with their standard errors; exit 2 and one line on bad
    input; the help shows the example and the data format."""
    def cli(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "model", "calibrate", *args], cwd=ROOT, env=environment(),
                              capture_output=True, text=True, timeout=600)

    proc = cli(str(SPECIMEN), "--data", str(MEASURED), "--fit", "material.0.E,material.0.nu", "--out",
               str(tmp_path / "fit"), "--bounds", "material.0.nu=0.1:0.45")
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "material.0.E = 1003" in proc.stdout and "+-" in proc.stdout
    assert (tmp_path / "fit" / "fit.png").is_file()
    bad = cli(str(SPECIMEN), "--data", str(MEASURED), "--fit", "material.0.E", "--bounds", "material.0.E=1e3")
    assert bad.returncode == 2 and bad.stderr.strip().count("\n") == 0 and "write KEY=LO:HI" in bad.stderr
    help_text = cli("--help").stdout
    assert "examples/calibration/specimen.toml" in help_text and "reaction.BOUNDARY" in help_text


def test_same_fit_on_every_rank(shared_tmp: Path) -> None:
    """The evaluation (quantities and derivatives) is the same on every rank; its force is the one a run of the same
    parameters reports (model.pipeline.run: another route to the reaction) for any number of ranks, and at fixed nu the
    force at a prescribed stretch is proportional to E (dF/dE = F/E)."""
    from model.pipeline import run

    cal = Calibration(parse(specimen(), SPECIMEN.parent), MEASURED, ["material.0.E", "material.0.nu"])
    e = cal.evaluate({"material.0.E": 9.0e3, "material.0.nu": 0.31})
    gathered = MPI.COMM_WORLD.allgather(np.concatenate([e.quantities, e.jacobian.ravel()]))
    for other in gathered[1:]:
        assert np.array_equal(other, gathered[0])
    raw = specimen()
    raw["material"][0].update(E=9.0e3, nu=0.31)
    summary = run(parse(raw, SPECIMEN.parent), out=shared_tmp / "run")
    force = summary["steps"][-1]["reactions"]["xmax"][0]  # load factor 1: row 8 of measured.csv
    assert e.quantities[8] == pytest.approx(force, rel=1e-7)  # Newton's tolerance
    assert e.jacobian[8, 0] == pytest.approx(e.quantities[8] / 9.0e3, rel=1e-7)
