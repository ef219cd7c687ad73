"""emit and check in every tangent layout and file format: what emit writes passes check, a perturbed
entry fails it, a layout mix-up is named, stresses are checked in their own measure, and the samples
where a conversion loses digits are left out with a count. The reference arrays here are an
independent closed-form neo-Hookean (numpy), converted to each layout by explicit loops."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from conftest import ROOT, environment, serial_only

from model.verify import check, deformation_samples, emit
from model.verify.files import read_arrays

MU, LMBDA = 3.0, 7.0
PARAMS = {"mu": MU, "lmbda": LMBDA}
LAYOUTS = ("ijkl", "hessian9-col", "hessian9-row", "voigt-spatial", "abaqus-ddsdde", "voigt-material")
VOIGT = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))


def neo_hookean(F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """P = mu (F - F^-T) + lmbda ln J F^-T and A_ijkl = mu d_ik d_jl + (mu - lmbda ln J) Finv_jk Finv_li
    + lmbda Finv_ji Finv_lk."""
    J = np.linalg.det(F)
    Finv = np.linalg.inv(F)
    FinvT = np.transpose(Finv, (0, 2, 1))
    lnJ = np.log(J)
    P = MU * (F - FinvT) + LMBDA * lnJ[:, None, None] * FinvT
    eye = np.eye(3)
    A = (MU * np.einsum("ik,jl->ijkl", eye, eye)[None]
         + (MU - LMBDA * lnJ)[:, None, None, None, None] * np.einsum("njk,nli->nijkl", Finv, Finv)
         + LMBDA * np.einsum("nji,nlk->nijkl", Finv, Finv))
    return P, A


def in_layout(layout: str, F: np.ndarray, P: np.ndarray, A: np.ndarray) -> np.ndarray:
    """The tangent in ``layout``, by loops over the definitions of verification.md."""
    n = len(F)
    if layout == "ijkl":
        return A
    if layout.startswith("hessian9"):
        H = np.empty((n, 9, 9))
        for i, j, k, l in np.ndindex(3, 3, 3, 3):
            a, b = (i + 3 * j, k + 3 * l) if layout == "hessian9-col" else (3 * i + j, 3 * k + l)
            H[:, a, b] = A[:, i, j, k, l]
        return H
    D = np.empty((n, 6, 6))
    for m in range(n):
        f, J = F[m], np.linalg.det(F[m])
        finv = np.linalg.inv(f)
        S = finv @ P[m]
        sigma = P[m] @ f.T / J
        if layout == "voigt-material":  # C_IJKL = dS_IJ/dE_KL from A_iJkL = delta_ik S_JL + F_iI F_kK C_IJKL
            T = np.einsum("Ii,Kk,iJkL->IJKL", finv, finv, A[m] - np.einsum("ik,JL->iJkL", np.eye(3), S))
        else:  # c_ijkl = (1/J) F_iI F_jJ F_kK F_lL C_IJKL = (1/J) F_jJ F_lL A_iJkL - delta_ik sigma_jl
            T = np.einsum("jJ,lL,iJkL->ijkl", f, f, A[m]) / J - np.einsum("ik,jl->ijkl", np.eye(3), sigma)
            if layout == "abaqus-ddsdde":
                d = np.eye(3)
                T = T + 0.5 * (np.einsum("ik,jl->ijkl", d, sigma) + np.einsum("ik,jl->ijkl", sigma, d)
                               + np.einsum("il,jk->ijkl", d, sigma) + np.einsum("il,jk->ijkl", sigma, d))
        for I, (i, j) in enumerate(VOIGT):
            for K, (k, l) in enumerate(VOIGT):
                D[m, I, K] = T[i, j, k, l]
    return D


def samples(n: int = 14, seed: int = 5) -> tuple[np.ndarray, list[str]]:
    """deformation samples without the nearly flat ones (their dS/dE conversion is tested apart)."""
    F, labels = deformation_samples(n, seed, inverted=False)
    keep = [i for i, label in enumerate(labels) if label != "nearly_flat"]
    return F[keep], [labels[i] for i in keep]


@pytest.mark.parametrize("layout", LAYOUTS)
def test_a_right_tangent_passes_and_a_perturbed_entry_fails_in_every_layout(layout: str) -> None:
    F, labels = samples()
    P, A = neo_hookean(F)
    tangent = in_layout(layout, F, P, A)
    report = check(F, P=P, tangent=tangent, law="neo_hookean", params=PARAMS, layout=layout, labels=labels,
                   rtol=1e-9)
    assert report.ok, str(report)
    assert f"tangent layout {layout}" in str(report)
    wrong = tangent.copy()
    index = (4, *([1] * (wrong.ndim - 1)))
    wrong[index] += 1e-5 * np.abs(wrong[4]).max()
    report = check(F, tangent=wrong, law="neo_hookean", params=PARAMS, layout=layout, labels=labels, rtol=1e-9)
    assert not report.ok and report.row("A").worst_sample == 4 and report.row("A").worst_samples == (4,)


def test_stresses_are_checked_in_their_own_measure() -> None:
    """PK2 = F^-1 P and sigma = P F^T / J, as 3x3 or Voigt; a Kirchhoff stress given as sigma is named."""
    F, labels = samples()
    P, _ = neo_hookean(F)
    J = np.linalg.det(F)
    S = np.linalg.solve(F, P)
    sigma = P @ np.transpose(F, (0, 2, 1)) / J[:, None, None]
    voigt = np.stack([sigma[:, i, j] for i, j in VOIGT], axis=1)
    report = check(F, PK2=S, sigma=voigt, law="neo_hookean", params=PARAMS, labels=labels, rtol=1e-9)
    assert report.ok and [r.quantity for r in report.rows] == ["PK2", "sigma"], str(report)
    tau = J[:, None] * voigt
    report = check(F, sigma=tau, law="neo_hookean", params=PARAMS, labels=labels, rtol=1e-9)
    assert not report.ok and any("Kirchhoff" in h for h in report.hints), report.hints


def test_a_column_major_hessian_read_as_row_major_is_named() -> None:
    """HOBAK's layout (vec(F) column-major) checked as hessian9-row: the report says which layout matches."""
    F, labels = samples()
    P, A = neo_hookean(F)
    report = check(F, tangent=in_layout("hessian9-col", F, P, A), law="neo_hookean", params=PARAMS,
                   layout="hessian9-row", labels=labels)
    assert not report.ok
    assert any("hessian9-col" in h for h in report.hints), report.hints


