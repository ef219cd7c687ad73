"""verify's diagnosis: errors measured where they are, coverage said, inverted samples by default.

The planted-bug catalogue (tests/test_verify_planted.py) checks the hints over many bugs; this file checks
the measurement itself: the nearly flat samples no longer hide the others, the coverage line, the
default sampling, single precision and atol, and the command line's --atol / --no-inverted.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys

import numpy as np
import pytest
from conftest import ROOT, environment

from model.verify import check, deformation_samples, emit

MU, LMBDA = 3.0, 7.0
PARAMS = {"mu": MU, "lmbda": LMBDA}


def neo_hookean(F: np.ndarray, dtype: type = np.float64) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """psi = mu/2 (I1 - 3) - mu ln J + lmbda/2 (ln J)^2, P = mu (F - F^-T) + lmbda ln J F^-T,
    A = mu I(x)I - (mu - lmbda ln J) d(F^-T)/dF + lmbda F^-T x F^-T, in ``dtype``."""
    F = np.asarray(F, dtype=dtype)
    with np.errstate(all="ignore"):
        J = np.linalg.det(F)
        lnJ = np.log(J)
        Fi = np.linalg.inv(F)
    FiT = np.transpose(Fi, (0, 2, 1))
    psi = MU / 2 * (np.einsum("nij,nij->n", F, F) - 3) - MU * lnJ + LMBDA / 2 * lnJ**2
    P = MU * (F - FiT) + LMBDA * lnJ[:, None, None] * FiT
    dT = -np.einsum("nli,njk->nijkl", Fi, Fi)
    eye = np.eye(3, dtype=dtype)
    A = (MU * np.einsum("ik,jl->ijkl", eye, eye)[None] - (MU - LMBDA * lnJ)[:, None, None, None, None] * dT
         + LMBDA * np.einsum("nij,nkl->nijkl", FiT, FiT))
    return psi, P, A


def lambda_term(F: np.ndarray) -> np.ndarray:
    FiT = np.transpose(np.linalg.inv(F), (0, 2, 1))
    return LMBDA * np.einsum("nij,nkl->nijkl", FiT, FiT)


def test_nearly_flat_samples_no_longer_hide_the_others() -> None:
    """The tangent missing lmbda F^-T x F^-T: its true relative error is ~0.7 at the identity and up to ~1 at
    large stretches. Before, the floor 1e-6 max|A| (pushed to ~1e9 by the nearly flat samples) shrank every
    ordinary sample's error ~100x, and the worst samples named were all nearly flat."""
    F, labels = deformation_samples(100, seed=1)
    psi, P, A = neo_hookean(F)
    report = check(F, tangent=A - lambda_term(F), law="neo_hookean", params=PARAMS, labels=labels)
    row = report.row("A")
    assert not row.ok
    per_kind = dict(row.per_kind)
    assert per_kind["identity"] == pytest.approx(LMBDA * 3 / np.linalg.norm(neo_hookean(np.eye(3)[None])[2]),
                                                 rel=1e-10)  # |lmbda I x I| = 3 lmbda
    assert per_kind["identity"] > 0.5 and per_kind["large_stretch"] > per_kind["nearly_flat"]
    assert not any(labels[n] == "nearly_flat" for n in row.worst_samples), [labels[n] for n in row.worst_samples]
    rel = np.linalg.norm((lambda_term(F)).reshape(100, -1), axis=1) / np.maximum(
        np.linalg.norm(A.reshape(100, -1), axis=1), report.modulus)
    finite = np.isfinite(rel)
    assert row.worst_sample == int(np.flatnonzero(finite)[np.argmax(rel[finite])])  # the truly worst
    text = str(report)
    assert "A[0, 0, 0, 0] at the identity #0 (J 1, stretches 1, 1, 1): yours 6, reference 13" in text, text
    assert "hint: A: yours - reference = -7 F^-T x F^-T at every compared sample (c = -lmbda)" in text, text


def test_every_report_ends_with_its_coverage() -> None:
    """ok or not, the report says what was compared and what never was: neo_hookean (ln J) is not finite at
    det F < 0, so those samples are excluded and 'det F < 0' is listed as never compared."""
    F, labels = deformation_samples(28, seed=2)
    psi, P, A = neo_hookean(F)
    report = check(F, psi=psi, P=P, tangent=A, law="neo_hookean", params=PARAMS, labels=labels)
    assert report.ok, str(report)
    coverage, never = report.coverage
    inverted = sum(label.startswith("inverted_") for label in labels)
    assert inverted == 7 and coverage.startswith(f"coverage: {28 - inverted} of 28 samples compared (identity 1, ")
    assert never == "never compared: det F < 0"
    assert str(report).splitlines()[-3:-1] == report.coverage
    stvk = check(F[:1], psi=np.zeros(1), law="stvk", params=PARAMS)
    never = stvk.coverage[1]
    assert "the identity" not in never and "det F < 0" in never and "a rotation" in never


