"""``check``: a user's psi, P and/or tangent against the reference of a law, as a Python API (for a
user's own test suite) and from a file (``verify check FILE``).

Per quantity and sample n (report.py): abs = ||user_n - ref_n||_F, rel = abs / max(||ref_n||_F, floor),
floor = 1e-6 max_m ||ref_m||_F over the compared samples. Left out, with a count per reason:
samples where the reference is not finite (psi, P or A NaN/inf, e.g. ln J at det F <= 0) from every
quantity, samples where the law says the tangent is undefined (Law.tangent_undefined) from A, and
samples where it says P itself is undefined (Law.stress_undefined: a rotation law where the polar
rotation is not unique, psi has a kink there) from the stresses.
With ``projected`` the user's tangent is compared with the PSD projection of the reference (the 9x9
matrix A[(i,j),(k,l)] with its negative eigenvalues set to 0, forms.projection.project_tangent).

Layouts (model.verify.layouts): the reference is converted into the user's layout and measures, and
compared there (an error in the user's stress never leaks into their tangent): the tangent in
``layout`` (ijkl, hessian9-col, hessian9-row, voigt-spatial, abaqus-ddsdde, voigt-material), each
stress the user gives in its own measure (P, PK2 = S, sigma; 3x3 or Voigt 6). Samples where the
conversion itself may lose more than rtol/10 (``layouts.conversion_accuracy``: dS/dE at nearly flat F,
eps cond(F)^3) are left out of that quantity, with a count.

Hints: a constant factor (user = c ref over all samples, c = <u, r> / <r, r>, when
||u - c r|| <= 10 rtol ||u||), a transposed P (user_n = ref_n^T within rtol), and otherwise what
``layouts.hints`` finds: another layout, measure, Voigt order or index permutation that matches.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

import forms
from forms.metadata import FIELD_SHAPES
from forms.projection import project_tangent
from model.verify import diagnosis, files, layouts
from model.verify.evaluator import SHAPES, ReferenceEvaluator
from model.verify.report import CheckRow, Report

Arrays = dict[str, np.ndarray]
NOT_FINITE = "reference not finite there (psi, P or A is NaN/inf, e.g. ln J at det F <= 0)"
UNDEFINED = ("tangent undefined there (a breakpoint of the law, or a polar rotation that is not unique: "
             "Law.tangent_undefined)")
STRESS_UNDEFINED = ("stress undefined there (psi has a kink: the polar rotation is not unique, "
                    "Law.stress_undefined)")
LOSSY = "the conversion to this layout loses more than rtol/10 there (layouts.conversion_accuracy)"
#: the quantities of a check in the order of the report: the energy, the stresses (file keys), the tangent
QUANTITIES = ("psi", "P", "PK2", "sigma", "A")
#: the stress measure of each stress key (model.verify.files.STRESS_KEYS inverted)
MEASURE = {key: measure for measure, key in files.STRESS_KEYS.items()}


def compare(user: Arrays, ref: Arrays, rtol: float, *, exclude: dict[str, list[tuple[str, np.ndarray]]] | None = None,
            labels: list[str] | None = None, worst: int = 3, atol: float = 0.0,
            modulus: float | None = None) -> list[CheckRow]:
    """Per-sample Frobenius errors of every quantity the user gave (module docstring).

    With ``modulus`` M (check's: the law's largest |A_ijkl(I)|): rel_n = |u_n - r_n| / max(|r_n|, M), and
    sample n agrees when |u_n - r_n| <= rtol max(|r_n|, M) + atol; the worst samples are those with the
    largest |u_n - r_n| / (rtol max(|r_n|, M) + atol). Without it, the floor is 1e-6 max_m |r_m| and atol 0.
    ``exclude``: {quantity: [(reason, (N,) bool mask), ...]}, samples left out of that quantity (a
    sample is counted under its first reason). Reference samples that are not finite are always left out.
    """
    rows = []
    for q in QUANTITIES:
        if q not in user:
            continue
        n = len(ref[q])
        r = np.asarray(ref[q], dtype=np.float64).reshape(n, -1)
        u = np.asarray(user[q], dtype=np.float64)
        if u.size != r.size:
            raise ValueError(f"{q}: shape {u.shape} does not match the reference {np.shape(ref[q])}")
        u = u.reshape(n, -1)
        keep = np.ones(n, dtype=bool)
        excluded: list[tuple[str, int]] = []
        reasons = [(NOT_FINITE, ~np.all(np.isfinite(r), axis=1)), *(exclude or {}).get(q, [])]
        for reason, mask in reasons:
            mask = np.asarray(mask, dtype=bool) & keep
            if mask.any():
                excluded.append((reason, int(mask.sum())))
                keep &= ~mask
        index = np.flatnonzero(keep)
        err = np.linalg.norm(u[index] - r[index], axis=1)
        norm = np.linalg.norm(r[index], axis=1)
        floor = modulus if modulus is not None else 1e-6 * max(float(norm.max(initial=0.0)), 1e-300)
        scale = np.maximum(norm, floor)
        rel = err / scale
        rel[~np.isfinite(rel)] = np.inf
        err[~np.isfinite(err)] = np.inf
        score = err / (rtol * scale + (atol if modulus is not None else 0.0))
        score[~np.isfinite(score)] = np.inf
        ranked = np.argsort(-score, kind="stable")
        order = index[ranked]
        failing = index[ranked[score[ranked] > 1.0]]
        per_kind: list[tuple[str, float]] = []
        if labels is not None:
            kinds: dict[str, float] = {}
            for m, value in zip(index, rel):
                kinds[labels[m]] = max(kinds.get(labels[m], 0.0), float(value))
            per_kind = list(kinds.items())
        rows.append(CheckRow(q, float(err.max(initial=0.0)), float(rel.max(initial=0.0)),
                             int(order[0]) if len(order) else -1, bool(np.all(score <= 1.0)),
                             tuple(int(m) for m in failing[:worst]), len(index), tuple(excluded), tuple(per_kind)))
    return rows


def _as_samples(name: str, values: Any, n: int, shape: tuple[int, ...]) -> np.ndarray:
    """``values`` as (n, *shape) float64, or ValueError naming the array and both shapes."""
    array = np.asarray(values, dtype=np.float64)
    size = int(np.prod(shape, dtype=int))
    if array.size != n * size or (array.ndim > 1 and array.shape[0] != n):
        raise ValueError(f"{name}: shape {array.shape} does not match {n} samples of F; expected {(n, *shape)}")
    return array.reshape(n, *shape)


def _require_layout_of_matrix(layout: str, tangent: Any) -> None:
    """ValueError when a tangent of (N, 9, 9) or (N, 6, 6) is to be read as ijkl: a 9x9 Hessian is row-major
    or column-major in vec(F) and a 6x6 matrix one of three Voigt tangents, and reading either as
    A[i,j,k,l] would silently pick one (the 9x9 as row-major vec(F), HOBAK's column-major then fails at
    relative error ~1 for no visible reason). The user names the layout instead."""
    shape = tuple(np.shape(tangent)[1:])
    if layout != "ijkl" or shape not in ((9, 9), (6, 6)):
        return
    choices = [name for name in layouts.TANGENT_LAYOUTS if layouts.TANGENT_SHAPES[name] == shape]
    described = ", ".join(f"{name} ({layouts.LAYOUT_SHORT[name]})" for name in choices)
    usual = "; HOBAK and Dynamic Deformables write hessian9-col" if shape == (9, 9) else ""
    raise ValueError(f"tangent: shape {np.shape(tangent)} is a {shape[0]}x{shape[1]} matrix per sample, not ijkl's "
                     f"(N, 3, 3, 3, 3): give its layout (--layout or layout=), one of {described}{usual}")


def _fields(material: str, fields: dict[str, Any] | None, n: int) -> Arrays:
    """The law's fields per sample (a single value is used for every sample); ValueError naming the field."""
    wanted = forms.resolve_law(material).fields
    given = dict(fields or {})
    for name in given:
        if name not in wanted:
            raise ValueError(f"field {name!r}: {material} does not take it (its fields: {', '.join(wanted) or 'none'})")
    out = {}
    for name in wanted:
        if name not in given:
            raise ValueError(f"{material} needs the field {name!r} ({forms.FIELD_MEANINGS[name]})")
        shape = FIELD_SHAPES[name]
        value = np.asarray(given[name], dtype=np.float64)
        if value.shape == shape:
            value = np.broadcast_to(value, (n, *shape))
        out[name] = _as_samples(name, value, n, shape)
    return out


