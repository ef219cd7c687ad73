"""The verify Python API (check -> Report), its exclusions and hints, and emit's samples: against
independent numpy implementations written here (neo-Hookean psi, P, A in closed form; the fibre
stretch lbar = |F a0| J^(-1/3); the PSD projection by eigen-decomposition)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from forms.muscle import Muscle
from model.verify import check, deformation_samples, emit
from model.verify.samples import parse_field

MU, LMBDA = 3.0, 7.0


def neo_hookean(F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """psi = mu/2 (tr C - 3) - mu ln J + lmbda/2 (ln J)^2, P = mu (F - F^-T) + lmbda ln J F^-T,
    A_ijkl = mu d_ik d_jl + (mu - lmbda ln J) Finv_jk Finv_li + lmbda Finv_ji Finv_lk (NaN where det F <= 0)."""
    J = np.linalg.det(F)
    with np.errstate(invalid="ignore", divide="ignore"):
        lnJ = np.log(J)
    Finv = np.linalg.inv(F)
    FinvT = np.transpose(Finv, (0, 2, 1))
    psi = 0.5 * MU * (np.einsum("nij,nij->n", F, F) - 3) - MU * lnJ + 0.5 * LMBDA * lnJ**2
    P = MU * (F - FinvT) + LMBDA * lnJ[:, None, None] * FinvT
    eye = np.eye(3)
    A = (MU * np.einsum("ik,jl->ijkl", eye, eye)[None]
         + (MU - LMBDA * lnJ)[:, None, None, None, None] * np.einsum("njk,nli->nijkl", Finv, Finv)
         + LMBDA * np.einsum("nji,nlk->nijkl", Finv, Finv))
    return psi, P, A


def lbar(F: np.ndarray, a0: np.ndarray) -> np.ndarray:
    """|F a0| |J|^(-1/3), the isochoric fibre stretch."""
    return np.linalg.norm(np.einsum("nij,nj->ni", F, a0), axis=1) / np.cbrt(np.abs(np.linalg.det(F)))


def test_right_formulas_pass_and_the_report_says_so() -> None:
    F, labels = deformation_samples(21, 4, inverted=False)
    psi, P, A = neo_hookean(F)
    report = check(F, psi=psi, P=P, tangent=A, law="neo_hookean", params={"mu": MU, "lmbda": LMBDA},
                   labels=labels, rtol=1e-10)
    assert report.ok, str(report)
    report.raise_if_failed()
    assert [r.quantity for r in report.rows] == ["psi", "P", "A"] and all(r.compared == 21 for r in report.rows)
    assert "result: ok" in str(report)


def test_a_nan_reference_is_excluded_with_a_count_and_never_poisons_the_rest() -> None:
    """ln J at det F < 0: the reference is NaN there. Those samples are left out (counted); the worst
    sample of a real error elsewhere is named, not sample 0."""
    F, labels = deformation_samples(28, 2, inverted=True)
    inverted = np.linalg.det(F) < 0
    assert inverted.sum() == 7
    psi, P, A = neo_hookean(F)
    P = P.copy()
    victim = int(np.flatnonzero(~inverted)[3])
    P[victim, 0, 1] += 1e-3 * np.abs(P[victim]).max()
    report = check(F, psi=psi, P=P, tangent=A, law="neo_hookean", params={"mu": MU, "lmbda": LMBDA}, labels=labels)
    rows = {r.quantity: r for r in report.rows}
    assert rows["psi"].ok and rows["A"].ok and not rows["P"].ok
    assert rows["P"].worst_sample == victim and np.isfinite(rows["P"].max_rel_error)
    for r in report.rows:
        assert dict(r.excluded)[next(iter(dict(r.excluded)))] == 7 and r.compared == 21
    text = str(report)
    assert "7 sample(s) excluded" in text and f"#{victim} {labels[victim]}" in text
    sigma = np.linalg.svd(F[victim], compute_uv=False)
    assert f"{sigma[0]:.6g}" in text  # the worst sample's singular values are printed


def test_constant_factor_hint() -> None:
    F, labels = deformation_samples(14, 6)
    _, P, _ = neo_hookean(F)
    report = check(F, P=0.5 * P, law="neo_hookean", params={"mu": MU, "lmbda": LMBDA}, labels=labels)
    assert not report.ok
    assert any("c = 0.5 " in h for h in report.hints), report.hints
    with pytest.raises(AssertionError, match="c = 0.5"):
        report.raise_if_failed()


def test_transpose_hint() -> None:
    F, labels = deformation_samples(14, 8, inverted=False)
    _, P, _ = neo_hookean(F)
    assert np.abs(P - np.transpose(P, (0, 2, 1))).max() > 1e-3  # P is not symmetric at these F
    report = check(F, P=np.transpose(P, (0, 2, 1)), law="neo_hookean", params={"mu": MU, "lmbda": LMBDA})
    assert not report.ok and any("transpose" in h for h in report.hints), report.hints
    assert not any("c = " in h for h in report.hints)


def test_errors_per_sample_kind() -> None:
    F, labels = deformation_samples(21, 3, inverted=False)
    psi, P, A = neo_hookean(F)
    A = A.copy()
    nearly_flat = [n for n, label in enumerate(labels) if label == "nearly_flat"]
    A[nearly_flat] *= 1.01
    report = check(F, tangent=A, law="neo_hookean", params={"mu": MU, "lmbda": LMBDA}, labels=labels)
    per_kind = dict(report.row("A").per_kind)
    assert set(per_kind) == set(labels)
    assert abs(per_kind["nearly_flat"] - 0.01) < 1e-8
    assert all(v < 1e-8 for k, v in per_kind.items() if k != "nearly_flat")
    assert labels[report.row("A").worst_sample] == "nearly_flat"


def project(A: np.ndarray) -> np.ndarray:
    """A as 9x9 [(i,j),(k,l)], eigenvalues below 0 set to 0 (numpy eigh, symmetrised first)."""
    H = A.reshape(-1, 9, 9)
    H = 0.5 * (H + np.transpose(H, (0, 2, 1)))
    w, V = np.linalg.eigh(H)
    return np.einsum("nij,nj,nkj->nik", V, np.maximum(w, 0.0), V).reshape(A.shape)


def test_projected_tangent() -> None:
    F, labels = deformation_samples(28, 5, inverted=False)
    _, _, A = neo_hookean(F)
    clamped = project(A)
    assert np.abs(clamped - A).max() > 1e-2  # some samples are indefinite
    params = {"mu": MU, "lmbda": LMBDA}
    assert check(F, tangent=clamped, law="neo_hookean", params=params, projected=True).ok
    assert not check(F, tangent=A, law="neo_hookean", params=params, projected=True).ok
    assert not check(F, tangent=clamped, law="neo_hookean", params=params).ok


def test_wrong_shapes_and_fields_are_one_line_errors() -> None:
    F, _ = deformation_samples(7, 1)
    _, P, A = neo_hookean(F)
    params = {"mu": MU, "lmbda": LMBDA}
    with pytest.raises(ValueError, match=r"P: shape \(6, 3, 3\) .*7 samples.*\(7, 3, 3\)"):
        check(F, P=P[:-1], law="neo_hookean", params=params)
    with pytest.raises(ValueError, match=r"tangent \(ijkl\): shape \(7, 9, 8\)"):
        check(F, tangent=A.reshape(7, 81)[:, :72].reshape(7, 9, 8), law="neo_hookean", params=params)
    with pytest.raises(ValueError, match="needs the field 'a0'"):
        check(F, P=P, law="tendon")
    with pytest.raises(ValueError, match="field 'S'"):
        check(F, P=P, law="neo_hookean", params=params, fields={"S": np.eye(3)})


def test_tangent_undefined_samples_are_left_out_of_A_only(monkeypatch, tmp_path) -> None:
    """Where the law says A is undefined (here: muscle at lbar = 1, declared in the test), A is not
    compared there (counted) while psi and P still are."""
    def at_lbar_one(self, F, **fields):  # noqa: ANN001, ANN202
        return np.abs(lbar(np.reshape(F, (-1, 3, 3)), fields["a0"]) - 1.0) < 1e-8

    monkeypatch.setattr(Muscle, "tangent_undefined", at_lbar_one)
    data = emit("muscle", {}, samples=14, seed=2, out=tmp_path / "ref.npz", include_undefined=True)
    fields = {"a0": data["a0"], "alpha": data["alpha"]}
    undefined = np.abs(lbar(data["F"], data["a0"]) - 1.0) < 1e-8
    assert undefined.sum() >= 4
    A = data["A"].copy()
    A[undefined] *= 2.0  # any value there: it is not compared
    report = check(data["F"], psi=data["psi"], P=data["P"], tangent=A, law="muscle", fields=fields,
                   labels=list(data["labels"]))
    assert report.ok, str(report)
    assert dict(report.row("A").excluded) == {"tangent undefined there (a breakpoint of the law, or a polar "
                                              "rotation that is not unique: Law.tangent_undefined)":
                                              int(undefined.sum())}
    assert report.row("P").compared == 14


def test_muscle_samples_avoid_the_fibre_breakpoint(tmp_path) -> None:
    """Before: 14 of 30 emitted muscle samples had lbar = 1 exactly (identity, rotations, isotropic
    stretches), where A jumps; with the identity drawn once, 11 of 30 of today's samples. Now none by
    default, and emit says how many it moved."""
    at = emit("muscle", {}, samples=30, seed=1, out=tmp_path / "ref.npz", include_undefined=True)
    assert np.sum(np.abs(lbar(at["F"], at["a0"]) - 1.0) < 1e-8) == 11
    data = emit("muscle", {}, samples=30, seed=1, out=tmp_path / "ref.npz")
    stretch = lbar(data["F"], data["a0"])
    assert np.sum(np.abs(stretch - 1.0) < 1e-8) == 0 and np.min(np.abs(stretch - 1.0)) > 1e-4
    summary = json.loads(str(data["emit_json"]))
    moved = [str(label) for label in data["labels"] if str(label).startswith("perturbed_")]
    assert summary["moved"] == {"fibre_breakpoint": len(moved)} and len(moved) >= 11
    assert summary["written"] == 30 and sum(summary["kinds"].values()) == 30
    fixed = emit("tendon", {}, samples=14, seed=3, out=tmp_path / "ref.npz", fields={"a0": np.array([1.0, 0.0, 0.0])})
    assert np.all(fixed["a0"] == [1.0, 0.0, 0.0]) and np.min(np.abs(lbar(fixed["F"], fixed["a0"]) - 1.0)) > 1e-4
    assert np.min(np.abs(np.linalg.norm(fixed["F"][:, :, 0], axis=1) - 1.0)) > 1e-4  # |F a0| = 1 avoided too


def test_emit_never_writes_a_non_finite_reference(tmp_path) -> None:
    """neo_hookean (ln J) with inverted samples: those have no energy; emit drops them and says so."""
    data = emit("neo_hookean", {"mu": MU, "lmbda": LMBDA}, samples=28, seed=2, out=tmp_path / "ref.npz", inverted=True)
    assert len(data["F"]) == 21 and np.all(np.linalg.det(data["F"]) > 0)
    for q in ("psi", "P", "A"):
        assert np.all(np.isfinite(data[q]))
    summary = json.loads(str(data["emit_json"]))
    assert summary["dropped"] == {"reference not finite (e.g. ln J at det F <= 0)": 7}
    assert not any(str(label).startswith("inverted") for label in data["labels"])
    psi, P, A = neo_hookean(data["F"])
    np.testing.assert_allclose(data["P"], P, rtol=1e-10, atol=1e-10 * np.abs(P).max())


def test_field_values() -> None:
    name, a0 = parse_field("muscle", "a0=1,1,0")
    assert name == "a0" and np.allclose(a0, [2**-0.5, 2**-0.5, 0.0])
    assert np.array_equal(parse_field("shape_target", "S=identity")[1], np.eye(3))
    assert parse_field("muscle", "alpha=0.5")[1] == 0.5
    with pytest.raises(ValueError, match="--field S: neo_hookean does not take"):
        parse_field("neo_hookean", "S=identity")
    with pytest.raises(ValueError, match="--field a0: 2 value"):
        parse_field("muscle", "a0=1,0")
    with pytest.raises(ValueError, match="S"):
        parse_field("shape_target", "S=1,2,3,4,5,6,7,8,9")


def test_a_9x9_or_6x6_tangent_must_name_its_layout(tmp_path) -> None:
    """An (N,9,9) tangent given without a layout was read as ijkl, i.e. as row-major vec(F): HOBAK's
    column-major Hessian then failed at relative error ~1 with no word on why. Now it is refused, naming the
    layouts of that shape, and passes when its layout is given."""
    F, _ = deformation_samples(8, 3)
    psi, P, A = neo_hookean(F)
    H_col = np.transpose(A, (0, 2, 1, 4, 3)).reshape(-1, 9, 9)  # H[i+3j, k+3l] = A[i,j,k,l]
    with pytest.raises(ValueError, match=r"shape \(8, 9, 9\).*hessian9-col.*hessian9-row"):
        check(F, tangent=H_col, law="neo_hookean", params={"mu": MU, "lmbda": LMBDA})
    with pytest.raises(ValueError, match=r"shape \(8, 6, 6\).*voigt-spatial.*abaqus-ddsdde.*voigt-material"):
        check(F, tangent=np.zeros((8, 6, 6)), law="neo_hookean", params={"mu": MU, "lmbda": LMBDA})
    assert check(F, tangent=H_col, law="neo_hookean", params={"mu": MU, "lmbda": LMBDA}, layout="hessian9-col").ok
    path = tmp_path / "hobak.npz"
    np.savez(path, F=F, A=H_col, material=np.array("neo_hookean"),
             params_json=np.array(json.dumps({"mu": MU, "lmbda": LMBDA})))
    with pytest.raises(ValueError, match=r"hobak.npz: tangent: shape \(8, 9, 9\).*--layout"):
        check(str(path))
    assert check(str(path), layout="hessian9-col").ok


def _signed_polar(F: np.ndarray) -> np.ndarray:
    """The rotation nearest to each F (numpy SVD, last column of U negated when det F < 0)."""
    U, _, Vt = np.linalg.svd(F)
    U[:, :, 2] *= np.sign(np.linalg.det(U @ Vt))[:, None]
    return U @ Vt


def test_rotation_law_stress_is_left_out_where_psi_has_a_kink() -> None:
    """corotated (mu = 1, lmbda = 0): psi = min_R ||F - R||^2 = sum (s_i - 1)^2 with s3 negated at det F < 0.
    Where det F < 0 and s2 = s3 the minimiser is not unique and psi has a kink (its one-sided derivatives
    along Q1 diag(0, 1, 0) Q2 differ, computed here): P is compared nowhere there (any P passes, counted),
    psi everywhere (3.53 at the issue's sample), P elsewhere against 2 mu (F - R) with numpy's SVD."""
    from scipy.spatial.transform import Rotation

    Q1, Q2 = Rotation.random(2, random_state=5).as_matrix()
    kinks = np.array([Q1 @ np.diag([1.5, 0.8, -0.8]) @ Q2, np.diag([1.0, 1.0, -1.0])])
    F = np.concatenate([deformation_samples(9, 2)[0], kinks])

    def psi_numpy(M: np.ndarray) -> np.ndarray:
        s = np.linalg.svd(M, compute_uv=False)
        s[:, 2] *= np.sign(np.linalg.det(M))
        return np.sum((s - 1.0) ** 2, axis=1)

    h = 1e-6
    D = Q1 @ np.diag([0.0, 1.0, 0.0]) @ Q2
    right = (psi_numpy(kinks[:1] + h * D) - psi_numpy(kinks[:1])) / h
    left = (psi_numpy(kinks[:1]) - psi_numpy(kinks[:1] - h * D)) / h
    assert abs(right[0] - (-0.4)) < 1e-4 and abs(left[0] - 3.6) < 1e-4  # a kink: no derivative there
    psi = psi_numpy(F)
    assert abs(psi[-2] - 3.53) < 1e-13
    P = 2.0 * (F - _signed_polar(F))
    P[-2:] = 17.0  # anything: P does not exist there
    report = check(F, psi=psi, P=P, law="corotated", params={"mu": 1.0, "lmbda": 0.0}, rtol=1e-9)
    assert report.ok, str(report)
    row = report.row("P")
    assert row.compared == 9 and sum(count for _, count in row.excluded) == 2
    assert "kink" in row.excluded[0][0] and report.row("psi").compared == 11
    largest = int(np.argmax(np.linalg.norm(P[:9], axis=(1, 2))))
    P[largest] *= 1.1
    wrong = check(F, P=P, law="corotated", params={"mu": 1.0, "lmbda": 0.0})
    assert not wrong.ok and wrong.row("P").worst_sample == largest


def test_zero_is_not_a_constant_factor() -> None:
    F, _ = deformation_samples(8, 4)
    psi, P, _ = neo_hookean(F)
    report = check(F, psi=np.zeros_like(psi), P=P, law="neo_hookean", params={"mu": MU, "lmbda": LMBDA})
    assert not report.ok
    assert report.hints == ["psi: yours is zero at every compared sample (the reference is not): not written, "
                            "or not read"], report.hints


def test_at_breakpoints_with_inverted_emits_rotation_kinks(tmp_path) -> None:
    """emit --inverted --at-breakpoints for a rotation law: some inverted samples have the two smallest
    singular values equal (labels ..._kink), psi there is min over SO(3) (numpy's signed singular values),
    and a check of the file leaves P and A out there with a count. Without --at-breakpoints none."""
    data = emit("corotated", {"mu": 1.0, "lmbda": 0.0}, samples=40, seed=3, out=tmp_path / "kinks.npz",
                inverted=True, include_undefined=True)
    labels = [str(x) for x in data["labels"]]
    kinks = np.array([label.endswith("_kink") for label in labels])
    assert 1 <= kinks.sum() <= 5, labels
    s = np.linalg.svd(data["F"], compute_uv=False)
    assert np.all(np.linalg.det(data["F"][kinks]) < 0)
    assert np.allclose(s[kinks, 1], s[kinks, 2], rtol=1e-12)
    s[:, 2] *= np.sign(np.linalg.det(data["F"]))
    np.testing.assert_allclose(data["psi"], np.sum((s - 1.0) ** 2, axis=1), rtol=1e-12, atol=1e-12)
    report = check(str(data["path"]))
    assert report.ok, str(report)
    for q in ("P", "A"):
        assert sum(count for _, count in report.row(q).excluded) == kinks.sum(), report.row(q)
    plain = emit("corotated", {"mu": 1.0, "lmbda": 0.0}, samples=40, seed=3, out=tmp_path / "plain.npz",
                 inverted=True)
    assert not any(str(label).endswith("_kink") for label in plain["labels"])
