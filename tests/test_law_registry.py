"""The law registry (forms.registry): metadata of every built-in law, its agreement with the laws' own
validation, the Markdown reference, and user laws from files (forms.user_law, examples/guccione_law.py).

- LAWS, FIELDS and make_law are unchanged views of the registry.
- Every parameter has a meaning, a unit and a default or "required"; defaults are the dataclasses'
  defaults; each numeric bound is the one the law enforces (a value beyond it raises the
  ParameterError naming the key and the documented range), inf is accepted exactly where documented.
- A user law validates its parameters with the same wording as the built-in ones; its stress dW/dF
  (derived by UFL) matches central differences of W; the Guccione example equals Land et al. 2015's
  formula written in an explicit fibre frame (f, s, n).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import ufl
from conftest import EXAMPLES
from dolfinx import fem
from mpi4py import MPI
from scipy.spatial.transform import Rotation

import forms
from forms.metadata import FIELD_MEANINGS
from model import compat

inf = math.inf
BUILT_IN = ["stvk", "neo_hookean", "mooney_rivlin", "corotated", "fixed_corotated", "arap", "stable_neo_hookean",
            "yeoh", "shape_target", "volume", "muscle", "tendon", "ogden", "holzapfel_ogden",
            "trans_iso_mooney_rivlin", "blemker"]
UNITS = {"Pa (stress)", "dimensionless", "choice"}


def test_laws_and_fields_are_views_of_the_registry() -> None:
    assert list(forms.REGISTRY) == BUILT_IN
    assert forms.LAWS == {name: forms.REGISTRY[name].law for name in BUILT_IN}
    assert forms.FIELDS == {"shape_target": ("S",), "volume": ("S",), "muscle": ("a0", "alpha"), "tendon": ("a0",),
                            "holzapfel_ogden": ("a0", "s0"), "trans_iso_mooney_rivlin": ("a0", "alpha"),
                            "blemker": ("a0", "alpha")}
    assert all(forms.resolve_law(name) is forms.REGISTRY[name] for name in BUILT_IN)
    law = forms.REGISTRY["neo_hookean"].make(E=1e4, nu=0.3)
    assert law == forms.make_law("neo_hookean", E=1e4, nu=0.3)
    with pytest.raises(forms.ParameterError, match="unknown law 'neo_hooke' \\(choose from arap, blemker, corotated, "):
        forms.make_law("neo_hooke")
    with pytest.raises(forms.ParameterError, match="unknown law 'neo_hooke' .*FILE.py:FUNCTION"):
        forms.resolve_law("neo_hooke")


@pytest.mark.parametrize("name", BUILT_IN)
def test_every_parameter_is_described(name: str) -> None:
    entry = forms.REGISTRY[name]
    assert entry.formula and entry.summary and entry.law.name == name
    assert all(f in FIELD_MEANINGS for f in entry.fields)
    if entry.bulk_parameter is None:  # arap: no volumetric term
        assert entry.make(**valid(name, "mu")).bulk_penalty == 0
    else:
        assert entry.bulk_parameter == entry.law.bulk_parameter and entry.parameter(entry.bulk_parameter).infinite
    assert len(set(entry.names)) == len(entry.names)
    for group in entry.parameter_sets:
        assert set(group) <= set(entry.names)
    fields = {f.name: f for f in dataclasses.fields(entry.law)}
    for p in entry.parameters:
        assert p.meaning and "|" not in p.meaning, p.name
        assert p.unit in UNITS, (p.name, p.unit)
        assert p.allowed
        if p.default is not None and p.name in fields:  # the documented default is the law's
            assert fields[p.name].default == p.default, p.name
        if p.default is None and not any(p.name in group for group in entry.parameter_sets):
            assert p.name in fields and fields[p.name].default is dataclasses.MISSING or p.applies, p.name


def valid(name: str, key: str) -> dict:
    """Parameters of law ``name`` that build, and that contain ``key`` (in the set it belongs to)."""
    lame = {"E": 1.0e3, "nu": 0.3} if key in ("E", "nu") else {"mu": 1.0e3, "lmbda": 1.0e3}
    if name in ("stvk", "neo_hookean", "corotated", "fixed_corotated", "stable_neo_hookean"):
        return lame
    if name in ("muscle", "tendon"):
        return {"isotropic": "stvk", **lame} if key in ("E", "nu", "mu", "lmbda") else {}
    if name in ("holzapfel_ogden", "trans_iso_mooney_rivlin", "blemker"):  # every parameter has a default
        return {}
    return {"mooney_rivlin": {"c1": 1.0, "c2": 1.0, "K": 1.0}, "shape_target": {"mu": 1.0},
            "volume": {"kappa": 1.0}, "arap": {"mu": 1.0}, "yeoh": {"c1": 1.0, "kappa": 1.0},
            "ogden": {"c1": 1.0, "m1": 2.0, "kappa": 1.0}}[name]


#: values that break a bound given in words (relative to another parameter)
BREAK_CONSTRAINT = {"lmbda": -1.0e3, "l_star": 0.9, "lam_max": 0.9, **{f"m{p}": 0.0 for p in range(1, 7)}}


def cases() -> list[tuple[str, str]]:
    return [(name, p.name) for name in BUILT_IN for p in forms.REGISTRY[name].parameters]


@pytest.mark.parametrize("name,key", cases())
def test_documented_range_is_the_enforced_range(name: str, key: str) -> None:
    entry = forms.REGISTRY[name]
    p = entry.parameter(key)
    base = valid(name, key)
    law_params = {**base}

    def refused(value: object, fragment: str) -> None:
        with pytest.raises(forms.ParameterError) as info:
            entry.make(**{**law_params, key: value})
        message = str(info.value)
        assert message.startswith(f"{name}: {key} = "), message
        assert fragment in message, (fragment, message)

    entry.make(**law_params)
    if p.choices:
        refused("rubber", p.allowed)
        return
    if p.constraint:
        refused(BREAK_CONSTRAINT[key], p.constraint)
    if p.lower is not None:
        refused(p.lower if p.lower_open else p.lower - 1.0, p.interval)
        if not p.lower_open and not (name == "mooney_rivlin" and key == "c1"):  # c1 = c2 = 0 is no law
            entry.make(**{**law_params, key: p.lower})
    if p.upper is not None:
        refused(p.upper if p.upper_open else p.upper + 1.0, p.interval)
    refused(float("nan"), "finite")
    refused(-inf, "finite")
    if p.infinite:
        assert entry.make(**{**law_params, key: inf}).incompressible
    else:
        refused(inf, "finite")


@pytest.mark.parametrize("params,fragment", [
    ({"E": 1.0, "nu": 0.5}, "nu = 0.5, must be in (-1, 0.5)"),
    ({"E": 1.0, "nu": -1.0}, "(-1, 0.5)"),
    ({"E": -1.0, "nu": 0.3}, "E = -1.0, must be > 0"),
    ({"E": inf, "nu": 0.3}, "E = inf, must be a finite number"),
    ({"youngs": 1.0}, "unknown parameter 'youngs' (allowed: E, nu, mu, lmbda)"),
    ({"E": 1.0}, "nu is missing"),
    ({"E": 1.0, "nu": 0.3, "mu": 1.0, "lmbda": 1.0}, "give either (E, nu) or (mu, lmbda), not both"),
    ({}, "give either (E, nu) or (mu, lmbda)"),
])
def test_old_messages_stay(params: dict, fragment: str) -> None:
    """The messages tests/test_config_errors.py relies on."""
    with pytest.raises(forms.ParameterError) as info:
        forms.make_law("neo_hookean", **params)
    assert str(info.value).startswith("neo_hookean: ") and fragment in str(info.value)


def test_markdown_reference() -> None:
    text = forms.laws_markdown()
    assert text == forms.laws_markdown()  # deterministic
    assert text.startswith("## Laws and their parameters\n")
    assert text.count("| parameter | meaning | unit | default | allowed |") == len(BUILT_IN)
    for name in BUILT_IN:
        entry = forms.REGISTRY[name]
        assert f"### `{name}`" in text and f"    psi = {entry.formula}" in text
        for p in entry.parameters:
            assert f"| `{p.name}` |" in text
    assert "| `nu` | Poisson's ratio | dimensionless | required (with E) | in (-1, 0.5) |" in text
    assert "| `lmbda` | first Lame parameter" in text and "> -2 mu / 3, or inf (incompressible)" in text
    assert "| `sigma_max` | maximum isometric fibre stress | Pa (stress) | 3e5 | >= 0 |" in text
    assert "Fields: `a0`, unit fibre direction" in text
    user = forms.resolve_law("guccione_law.py:psi", base=EXAMPLES)
    more = forms.laws_markdown([user], level=3)
    assert more.startswith("### Laws and their parameters\n") and "#### `guccione_law.py:psi`" in more
    assert "| `C` | stiffness scale | Pa (stress) | 2000 | > 0 |" in more
    assert "| `kappa` | bulk penalty of the volumetric term (kappa/2) g(F)^2 | Pa (stress) | 0 | >= 0, or inf " in more


# --- user laws ----------------------------------------------------------------------------------------

def test_guccione_entry() -> None:
    entry = forms.resolve_law("guccione_law.py:psi", base=EXAMPLES)
    assert entry is forms.resolve_law("guccione_law.py:psi", base=EXAMPLES)  # imported once
    assert entry is not forms.resolve_law(str(EXAMPLES / "guccione_law.py") + ":psi")  # named as written
    assert entry.name == "guccione_law.py:psi" and entry.fields == ("a0",)
    assert entry.defaults == {"C": 2000.0, "bf": 8.0, "bt": 2.0, "bfs": 4.0, "kappa": 0.0}
    assert entry.bulk_parameter == "kappa" and entry.volume_constraint == "J - 1"
    law = entry.make(C=2.0, kappa=1e3, a0=ufl.as_vector([1.0, 0.0, 0.0]))
    assert law.parameters() == {"C": 2.0, "bf": 8.0, "bt": 2.0, "bfs": 4.0, "kappa": 1e3}
    assert dataclasses.replace(law, a0=None).a0 is None and law.name == "guccione_law.py:psi"


@pytest.mark.parametrize("params,message", [
    ({"C": -1.0}, "guccione_law.py:psi: C = -1.0, must be > 0"),
    ({"C": 0.0}, "guccione_law.py:psi: C = 0.0, must be > 0"),
    ({"bf": -2.0}, "guccione_law.py:psi: bf = -2.0, must be >= 0"),
    ({"C": inf}, "guccione_law.py:psi: C = inf, must be a finite number"),
    ({"C": "2e3"}, "guccione_law.py:psi: C = '2e3', must be a finite number"),
    ({"kappa": -1.0}, "guccione_law.py:psi: kappa = -1.0, must be >= 0"),
    ({"Cf": 1.0}, "guccione_law.py:psi: unknown parameter 'Cf' (allowed: C, bf, bt, bfs, kappa, a0)"),
])
def test_guccione_parameters_are_validated(params: dict, message: str) -> None:
    entry = forms.resolve_law("guccione_law.py:psi", base=EXAMPLES)
    with pytest.raises(forms.ParameterError) as info:
        entry.make(**params)
    assert str(info.value) == message


def write(tmp_path: Path, text: str, name: str = "law.py") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_required_parameter_and_fields(tmp_path: Path) -> None:
    write(tmp_path, "import ufl\nFIELDS = ('alpha',)\nVOLUMETRIC = 'ln J'\nPARAMETERS = {'c': {'bounds': (0, 1), "
                    "'exclusive': (True, False)}}\n"
                    "def psi(F, *, c, alpha=None):\n    return c * alpha * (ufl.tr(F.T * F) - 3)\n")
    entry = forms.resolve_law("law.py:psi", base=tmp_path)
    assert entry.parameter("c").required and entry.parameter("c").allowed == "in (0, 1]"
    assert entry.volume_constraint == "ln J" and entry.make(c=1.0).logarithmic
    with pytest.raises(forms.ParameterError, match=r"^law.py:psi: c is missing$"):
        entry.make(alpha=ufl.as_ufl(0.5))
    with pytest.raises(forms.ParameterError, match=r"^law.py:psi: c = 0, must be in \(0, 1\]$"):
        entry.make(c=0)
    law = entry.make(c=0.5)
    with pytest.raises(ValueError, match="the field alpha .* is required"):
        law.reduced_energy(ufl.Identity(3))


@pytest.mark.parametrize("text,fragment", [
    ("def psi(F, C=1.0):\n    return C\n", "argument 'C' must be keyword-only"),
    ("def psi(F, *, kappa=1.0):\n    return kappa\n", "'kappa' is reserved"),
    ("def psi(F, *, a0=None):\n    return 1.0\n", "argument 'a0' is a field: list it in FIELDS"),
    ("FIELDS = ('b',)\ndef psi(F, *, b=None):\n    return 1.0\n", "FIELDS lists 'b'"),
    ("FIELDS = ('a0',)\ndef psi(F):\n    return 1.0\n", "the function must take it"),
    ("PARAMETERS = {'D': {}}\ndef psi(F, *, C=1.0):\n    return C\n", "PARAMETERS names 'D'"),
    ("PARAMETERS = {'C': {'units': 'Pa'}}\ndef psi(F, *, C=1.0):\n    return C\n", "unknown key 'units'"),
    ("PARAMETERS = {'C': {'bounds': (0, None)}}\ndef psi(F, *, C=-1.0):\n    return C\n", "C = -1.0, must be >= 0"),
    ("def psi(F, *, C='a'):\n    return C\n", "the default of 'C' must be a finite number"),
    ("VOLUMETRIC = 'J^2'\ndef psi(F):\n    return 1.0\n", "VOLUMETRIC = 'J^2', must be one of"),
    ("def psi(F):\n    return F\n", "must return a scalar UFL expression of F, got shape (3, 3)"),
    ("import numpy\ndef psi(F):\n    return numpy.linalg.det(F)\n", "calling the function with a UFL F failed"),
    ("def other(F):\n    return 1.0\n", "has no function 'psi'"),
    ("import not_a_module\n", "importing"),
])
def test_contract_violations_are_named(tmp_path: Path, text: str, fragment: str) -> None:
    write(tmp_path, text, "bad.py")
    with pytest.raises(forms.ParameterError) as info:
        forms.resolve_law("bad.py:psi", base=tmp_path)
    assert str(info.value).startswith("bad.py:psi: ") and fragment in str(info.value), str(info.value)


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(forms.ParameterError, match="^nowhere.py:psi: no such file: "):
        forms.resolve_law("nowhere.py:psi", base=tmp_path)


# --- the Guccione law at the constitutive level ----------------------------------------------------------

class Evaluator:
    """psi and P = dpsi/dF of a law at N deformation gradients (one disjoint tetrahedron each, DG0 F and a0)."""

    def __init__(self, law: forms.Law, n: int) -> None:
        reference_tet = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
        cells = np.arange(4 * n, dtype=np.int64).reshape(n, 4)
        self.mesh = compat.create_mesh(MPI.COMM_SELF, cells, np.tile(reference_tet, (n, 1)))
        self.order = np.asarray(self.mesh.topology.original_cell_index, dtype=np.int64)
        self.n = n
        self.F = fem.Function(compat.function_space(self.mesh, "DG", 0, (3, 3)))
        self.a0 = fem.Function(compat.function_space(self.mesh, "DG", 0, (3,)))
        law = dataclasses.replace(law, a0=self.a0)
        Fv = ufl.variable(self.F)
        points = compat.quadrature_points(self.mesh, 1)
        self.psi = fem.Expression(law.energy(Fv), points)
        self.P = fem.Expression(law.stress(Fv), points)

    def __call__(self, F: np.ndarray, a0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        self.F.x.array[:] = np.asarray(F).reshape(self.n, 9)[self.order].reshape(-1)
        self.a0.x.array[:] = np.asarray(a0).reshape(self.n, 3)[self.order].reshape(-1)
        inverse = np.empty_like(self.order)
        inverse[self.order] = np.arange(self.n)
        cells = np.arange(self.n, dtype=np.int32)
        psi = compat.evaluate(self.psi, self.mesh, cells).reshape(self.n)[inverse]
        P = compat.evaluate(self.P, self.mesh, cells).reshape(self.n, 3, 3)[inverse]
        return psi, P


def samples(n: int, seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    F = np.eye(3) + 0.25 * rng.uniform(-1.0, 1.0, (n, 3, 3))
    assert np.all(np.linalg.det(F) > 0.2)
    a0 = rng.normal(size=(n, 3))
    return F, a0 / np.linalg.norm(a0, axis=1)[:, None]


def land_guccione(F: np.ndarray, f: np.ndarray, C: float, bf: float, bt: float, bfs: float,
                  rng: np.random.Generator) -> np.ndarray:
    """Land et al. 2015's W = (C/2)(exp(Q) - 1) with E in an explicit frame (f, s, n), s and n random."""
    out = []
    for Fi, fi in zip(F, f):
        s = np.cross(fi, rng.normal(size=3))
        s /= np.linalg.norm(s)
        frame = np.column_stack([fi, s, np.cross(fi, s)])
        E = frame.T @ (0.5 * (Fi.T @ Fi - np.eye(3))) @ frame
        Q = (bf * E[0, 0] ** 2 + bt * (E[1, 1] ** 2 + E[2, 2] ** 2 + 2 * E[1, 2] ** 2)
             + 2 * bfs * (E[0, 1] ** 2 + E[0, 2] ** 2))
        out.append(0.5 * C * (math.exp(Q) - 1.0))
    return np.array(out)