def check(F: Any, *, psi: Any = None, P: Any = None, tangent: Any = None, law: str | None = None,
          params: dict[str, Any] | None = None, fields: dict[str, Any] | None = None, layout: str = "ijkl",
          rtol: float = 1e-8, labels: list[str] | None = None, projected: bool = False, PK2: Any = None,
          sigma: Any = None, atol: float = 0.0) -> Report:
    """Compare a user's psi (N,), stresses and/or tangent at F (N,3,3) with the reference of ``law`` (a
    built-in name or "FILE.py:FUNCTION") with ``params`` and ``fields`` (per sample, or one value for all).

    Stresses: P (N,3,3) the first Piola-Kirchhoff stress, PK2 = S = F^-1 P the second, sigma = P F^T / J
    the Cauchy stress (PK2 and sigma as (N,3,3) or Voigt (N,6), order 11, 22, 33, 12, 13, 23). The
    tangent in ``layout`` (model.verify.layouts; ijkl: A (N,3,3,3,3), A[n,i,j,k,l] = dP_ij/dF_kl).
    Sample n of a quantity agrees when |yours_n - ref_n| <= rtol max(|ref_n|, M) + atol (Frobenius norms;
    M the law's modulus, the largest |A_ijkl| at F = I: model.verify.diagnosis). Returns a Report (``.ok``,
    ``.raise_if_failed()``, ``.diagnoses``, ``str``); ValueError for bad input. Given a file path instead
    of F (and no law), checks that file (``check_file``).
    """
    if isinstance(F, (str, Path)) and law is None:
        return check_file(Path(F), rtol=rtol, params=params, layout=None if layout == "ijkl" else layout,
                          projected=projected, atol=atol)
    if law is None:
        raise ValueError("check: law is required (a built-in law's name or FILE.py:FUNCTION)")
    if not (isinstance(rtol, (int, float)) and math.isfinite(rtol) and rtol > 0):
        raise ValueError(f"rtol = {rtol!r}, must be a finite number > 0")
    if isinstance(atol, bool) or not (isinstance(atol, (int, float)) and math.isfinite(atol) and atol >= 0):
        raise ValueError(f"atol = {atol!r}, must be a finite number >= 0")
    if layout not in layouts.TANGENT_LAYOUTS:
        raise ValueError(f"layout {layout!r}: unknown (choose from {', '.join(layouts.TANGENT_LAYOUTS)})")
    if projected and layout in layouts.VOIGT_LAYOUTS:
        raise ValueError(f"projected: the PSD projection is that of the 9x9 Hessian; layout {layout} is not one "
                         "(use ijkl, hessian9-col or hessian9-row)")
    F = np.asarray(F, dtype=np.float64)
    if F.size == 0 or F.size % 9:
        raise ValueError(f"F: shape {F.shape}, expected (N, 3, 3)")
    F = F.reshape(-1, 3, 3)
    n = len(F)
    if labels is not None:
        labels = [str(x) for x in np.asarray(labels).reshape(-1)]
        if len(labels) != n:
            raise ValueError(f"labels: {len(labels)} given for {n} samples of F")
    sample_fields = _fields(law, fields, n)
    user: Arrays = {}
    if psi is not None:
        user["psi"] = _as_samples("psi", psi, n, SHAPES["psi"])
    if P is not None:
        user["P"] = _as_samples("P", P, n, SHAPES["P"])
    for key, value in (("PK2", PK2), ("sigma", sigma)):
        if value is not None:
            voigt = np.asarray(value).ndim == 2 and np.shape(value)[-1] == 6
            user[key] = _as_samples(key, value, n, (6,) if voigt else (3, 3))
    if tangent is not None:
        _require_layout_of_matrix(layout, tangent)
        user["A"] = _as_samples(f"tangent ({layout})", tangent, n, layouts.TANGENT_SHAPES[layout])
    if not user:
        raise ValueError("none of psi, P, PK2, sigma, tangent to check")
    evaluator = ReferenceEvaluator(law, dict(params or {}), n)
    values = evaluator.evaluate(F, **sample_fields)
    A_ref = values["A"]
    if projected and "A" in user:
        finite = np.all(np.isfinite(A_ref.reshape(n, -1)), axis=1)
        A_ref = np.full_like(A_ref, np.nan)
        A_ref[finite] = project_tangent(values["A"][finite])
    with np.errstate(all="ignore"):  # singular F: the conversions give inf/nan there, left out as not finite
        ref = _in_layout(layout, F, values["psi"], values["P"], A_ref, user)
        accuracy = layouts.conversion_accuracy(layout, F)
        lossy_S = layouts.conversion_accuracy(layout, F, "S")["stress"] > rtol / 10
    exclude: dict[str, list[tuple[str, np.ndarray]]] = {}
    kink = evaluator.stress_undefined(F, **sample_fields)
    for key in ("P", "PK2", "sigma"):
        if key in user:
            exclude[key] = [(STRESS_UNDEFINED, kink)]
    if "A" in user:
        exclude["A"] = [(UNDEFINED, evaluator.tangent_undefined(F, **sample_fields)),
                        (LOSSY, accuracy["tangent"] > rtol / 10)]
    if "PK2" in user:
        exclude["PK2"].append((LOSSY, lossy_S))
    M = modulus(evaluator, n, sample_fields)
    rows = compare(user, ref, rtol, exclude=exclude, labels=labels, atol=atol, modulus=M)
    compared = {q: _compared_mask(ref[q], exclude.get(q, [])) for q in user}
    a0 = sample_fields.get("a0")
    features = diagnosis.sample_features(F, a0)
    params_numeric = {k: float(v) for k, v in evaluator.parameters().items()
                      if isinstance(v, (int, float)) and not isinstance(v, bool)}
    at_transpose: Arrays | None = None
    term_values: dict[str, np.ndarray] = {}
    term_names: list[str] = []
    diagnoses: list[diagnosis.Diagnosis] = []
    quantities: dict[str, diagnosis.Quantity] = {}
    details: list[str] = []
    label = (lambda m: labels[m]) if labels is not None else (lambda m: "")  # noqa: E731
    for row in rows:
        if row.ok:
            continue
        q, keep = row.quantity, compared[row.quantity]
        scale = np.maximum(np.linalg.norm(np.reshape(ref[q], (n, -1)), axis=1), M)
        quantity = diagnosis.Quantity(q, np.asarray(user[q], dtype=np.float64), np.asarray(ref[q], dtype=np.float64),
                                      keep, rtol * scale + atol, convert=_converter(q, layout, F, user),
                                      family="psi" if q == "psi" else ("A" if q == "A" else "P"))
        identity = np.flatnonzero(features["identity"] & keep)
        if len(identity):
            details.append(diagnosis.detail(quantity, int(identity[0]), label(int(identity[0])), features,
                                            "the identity"))
        if row.worst_sample >= 0 and (not len(identity) or row.worst_sample != identity[0]):
            details.append(diagnosis.detail(quantity, row.worst_sample, label(row.worst_sample), features,
                                            "the worst sample"))
        if at_transpose is None:
            Ft = np.ascontiguousarray(np.transpose(F, (0, 2, 1)))
            with np.errstate(all="ignore"):
                tv = evaluator.evaluate(Ft, **sample_fields)
                at_transpose = _in_layout(layout, Ft, tv["psi"], tv["P"], tv["A"], user)
                at_transpose["P_ijkl"] = tv["P"]

        def layout_hints(index: np.ndarray | None, q: str = q, keep: np.ndarray = keep) -> list[str]:
            if q == "psi":
                return []
            keep = keep & np.all(np.isfinite(values["P"].reshape(n, -1)), axis=1)
            if index is not None:  # the layout search on the screened samples only (diagnosis.SCREEN)
                keep = keep & np.isin(np.arange(n), index)
            keep &= np.all(np.isfinite(A_ref.reshape(n, -1)), axis=1)
            with np.errstate(all="ignore"):
                return layouts.hints(layout, F[keep], values["P"][keep], A_ref[keep],
                                     user_tangent=user[q][keep] if q == "A" else None,
                                     user_stress=user[q][keep] if q != "A" else None, measure=MEASURE.get(q))

        def law_terms(index: np.ndarray | None,
                      quantity: diagnosis.Quantity = quantity) -> list[tuple[str, np.ndarray]]:
            if not term_names:
                term_names.extend(evaluator.energy_terms() or ["none"])
                if term_names != ["none"]:
                    with np.errstate(all="ignore"):
                        term_values.update(evaluator.evaluate_terms(F, **sample_fields))
            if not term_values or projected:
                return []
            values = term_values[quantity.family]
            if index is not None:
                values = values[index]
            out = []
            for k, name in enumerate(term_names):
                T = values[:, k]
                with np.errstate(all="ignore"):
                    out.append((name, quantity.convert(T, index) if quantity.convert is not None else T))
            return out

        quantities[q] = quantity
        diagnoses += diagnosis.diagnose(quantity, F, params_numeric, features, at_transpose.get(q), layout_hints,
                                        law_terms)
    diagnoses = _parameter_diagnosis(diagnoses, quantities, law, dict(params or {}), F, sample_fields, layout, user,
                                     projected)
    notes = []
    for row in rows:
        if row.quantity != "psi" and not row.compared:
            notes.append(f"no sample left to compare {row.quantity}")
    any_compared = np.zeros(n, dtype=bool)
    for mask in compared.values():
        any_compared |= mask
    return Report(rows, rtol, law, F, labels, [d.text for d in diagnoses], notes, projected and "A" in user, layout,
                  diagnoses=diagnoses, details=details, atol=atol, modulus=M,
                  coverage=diagnosis.coverage(F, labels, features, any_compared, a0 is not None))