def test_dS_dE_at_nearly_flat_samples_is_left_out_with_a_count() -> None:
    """dS/dE from A loses eps cond(F)^3: at the nearly flat samples (smallest singular value 1e-4..1e-2)
    a check at 1e-8 would fail a right answer; those samples are excluded from A, counted, and the
    others compared."""
    F, labels = deformation_samples(21, 3, inverted=False)
    flat = np.array([label == "nearly_flat" for label in labels])
    P, A = neo_hookean(F)
    report = check(F, tangent=in_layout("voigt-material", F, P, A), law="neo_hookean", params=PARAMS,
                   layout="voigt-material", labels=labels, rtol=1e-8)
    assert report.ok, str(report)
    row = report.row("A")
    lossy = sum(count for reason, count in row.excluded if "loses" in reason)
    assert 1 <= lossy <= flat.sum() and row.compared == 21 - lossy
    assert check(F, tangent=in_layout("ijkl", F, P, A), law="neo_hookean", params=PARAMS).row("A").compared == 21


def test_projected_tangent_needs_a_9x9_layout() -> None:
    F, _ = samples()
    P, A = neo_hookean(F)
    with pytest.raises(ValueError, match="voigt-spatial"):
        check(F, tangent=in_layout("voigt-spatial", F, P, A), law="neo_hookean", params=PARAMS,
              layout="voigt-spatial", projected=True)


@pytest.mark.parametrize("suffix", [".npz", ".csv", ".json", "_npy"])
@pytest.mark.parametrize("layout", ["hessian9-col", "abaqus-ddsdde"])
def test_emit_writes_the_layout_and_format_and_check_reads_it_back(layout: str, suffix: str, shared_tmp) -> None:
    out = shared_tmp / f"ref_{layout}{suffix}"
    if suffix == "_npy":
        out.mkdir(exist_ok=True)
    data = emit("neo_hookean", PARAMS, samples=14, seed=2, out=out, layout=layout)
    assert str(data["path"]) == str(out)
    content = read_arrays(out)
    assert content["layout"] == layout and content["A"].shape[1:] == ((9, 9) if layout == "hessian9-col" else (6, 6))
    if layout == "abaqus-ddsdde":
        assert content["sigma"].shape[1:] == (6,)
    P, A = neo_hookean(content["F"])
    expected = in_layout(layout, content["F"], P, A).reshape(len(P), -1)
    error = np.linalg.norm(content["A"].reshape(len(P), -1) - expected, axis=1) / np.linalg.norm(expected, axis=1)
    assert error.max() < 1e-8, error  # 2e-9 at a nearly flat sample (cond F 1e4): the closed form loses digits too
    assert check(out).ok


@serial_only
def test_cli_checks_a_csv_written_by_another_code(tmp_path) -> None:
    """A C++ code writes a CSV: F row-major, the Hessian in HOBAK's layout; check takes the law on the
    command line; an off entry gives exit 1."""
    F, _ = samples(7, 1)
    P, A = neo_hookean(F)
    H = in_layout("hessian9-col", F, P, A)
    header = [f"F{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3)] + [f"P{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3)]
    header += [f"H_{a}_{b}" for a in range(9) for b in range(9)]

    def write(path, H):  # noqa: ANN001, ANN202
        rows = [",".join(header)]
        for n in range(len(F)):
            values = [*F[n].reshape(-1), *P[n].reshape(-1), *H[n].reshape(-1)]
            rows.append(",".join(f"{v:.17g}" for v in values))
        path.write_text("\n".join(rows) + "\n")

    write(tmp_path / "mine.csv", H)
    command = [sys.executable, "-m", "model", "verify", "check", str(tmp_path / "mine.csv"), "--material",
               "neo_hookean", "--param", "mu=3", "--param", "lmbda=7", "--layout", "hessian9-col", "--rtol", "1e-9"]
    run = subprocess.run(command, capture_output=True, text=True, env=environment(), cwd=ROOT)
    assert run.returncode == 0, run.stdout + run.stderr
    H[3, 2, 5] *= 1.001
    write(tmp_path / "mine.csv", H)
    run = subprocess.run(command, capture_output=True, text=True, env=environment(), cwd=ROOT)
    assert run.returncode == 1 and "result: FAIL" in run.stdout, run.stdout + run.stderr