def test_guccione_is_land_2015_in_any_cross_fibre_frame() -> None:
    entry = forms.resolve_law("guccione_law.py:psi", base=EXAMPLES)
    params = {"C": 2000.0, "bf": 8.0, "bt": 2.0, "bfs": 4.0}
    F, a0 = samples(12)
    psi, _ = Evaluator(entry.make(**params), len(F))(F, a0)
    np.testing.assert_allclose(psi, land_guccione(F, a0, **params, rng=np.random.default_rng(5)), rtol=1e-12)
    rotation = Rotation.random(random_state=4).as_matrix()  # objectivity: W(Q F) = W(F)
    psi_rotated, _ = Evaluator(entry.make(**params), len(F))(rotation @ F, a0)
    np.testing.assert_allclose(psi_rotated, psi, rtol=1e-12)


@pytest.mark.parametrize("kappa", [0.0, 5.0e3])
def test_guccione_stress_is_the_derivative_of_psi(kappa: float) -> None:
    """P from UFL against central differences of psi (kappa > 0: with the volumetric term (kappa/2)(J - 1)^2)."""
    entry = forms.resolve_law("guccione_law.py:psi", base=EXAMPLES)
    F, a0 = samples(6, seed=11)
    n, h = len(F), 1e-6
    evaluate = Evaluator(entry.make(kappa=kappa), 18 * n)
    perturbed = np.repeat(F[:, None], 18, axis=1)  # per sample: +h e_ij then -h e_ij, 9 each
    for ij in range(9):
        perturbed[:, ij, ij // 3, ij % 3] += h
        perturbed[:, 9 + ij, ij // 3, ij % 3] -= h
    psi, _ = evaluate(perturbed.reshape(-1, 3, 3), np.repeat(a0, 18, axis=0))
    psi = psi.reshape(n, 18)
    fd = ((psi[:, :9] - psi[:, 9:]) / (2 * h)).reshape(n, 3, 3)
    _, P = Evaluator(entry.make(kappa=kappa), n)(F, a0)
    error = np.abs(P - fd).max() / np.abs(P).max()
    print(f"Guccione, kappa = {kappa}: max |P - FD| / max |P| = {error:.1e} (h = {h})")
    assert error < 1e-7