def _parameter_diagnosis(diagnoses: list[diagnosis.Diagnosis], quantities: dict[str, diagnosis.Quantity], law: str,
                         params: dict[str, Any], F: np.ndarray, fields: Arrays, layout: str, user: Arrays,
                         projected: bool) -> list[diagnosis.Diagnosis]:
    """The parameter hint (diagnosis.parameter_hint) for the failing quantities no cause explains (no hint, or
    only a region), through a second evaluator holding the law's parameters as runtime values; it replaces
    their region hints. Laws whose parameters cannot be held so are left as they are."""
    explained = {d.quantity for d in diagnoses if d.kind != "region"}
    open_ = [quantities[q] for q in quantities if q not in explained]
    if not open_ or projected:
        return diagnoses
    try:
        runtime = ReferenceEvaluator(law, params, len(F), runtime_parameters=True)
    except Exception:  # noqa: BLE001 -- no parameter hint for a law whose numbers UFL cannot hold
        return diagnoses

    def reference_at(values: dict[str, float], index: np.ndarray) -> Arrays:
        runtime.set_parameters(values)
        v = runtime.evaluate(F[index], **{k: f[index] for k, f in fields.items()})
        return _in_layout(layout, F[index], v["psi"], v["P"], v["A"], {k: u[index] for k, u in user.items()})

    own = {name: value for name, (_, value) in runtime.constants.items()}
    hint = diagnosis.parameter_hint(open_, own, reference_at, law)
    if hint is None:
        return diagnoses
    names = {q.name for q in open_}
    return [d for d in diagnoses if d.quantity not in names] + [hint]


