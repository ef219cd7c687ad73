"""``verify seeds``: the seed formulas as printed against the UFL reference (model/verify/seeds/).

The findings are pinned: the rows that agree must keep agreeing and the printed formulas that
disagree must keep disagreeing (by a clear margin, not rounding), so that a regression in either
the UFL reference or a transcription fails here. Every ``-corrected`` row agrees.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, environment, serial_only
from mpi4py import MPI

from model.verify import deformation_samples, field_samples, seeds

AGREE = {
    "klar-eq1", "klar-eq3", "klar-eq4-6", "klar-psd", "klar-eq1-inverted",
    "thesis-eq4.11", "thesis-eqC.15",
    "thesis-eq4.5-stvk", "thesis-eq4.5-neo_hookean", "thesis-eq4.5-corotated", "thesis-eq4.5-shape_target",
    "thesis-eq4.8", "thesis-eqB.19", "thesis-dUdF",
    "thesis-eq4.13", "thesis-sec3.3.3.1-F", "thesis-sec3.3.3.1-energy", "thesis-sec3.3.3.1-forces",
    "thesis-sec3.3.3.1-hessian", "thesis-eq4.4", "sgi-kkt", "sgi-kkt-stationarity", "sgi-kkt-fem",
    "sgi-adjoint", "sgi-adjoint-gradient",
}
DISAGREE = {"klar-eq2", "klar-eq3-inverted", "klar-eq4-6-inverted", "thesis-eq4.3", "thesis-eq4.12", "thesis-eqC.16",
            "thesis-eq4.9", "thesis-eq4.10", "thesis-eq4.14", "thesis-eq4.15", "thesis-sec3.3.3.1-pressure",
            "sgi-poisson-equation", "sgi-adjoint-dlambda", "sgi-adjoint-stationarity"}
#: the rows of the table before the split of model/verify/seeds.py into a package, in their order
BEFORE_SPLIT = [
    "klar-eq1", "klar-eq2", "klar-eq2-corrected", "klar-eq3", "klar-eq4-6", "klar-psd", "klar-eq1-inverted",
    "klar-eq3-inverted", "klar-eq3-inverted-corrected", "klar-eq4-6-inverted", "klar-eq4-6-inverted-corrected",
    "thesis-eq4.3", "thesis-eq4.3-corrected", "thesis-eq4.11", "thesis-eq4.12", "thesis-eq4.12-corrected",
    "thesis-eqC.15", "thesis-eqC.16", "thesis-eqC.16-corrected", "thesis-eq4.8", "thesis-eqB.19", "thesis-eq4.9",
    "thesis-eq4.9-corrected", "thesis-eq4.10", "thesis-eq4.10-corrected", "thesis-dUdF", "thesis-eq4.5-stvk",
    "thesis-eq4.5-neo_hookean", "thesis-eq4.5-corotated", "thesis-eq4.5-shape_target",
]
CORRECTED = {f"{id_}-corrected" for id_ in DISAGREE}
KEYS = {"id", "source", "agrees", "max_rel_error", "diagnosis"}


@pytest.fixture(scope="module")
def rows() -> list[seeds.SeedRow]:
    return seeds.seed_rows()


def by_id(rows: list[seeds.SeedRow]) -> dict[str, seeds.SeedRow]:
    table = {r.id: r for r in rows}
    assert len(table) == len(rows), "duplicate ids"
    return table


def test_table_has_exactly_the_pinned_rows(rows) -> None:
    assert set(by_id(rows)) == AGREE | DISAGREE | CORRECTED


def test_the_rows_before_the_split_come_first_in_their_order(rows) -> None:
    assert [r.id for r in rows[: len(BEFORE_SPLIT)]] == BEFORE_SPLIT


@pytest.mark.parametrize("id_", sorted(AGREE | CORRECTED))
def test_row_agrees(rows, id_: str) -> None:
    row = by_id(rows)[id_]
    assert row.agrees and row.max_rel_error <= seeds.RTOL, row


@pytest.mark.parametrize("id_", sorted(DISAGREE))
def test_printed_formula_disagrees(rows, id_: str) -> None:
    row = by_id(rows)[id_]
    assert not row.agrees and row.max_rel_error > 1e-2, row
    assert row.diagnosis and row.source.split()[0] in {seeds.KLAR, seeds.THESIS, seeds.SGI}


def test_klar_eq5_reading_of_the_levi_civita_contractions() -> None:
    """dR* of eq. 5 (as read in model/seeds.py) is the derivative of R* = U V^T: central differences."""
    F, _ = deformation_samples(21, 5, inverted=False)
    S = field_samples("shape_target", 21, 5)["S"]
    dF = np.random.default_rng(3).standard_normal(F.shape)
    h = 1e-6
    fd = (seeds.klar_rotation(F + h * dF, S) - seeds.klar_rotation(F - h * dF, S)) / (2 * h)
    exact = seeds.klar_eq5_rotation_differential(F, S, dF)
    np.testing.assert_allclose(exact, fd, atol=1e-7 * np.abs(exact).max())


def test_irving_Bm_is_minus_volume_times_shape_gradients() -> None:
    """B_m (Irving's area-weighted normals) = -V D_m^-T: eq. 4.5's G = P B_m is minus the element gradient."""
    X = seeds.TET
    Dm = (X[1:] - X[0]).T
    np.testing.assert_allclose(seeds.irving_Bm(X), -abs(np.linalg.det(Dm)) / 6.0 * np.linalg.inv(Dm).T, atol=1e-14)


def test_json_has_the_contract_keys(rows, shared_tmp: Path) -> None:
    path = shared_tmp / "seeds.json"
    assert seeds.run_seeds(path, rows=rows) == 0  # rank 0 writes, then a barrier
    data = json.loads(path.read_text())
    assert [d["id"] for d in data] == [r.id for r in rows]
    for d in data:
        assert set(d) == KEYS
        assert isinstance(d["agrees"], bool) and isinstance(d["max_rel_error"], float)
        assert isinstance(d["source"], str) and isinstance(d["diagnosis"], str) and d["diagnosis"]
    MPI.COMM_WORLD.barrier()  # rank 0 may remove shared_tmp only after every rank has read


@serial_only
def test_cli_verify_seeds(tmp_path: Path) -> None:
    out = tmp_path / "seeds.json"
    proc = subprocess.run([sys.executable, "-m", "model", "verify", "seeds", "--json", str(out)], cwd=ROOT,
                          env=environment(), capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    data = json.loads(out.read_text())
    assert {d["id"] for d in data} == AGREE | DISAGREE | CORRECTED
    assert all(set(d) == KEYS for d in data)
    for d in data:
        assert d["id"] in proc.stdout


def test_thesis_muscle_corrected_tangent_is_the_derivative_of_eq4_8() -> None:
    """eq. 4.10-corrected = d/dF (dF2/dlbar eq. 4.8) by central differences, independently of UFL."""
    F = np.array([np.eye(3) + 0.1 * g for g in np.random.default_rng(11).standard_normal((6, 3, 3))])
    a0 = field_samples("muscle", 6, 11)["a0"]

    def stress(G: np.ndarray) -> np.ndarray:
        dF2, _ = seeds.muscle_fibre_derivatives(seeds.fibre_stretch_np(G, a0))
        return dF2[:, None, None] * seeds.thesis_eq4_8_dlbar(G, a0)

    dF2, d2F2 = seeds.muscle_fibre_derivatives(seeds.fibre_stretch_np(F, a0))
    exact = seeds.thesis_eq4_10_corrected(F, a0, dF2, d2F2)
    fd = seeds._central_differences(stress, F)
    np.testing.assert_allclose(exact, fd, atol=1e-7 * np.abs(exact).max())
