"""The verify tool: emit against an independent SVD computation, check's exit codes, bad input."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import svd_reference
from conftest import ROOT, environment, serial_only

from model.verify import compare, deformation_samples, emit, field_samples, reference

CASES = {
    "shape_target": {"mu": 2.5, "kappa": 40.0},
    "corotated": {"mu": 2.5, "lmbda": 40.0},
}


@pytest.mark.parametrize("inverted", [False, True])
@pytest.mark.parametrize("material", sorted(CASES))
def test_emit_matches_independent_svd(material: str, inverted: bool, shared_tmp) -> None:
    params = CASES[material]
    data = emit(material, params, samples=70, seed=3, out=shared_tmp / f"{material}.npz", inverted=inverted)
    labels = [str(x) for x in data["labels"]]
    for kind in ("identity", "rotation", "uniaxial", "isotropic", "large_stretch", "nearly_flat"):
        assert any(label.endswith(kind) for label in labels), kind
    if inverted:
        assert np.sum(np.linalg.det(data["F"]) < 0) == 70 // 4
    S = data["S"] if material == "shape_target" else np.broadcast_to(np.eye(3), data["F"].shape)
    kappa = params.get("kappa", params.get("lmbda"))
    expected = {"psi": [], "P": [], "A": []}
    for F, Sn in zip(data["F"], S):
        psi, P, A = svd_reference.shape_target(F, Sn, params["mu"], kappa)
        expected["psi"].append(psi)
        expected["P"].append(P)
        expected["A"].append(A)
    expected = {k: np.array(v) for k, v in expected.items()}
    for row in compare(expected, {q: data[q] for q in ("psi", "P", "A")}, rtol=1e-8):
        assert row.ok, f"{material} {row.quantity}: max rel error {row.max_rel_error:.2e} at {labels[row.worst_sample]}"


def test_identity_is_stress_free_and_rotation_invariant() -> None:
    rng = np.random.default_rng(0)
    F, _ = deformation_samples(7, 1)
    S = field_samples("shape_target", 7, 1)["S"]
    Q = np.linalg.qr(rng.standard_normal((3, 3)))[0]
    Q *= np.sign(np.linalg.det(Q))
    base = reference("shape_target", {"mu": 1.0, "kappa": 5.0}, F, S=S)
    rotated = reference("shape_target", {"mu": 1.0, "kappa": 5.0}, Q @ F, S=S)
    np.testing.assert_allclose(rotated["psi"], base["psi"], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(rotated["P"], Q @ base["P"], rtol=1e-9, atol=1e-11)
    at_target = reference("shape_target", {"mu": 1.0, "kappa": 5.0}, S, S=S)  # F = S: zero energy and stress
    np.testing.assert_allclose(at_target["psi"], 0.0, atol=1e-12)
    np.testing.assert_allclose(at_target["P"], 0.0, atol=1e-11)


@serial_only
def test_check_exit_codes(tmp_path) -> None:
    ref = tmp_path / "ref.npz"
    emit("shape_target", {"mu": 1.0}, samples=21, seed=5, out=ref)
    cmd = [sys.executable, "-m", "model", "verify", "check"]
    ok = subprocess.run([*cmd, str(ref)], capture_output=True, text=True, env=environment(), cwd=ROOT)
    assert ok.returncode == 0, ok.stdout + ok.stderr
    assert "psi" in ok.stdout and "A" in ok.stdout
    data = dict(np.load(ref))
    data["A"] = data["A"].copy()
    data["A"][4, 0, 1, 2, 2] += 1e-5 * np.abs(data["A"][4]).max()
    data.pop("psi")
    bad = tmp_path / "bad.npz"
    np.savez(bad, **data)
    fail = subprocess.run([*cmd, str(bad)], capture_output=True, text=True, env=environment(), cwd=ROOT)
    assert fail.returncode == 1, fail.stdout + fail.stderr
    table = fail.stdout.splitlines()[1:]
    rows = {line.split()[0]: line for line in table[1:table.index(next(t for t in table[1:] if t.split()[0]
                                                                       not in ("psi", "P", "A")))]}
    assert set(rows) == {"P", "A"} and "FAIL" in rows["A"] and rows["A"].split()[3] == "4"
    labels = [str(x) for x in data["labels"]]
    assert f"#4 {labels[4]}: singular values" in fail.stdout
    missing = subprocess.run([*cmd, str(tmp_path / "nope.npz")], capture_output=True, text=True,
                             env=environment(), cwd=ROOT)
    assert missing.returncode == 2 and missing.stderr.startswith("error: ")
    emit_cmd = [sys.executable, "-m", "model", "verify", "emit", "--material", "shape_target", "--param", "mu=-1",
                "--samples", "3", "--seed", "0", "--out", str(tmp_path / "x.npz")]
    bad_param = subprocess.run(emit_cmd, capture_output=True, text=True, env=environment(), cwd=ROOT)
    assert bad_param.returncode == 2 and "mu" in bad_param.stderr and len(bad_param.stderr.splitlines()) == 1


@pytest.mark.parametrize("material", sorted(CASES))
def test_envelope_stress_is_the_derivative_of_the_energy(material: str) -> None:
    """P = 2 mu (F - R* S) + ... is written by the envelope theorem, not derived from psi by UFL:
    check it against central differences of the reference psi (independent of that argument)."""
    params = CASES[material]
    F, _ = deformation_samples(28, 9, inverted=True)
    fields = field_samples(material, 28, 9)
    if material == "shape_target":
        F, _ = deformation_samples(28, 9, inverted=True, targets=fields["S"])
    base = reference(material, params, F, **fields)
    h = 1e-6
    for k in range(3):
        for l in range(3):
            dF = np.zeros((3, 3))
            dF[k, l] = h
            plus = reference(material, params, F + dF, **fields)["psi"]
            minus = reference(material, params, F - dF, **fields)["psi"]
            fd = (plus - minus) / (2 * h)
            scale = np.abs(base["P"]).max(axis=(1, 2)) + 1.0
            assert np.all(np.abs(fd - base["P"][:, k, l]) < 1e-6 * scale), (k, l)


NEO_HOOKEAN_FILE = '''
import ufl

PARAMETERS = {"mu": {"meaning": "shear modulus", "unit": "Pa (stress)", "bounds": (0, None), "exclusive": True}}
VOLUMETRIC = "ln J"


def psi(F, *, mu=1.0):
    """(mu/2)(tr C - 3) - mu ln J; with kappa: + (kappa/2)(ln J)^2."""
    return 0.5 * mu * (ufl.tr(F.T * F) - 3) - mu * ufl.ln(ufl.det(F))
'''


def test_a_law_of_your_own_is_checked_like_a_built_in_one(tmp_path) -> None:
    """``verify`` takes "FILE.py:FUNCTION" (the configuration's law registry): a neo-Hookean written as a user law
    gives the built-in neo_hookean's psi, P and A, to round-off."""
    law = tmp_path / "my_neo_hookean.py"
    law.write_text(NEO_HOOKEAN_FILE)
    F, _ = deformation_samples(40, 2)
    mine = reference(f"{law}:psi", {"mu": 3.0, "kappa": 7.0}, F)
    built_in = reference("neo_hookean", {"mu": 3.0, "lmbda": 7.0}, F)
    for row in compare(built_in, mine, rtol=1e-12):
        assert row.ok, f"{row.quantity}: max rel error {row.max_rel_error:.2e}"
    data = emit(f"{law}:psi", {"mu": 3.0, "kappa": 7.0}, samples=20, seed=1, out=tmp_path / "mine.npz")
    assert str(data["material"]).endswith("my_neo_hookean.py:psi") and np.all(np.isfinite(data["A"]))


def _verify(*args: str, cwd=ROOT) -> subprocess.CompletedProcess:  # noqa: ANN001
    return subprocess.run([sys.executable, "-m", "model", "verify", *args], capture_output=True, text=True,
                          env=environment(), cwd=cwd)


@serial_only
def test_emit_writes_the_path_given_with_string_params_and_fields(tmp_path) -> None:
    """--out xx wrote xx.npz and printed xx (now it prints the path written: the format comes from the
    suffix, .npz when there is none); --param took numbers only; --field is new."""
    out = tmp_path / "xx"
    run = _verify("emit", "--material", "muscle", "--param", "isotropic=stvk", "--param", "mu=2e3",
                  "--param", "lmbda=5e3", "--field", "a0=0,0,2", "--field", "alpha=0.5", "--samples", "14",
                  "--seed", "1", "--out", str(out))
    assert run.returncode == 0, run.stderr
    written = tmp_path / "xx.npz"
    assert written.is_file() and not out.exists()
    missing = _verify("check", str(out))  # the path given to emit: check names the file emit wrote
    assert missing.returncode == 2 and f"{written} exists" in missing.stderr, missing.stderr
    assert run.stdout.splitlines()[0].startswith(f"wrote {written}: 14 of 14 samples of muscle")
    data = np.load(written)
    assert np.all(data["a0"] == [0.0, 0.0, 1.0]) and np.all(data["alpha"] == 0.5)
    params = json.loads(str(data["params_json"]))
    assert params["isotropic"] == "stvk" and params["mu"] == 2e3 and params["K"] == 1e7
    kinds = {}
    for label in data["labels"]:
        kinds[str(label)] = kinds.get(str(label), 0) + 1
    assert "samples per kind: " + ", ".join(f"{k} {v}" for k, v in kinds.items()) in run.stdout
    moved = sum(v for k, v in kinds.items() if k.startswith("perturbed_"))
    assert f"moved {moved} sample(s) off a fibre breakpoint" in run.stdout
    inverted = _verify("emit", "--material", "neo_hookean", "--param", "mu=1", "--param", "lmbda=2", "--samples",
                       "8", "--seed", "0", "--inverted", "--out", str(tmp_path / "nh.npz"))
    assert inverted.returncode == 0 and "wrote" in inverted.stdout and "6 of 8" in inverted.stdout
    assert "dropped 2 sample(s): reference not finite" in inverted.stdout
    energy = tmp_path / "my_neo_hookean.py"
    energy.write_text(NEO_HOOKEAN_FILE)
    mine = _verify("emit", "--energy", f"{energy}:psi", "--param", "mu=3", "--samples", "7", "--seed", "0",
                   "--out", str(tmp_path / "mine.npz"))
    assert mine.returncode == 0, mine.stderr
    both = _verify("emit", "--energy", f"{energy}:psi", "--material", "stvk", "--samples", "7", "--seed", "0",
                   "--out", str(tmp_path / "x.npz"))
    assert both.returncode == 2


@serial_only
def test_check_takes_the_law_from_the_command_line_and_names_bad_input(tmp_path) -> None:
    """The file may lack material/params_json; bad JSON and a wrong sample count are one-line errors."""
    data = emit("neo_hookean", {"mu": 3.0, "lmbda": 7.0}, samples=14, seed=4, out=tmp_path / "ref.npz")
    bare = {k: data[k] for k in ("F", "P", "labels")}
    np.savez(tmp_path / "bare.npz", **bare)
    no_law = _verify("check", str(tmp_path / "bare.npz"))
    assert no_law.returncode == 2 and "--material" in no_law.stderr and len(no_law.stderr.splitlines()) == 1
    given = _verify("check", str(tmp_path / "bare.npz"), "--material", "neo_hookean", "--param", "mu=3",
                    "--param", "lmbda=7")
    assert given.returncode == 0, given.stdout + given.stderr
    np.savez(tmp_path / "half.npz", **dict(bare, P=0.5 * bare["P"]))
    wrong = _verify("check", str(tmp_path / "half.npz"), "--material", "neo_hookean", "--param", "mu=3",
                    "--param", "lmbda=7")
    assert wrong.returncode == 1 and "hint: P: yours = c x reference with c = 0.5 " in wrong.stdout
    conflict = _verify("check", str(tmp_path / "ref.npz"), "--param", "mu=4")
    assert conflict.returncode == 2 and "mu" in conflict.stderr and "conflicts" in conflict.stderr
    other = _verify("check", str(tmp_path / "ref.npz"), "--material", "stvk")
    assert other.returncode == 2 and "conflicts with the file's material neo_hookean" in other.stderr
    bad_json = dict(data, params_json=np.array('{"mu": 3.0, "lmbda": }'))
    bad_json.pop("path")
    np.savez(tmp_path / "json.npz", **bad_json)
    run = _verify("check", str(tmp_path / "json.npz"))
    assert run.returncode == 2 and len(run.stderr.splitlines()) == 1
    assert "json.npz" in run.stderr and "params_json" in run.stderr
    short = dict(data, P=data["P"][:-1])
    short.pop("path")
    np.savez(tmp_path / "short.npz", **short)
    run = _verify("check", str(tmp_path / "short.npz"))
    assert run.returncode == 2 and len(run.stderr.splitlines()) == 1, run.stderr
    assert "P: 13 samples, F has 14" in run.stderr
    layout = _verify("check", str(tmp_path / "ref.npz"), "--layout", "hessian9-col")  # the file says ijkl
    assert layout.returncode == 2 and "hessian9-col" in layout.stderr and "ijkl" in layout.stderr


@serial_only
def test_help_lists_laws_parameters_layouts_and_formats() -> None:
    import forms

    def help_listing_the_laws(*args: str) -> str:
        run = _verify(*args)
        assert run.returncode == 0, run.stderr
        text = " ".join(run.stdout.split())
        for name, entry in forms.REGISTRY.items():
            assert f"{name}: " in text
            for p in entry.parameters:
                assert p.name in text
        return text

    for args in (("--help",), ("emit", "--help"), ("check", "--help")):
        text = help_listing_the_laws(*args)
        assert "sigma_max=3e5" in text and "l_star_t=1.03" in text
        for layout in ("ijkl", "hessian9-col", "hessian9-row", "voigt-spatial", "abaqus-ddsdde", "voigt-material"):
            assert layout in text
        assert ".npz" in text and "CSV" in text
    text = help_listing_the_laws("element", "--help")  # the element's own file format, the laws, their parameters
    assert "m6=1" in text and "exit codes: 0 agrees" in text