def modulus(evaluator: ReferenceEvaluator, n: int, fields: Arrays) -> float | None:
    """M = max |A_ijkl| at F = I over the samples' fields (lambda + 2 mu for an isotropic law): the absolute
    floor of every quantity's norm (psi, stresses and tangents share the unit of stress). None when it is
    0 or not finite (the old floor, 1e-6 of the largest reference norm, then applies)."""
    with np.errstate(all="ignore"):
        A = evaluator.evaluate(np.broadcast_to(np.eye(3), (n, 3, 3)).copy(), **fields)["A"]
    A = np.abs(A[np.isfinite(A)])
    value = float(A.max()) if A.size else 0.0
    return value if value > 0 and math.isfinite(value) else None


def _converter(q: str, layout: str, F: np.ndarray, user: Arrays) -> Any:
    """(term values in P form (n,3,3) or ijkl A form, the samples' indices or None) -> the user's measure /
    layout (linear maps)."""
    if q == "psi":
        return None
    if q == "A":
        return lambda T, index: layouts.from_reference(layout, F if index is None else F[index],
                                                       np.zeros((len(T), 3, 3)), T)["tangent"]
    if q == "P":
        return lambda T, index: T

    def stress(T: np.ndarray, index: np.ndarray | None) -> np.ndarray:
        out = layouts.stress_from_P(MEASURE[q], F if index is None else F[index], T)
        return layouts.to_voigt(out) if user[q].shape[1:] == (6,) else out
    return stress