def test_single_precision_passes_at_1e_4_and_atol_is_absolute() -> None:
    """Correct float32 formulas: the references near zero (identity, rotations) are measured against the law's
    modulus M, so rtol 1e-4 passes (before: only 1e-2 did). atol is an absolute tolerance in the quantity's unit."""
    F, labels = deformation_samples(40, seed=3, inverted=False)
    psi, P, A = neo_hookean(F, np.float32)
    report = check(F.astype(np.float32), psi=psi, P=P, tangent=A, law="neo_hookean", params=PARAMS, labels=labels,
                   rtol=1e-4)
    assert report.ok, str(report)
    psi64 = neo_hookean(F)[0]
    offset = check(F, psi=psi64 + 1e-6, law="neo_hookean", params=PARAMS)
    assert not offset.ok and [d.kind for d in offset.diagnoses] == ["offset"]
    assert check(F, psi=psi64 + 1e-6, law="neo_hookean", params=PARAMS, atol=2e-6).ok
    with pytest.raises(ValueError, match="atol = -1"):
        check(F, psi=psi64, law="neo_hookean", params=PARAMS, atol=-1)


def test_emit_draws_inverted_samples_unless_the_law_is_not_finite_there(tmp_path) -> None:
    stvk = emit("stvk", PARAMS, samples=28, seed=1, out=tmp_path / "stvk.npz")
    assert np.sum(np.linalg.det(stvk["F"]) < 0) == 7
    assert json.loads(str(stvk["emit_json"]))["inverted"] == "drawn"
    nh = emit("neo_hookean", PARAMS, samples=28, seed=1, out=tmp_path / "nh.npz")
    summary = json.loads(str(nh["emit_json"]))
    assert summary["written"] == 28 and np.all(np.linalg.det(nh["F"]) > 0)
    assert summary["inverted"].startswith("not drawn: the reference is not finite at det F < 0")
    off = emit("stvk", PARAMS, samples=28, seed=1, out=tmp_path / "off.npz", inverted=False)
    assert np.all(np.linalg.det(off["F"]) > 0)
    identities = np.sum(np.linalg.norm(stvk["F"] - np.eye(3), axis=(1, 2)) < 1e-12)
    assert identities == 1  # no sample twice


def test_command_line_atol_and_no_inverted(tmp_path) -> None:
    out = tmp_path / "ref.npz"
    emit_cmd = [sys.executable, "-m", "model", "verify", "emit", "--material", "stvk", "--param", "mu=3",
                "--param", "lmbda=7", "--samples", "14", "--seed", "2", "--no-inverted", "--out", str(out)]
    done = subprocess.run(emit_cmd, capture_output=True, text=True, env=environment(), cwd=ROOT)
    assert done.returncode == 0, done.stderr
    assert "inverted samples (det F < 0): not drawn (--no-inverted)" in done.stdout
    data = dict(np.load(out))
    data["psi"] = data["psi"] + 1e-6
    mine = tmp_path / "mine.npz"
    np.savez(mine, **data)
    check_cmd = [sys.executable, "-m", "model", "verify", "check", str(mine)]
    fail = subprocess.run(check_cmd, capture_output=True, text=True, env=environment(), cwd=ROOT)
    assert fail.returncode == 1 and "hint: psi: yours = reference + c with c = 1e-06" in fail.stdout, fail.stdout
    assert "never compared: det F < 0" in fail.stdout
    ok = subprocess.run([*check_cmd, "--atol", "2e-6"], capture_output=True, text=True, env=environment(), cwd=ROOT)
    assert ok.returncode == 0 and "atol 2e-06" in ok.stdout, ok.stdout


def test_the_documented_reports_are_what_the_shipped_commands_print(tmp_path) -> None:
    """docs/verify.md shows a report of each diagnosis kind for the files examples/verify_diagnosis.py writes:
    every line shown must still be printed, and each file gets the diagnosis of its kind."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("verify_diagnosis", ROOT / "examples" / "verify_diagnosis.py")
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    paths = example.write_cases(tmp_path)
    text = (ROOT / "docs" / "verify.md").read_text()
    blocks = re.findall(r"```\n\$ softtissue verify check results/verify_diagnosis/(\w+)\.npz\n(.*?)```", text, re.S)
    assert sorted(kind for kind, _ in blocks) == sorted(example.CASES)
    from model.verify import check_file

    for kind, block in blocks:
        report = check_file(paths[kind])
        assert not report.ok and {d.kind for d in report.diagnoses} == {kind}, (kind, report.hints)
        printed = str(report).splitlines()
        for line in block.strip().splitlines():
            assert line in printed, (kind, line)


def test_a_law_of_your_own_may_take_the_sheet_direction(tmp_path) -> None:
    """FIELDS = ("a0", "s0") was accepted by the contract but failed to load (a KeyError, then a TypeError)."""
    law = tmp_path / "sheet.py"
    law.write_text("import ufl\nFIELDS = ('a0', 's0')\n\n\ndef psi(F, *, mu=1.0, k=2.0, a0=None, s0=None):\n"
                   "    C = F.T * F\n    return 0.5 * mu * (ufl.tr(C) - 3) + k * (ufl.inner(s0, C * s0) - 1) ** 2\n")
    data = emit(f"{law}:psi", {}, samples=7, seed=1, out=tmp_path / "ref.npz")
    assert data["s0"].shape == (7, 3) and np.allclose(np.sum(data["s0"] * data["a0"], axis=1), 0.0)
    Cs = np.einsum("nji,njk,nk->ni", data["F"], data["F"], data["s0"])
    P = data["F"] + 4 * 2.0 * (np.einsum("ni,ni->n", data["s0"], Cs) - 1)[:, None, None] * np.einsum(
        "nij,nj,nk->nik", data["F"], data["s0"], data["s0"])
    assert check(data["F"], P=P, law=f"{law}:psi", fields={"a0": data["a0"], "s0": data["s0"]}).ok