def _in_layout(layout: str, F: np.ndarray, psi: np.ndarray, P: np.ndarray, A: np.ndarray, user: Arrays) -> Arrays:
    """The reference quantities the user gave, in the user's layout, measures and shapes (3x3 or Voigt)."""
    ref: Arrays = {"psi": psi}
    for key in ("P", "PK2", "sigma"):
        if key in user:
            stress = layouts.stress_from_P(MEASURE[key], F, P)
            ref[key] = layouts.to_voigt(stress) if user[key].shape[1:] == (6,) else stress
    if "A" in user:
        ref["A"] = layouts.from_reference(layout, F, P, A)["tangent"]
    return ref


def _compared_mask(ref: np.ndarray, exclude: list[tuple[str, np.ndarray]]) -> np.ndarray:
    keep = np.all(np.isfinite(np.reshape(ref, (len(ref), -1))), axis=1)
    for _, mask in exclude:
        keep &= ~np.asarray(mask, dtype=bool)
    return keep


def _params_from_file(path: Path, content: Arrays) -> dict[str, Any] | None:
    """The file's params_json as a dict, or None; ValueError naming the file and the key otherwise."""
    if "params_json" not in content:
        return None
    text = str(content["params_json"])
    try:
        params = json.loads(text)
    except json.JSONDecodeError as err:
        raise ValueError(f"{path}: params_json is not valid JSON ({err.msg} at column {err.colno}: {text[:60]!r})") \
            from None
    if not isinstance(params, dict):
        raise ValueError(f"{path}: params_json must be a JSON object {{\"key\": value, ...}}, got {text[:60]!r}")
    for key, value in params.items():
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            raise ValueError(f"{path}: params_json key {key!r} = {value!r}, must be a number or a string")
    return params


def merge_parameters(path: Path, file_params: dict[str, Any] | None, given: dict[str, Any] | None) -> dict[str, Any]:
    """The file's parameters completed by ``given`` (--param); a key in both with different values is an error."""
    merged = dict(file_params or {})
    for key, value in (given or {}).items():
        if key in merged and merged[key] != value:
            raise ValueError(f"{path}: --param {key}={value!r} conflicts with the file's params_json "
                             f"{key} = {merged[key]!r}")
        merged[key] = value
    return merged


def load_for_check(path: Path, *, material: str | None = None, params: dict[str, Any] | None = None,
                   layout: str | None = None) -> tuple[str, dict[str, Any], np.ndarray, Arrays, Arrays,
                                                       list[str] | None, str]:
    """(material, params, F, fields, user quantities, labels, layout) from a file (model.verify.files:
    .npz, a directory of .npy, .csv, .json); the material and parameters may come from the caller when
    the file has none (module check_file); the layout is the file's, else ``layout``, else ijkl (both
    given and different: an error)."""
    content = files.read_arrays(path, layout)
    file_material = str(content["material"]) if "material" in content else None
    if material is not None and file_material is not None and material != file_material:
        raise ValueError(f"{path}: --material {material} conflicts with the file's material {file_material}")
    material = material or file_material
    if material is None:
        raise ValueError(f"{path}: no 'material' in the file: give --material NAME or --energy FILE.py:NAME")
    params = merge_parameters(path, _params_from_file(path, content), params)
    F = content["F"]
    wanted = forms.resolve_law(material).fields
    fields = {k: content[k] for k in wanted if k in content}
    user = {q: content[q] for q in QUANTITIES if q in content}
    if not user:
        raise ValueError(f"{path}: none of psi, P, PK2, sigma, A to check")
    labels = [str(x) for x in content["labels"].reshape(-1)] if "labels" in content else None
    return material, params, F, fields, user, labels, str(content.get("layout") or "ijkl")


def check_file(path: Path, rtol: float = 1e-8, *, material: str | None = None, params: dict[str, Any] | None = None,
               layout: str | None = None, projected: bool = False, atol: float = 0.0) -> Report:
    """Recompute the reference for the file's F and fields and compare what it holds.

    The law is the file's ``material`` and ``params_json``; ``material`` (--material/--energy) and
    ``params`` (--param) supply them when the file has none and complete them otherwise: a
    different material or a parameter given in both with different values is an error. The tangent's
    layout is the file's ``layout``, else ``layout`` (--layout), else ijkl.
    """
    material, params, F, fields, user, labels, layout = load_for_check(path, material=material, params=params,
                                                                       layout=layout)
    try:
        return check(F, psi=user.get("psi"), P=user.get("P"), PK2=user.get("PK2"), sigma=user.get("sigma"),
                     tangent=user.get("A"), law=material, params=params, fields=fields, layout=layout, rtol=rtol,
                     labels=labels, projected=projected, atol=atol)
    except ValueError as err:
        if isinstance(err, forms.ParameterError):
            raise
        raise ValueError(f"{path}: {err}") from None
