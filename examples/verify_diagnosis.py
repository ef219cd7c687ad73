"""One planted bug per kind of verify's diagnosis, as files `softtissue verify check` reads.

    .venv/bin/python examples/verify_diagnosis.py              # writes results/verify_diagnosis/KIND.npz
    softtissue verify check results/verify_diagnosis/term.npz  # the report, with its hint

Each file holds the samples F of ``deformation_samples(28, seed=5)`` (inverted ones included), the law
(material, params_json), the fields and your quantities computed by the numpy formulas below with one bug
planted. docs/verify.md shows the reports; tests/test_verify_diagnosis.py checks that they still read so.

    stvk:         psi = mu E:E + (lmbda/2)(tr E)^2,  P = F S,  S = lmbda tr(E) I + 2 mu E,
                  A_ijkl = delta_ik S_lj + lmbda F_ij F_kl + mu F_il F_kj + mu (F F^T)_ik delta_jl
    neo_hookean:  psi = (mu/2)(I1 - 3) - mu ln J + (lmbda/2)(ln J)^2,  P = mu (F - F^-T) + lmbda ln J F^-T,
                  A = mu delta_ik delta_jl - (mu - lmbda ln J) d(F^-T)/dF + lmbda F^-T x F^-T
    corotated:    psi = mu |F - R|^2 + (lmbda/2)(J - 1)^2,  P = 2 mu (F - R) + lmbda (J - 1) J F^-T
                  (R the rotation of F's polar decomposition, det R = +1 also at det F < 0)
    fibre:        examples/fibre_neo_hookean_law.py: neo_hookean + k1/(2 k2)(exp(k2 (I4 - 1)^2) - 1),
                  P = neo_hookean's + 2 k1 (I4 - 1) exp(k2 (I4 - 1)^2) F a0 a0^T,  I4 = |F a0|^2
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
MU, LMBDA, K1, K2 = 3.0, 7.0, 2.0, 0.1
FIBRE_LAW = f"{HERE / 'fibre_neo_hookean_law.py'}:psi"
SAMPLES, SEED = 28, 5
EYE = np.eye(3)


def _t(x: np.ndarray) -> np.ndarray:
    return np.transpose(x, (0, 2, 1))


def stvk(F: np.ndarray, mu: float = MU, lmbda: float = LMBDA) -> dict[str, np.ndarray]:
    E = 0.5 * (_t(F) @ F - EYE)
    trE = np.trace(E, axis1=1, axis2=2)
    S = lmbda * trE[:, None, None] * EYE + 2 * mu * E
    A = (np.einsum("ik,nlj->nijkl", EYE, S) + lmbda * np.einsum("nij,nkl->nijkl", F, F)
         + mu * np.einsum("nil,nkj->nijkl", F, F) + mu * np.einsum("nik,jl->nijkl", F @ _t(F), EYE))
    return {"psi": mu * np.einsum("nij,nij->n", E, E) + 0.5 * lmbda * trE**2, "P": F @ S, "A": A}


def neo_hookean(F: np.ndarray, mu: float = MU, lmbda: float = LMBDA) -> dict[str, np.ndarray]:
    with np.errstate(all="ignore"):
        lnJ = np.log(np.linalg.det(F))
    Fi = np.linalg.inv(F)
    FiT = _t(Fi)
    dT = -np.einsum("nli,njk->nijkl", Fi, Fi)
    A = (mu * np.einsum("ik,jl->ijkl", EYE, EYE)[None] - (mu - lmbda * lnJ)[:, None, None, None, None] * dT
         + lmbda * np.einsum("nij,nkl->nijkl", FiT, FiT))
    return {"psi": 0.5 * mu * (np.einsum("nij,nij->n", F, F) - 3) - mu * lnJ + 0.5 * lmbda * lnJ**2,
            "P": mu * (F - FiT) + lmbda * lnJ[:, None, None] * FiT, "A": A}


def rotation(F: np.ndarray, signed: bool = True) -> np.ndarray:
    """R = U V^T of F = U Sigma V^T; ``signed``: U's last column times det(U V^T), so that det R = +1."""
    U, _, Vt = np.linalg.svd(F)
    if signed:
        U = U.copy()
        U[:, :, 2] *= np.sign(np.linalg.det(U @ Vt))[:, None]
    return U @ Vt


def corotated(F: np.ndarray, signed: bool = True) -> dict[str, np.ndarray]:
    R = rotation(F, signed)
    J = np.linalg.det(F)
    FiT = _t(np.linalg.inv(F))
    return {"psi": MU * np.einsum("nij,nij->n", F - R, F - R) + 0.5 * LMBDA * (J - 1) ** 2,
            "P": 2 * MU * (F - R) + (LMBDA * (J - 1) * J)[:, None, None] * FiT}


def fibre(F: np.ndarray, a0: np.ndarray) -> dict[str, np.ndarray]:
    out = neo_hookean(F)
    Fa = np.einsum("nij,nj->ni", F, a0)
    g = np.einsum("ni,ni->n", Fa, Fa) - 1
    e = np.exp(K2 * g**2)
    return {"psi": out["psi"] + K1 / (2 * K2) * (e - 1),
            "P": out["P"] + (2 * K1 * g * e)[:, None, None] * np.einsum("ni,nj->nij", Fa, a0)}


def _hessian9(A: np.ndarray, column_major: bool) -> np.ndarray:
    """A[i,j,k,l] as the 9x9 Hessian in vec(F), row-major (index 3 i + j) or column-major (i + 3 j)."""
    return (A.transpose(0, 2, 1, 4, 3) if column_major else A).reshape(-1, 9, 9)


#: kind -> (law, params, what the bug is, yours(F, a0) -> {quantity: values}, extra keys of the file)
CASES: dict[str, tuple[str, dict[str, float], str, Callable[..., dict[str, np.ndarray]], dict[str, str]]] = {
    "zero": ("stvk", {"mu": MU, "lmbda": LMBDA}, "P not written (zeros)",
             lambda F, a0: {"psi": stvk(F)["psi"], "P": 0 * F}, {}),
    "offset": ("stvk", {"mu": MU, "lmbda": LMBDA}, "psi + 0.5 (an energy defined up to a constant)",
               lambda F, a0: {"psi": stvk(F)["psi"] + 0.5, "P": stvk(F)["P"]}, {}),
    "factor": ("stvk", {"mu": MU, "lmbda": LMBDA}, "psi, P and A twice the reference (mu and lmbda doubled)",
               lambda F, a0: {k: 2 * v for k, v in stvk(F).items()}, {}),
    "transpose": ("neo_hookean", {"mu": MU, "lmbda": LMBDA}, "P written transposed",
                  lambda F, a0: {"P": _t(neo_hookean(F)["P"])}, {}),
    "layout": ("stvk", {"mu": MU, "lmbda": LMBDA}, "a column-major Hessian declared hessian9-row",
               lambda F, a0: {"A": _hessian9(stvk(F)["A"], column_major=True)}, {"layout": "hessian9-row"}),
    "column_major": (FIBRE_LAW, {"mu": MU, "lmbda": LMBDA, "k1": K1, "k2": K2},
                     "F read column-major (the formulas evaluated at F^T)",
                     lambda F, a0: fibre(_t(F), a0), {}),
    "term": ("neo_hookean", {"mu": MU, "lmbda": LMBDA}, "the tangent without its lmbda F^-T x F^-T",
             lambda F, a0: {"A": neo_hookean(F)["A"]
                            - LMBDA * np.einsum("nij,nkl->nijkl", _t(np.linalg.inv(F)), _t(np.linalg.inv(F)))},
             {}),
    "parameter": ("neo_hookean", {"mu": MU, "lmbda": LMBDA}, "P and A with mu 10 % too large",
                  lambda F, a0: {k: v for k, v in neo_hookean(F, mu=1.1 * MU).items() if k != "psi"}, {}),
    "region": ("corotated", {"mu": MU, "lmbda": LMBDA}, "the rotation from an SVD without the sign correction",
               lambda F, a0: corotated(F, signed=False), {}),
}


def write_cases(out: Path) -> dict[str, Path]:
    """Write out/KIND.npz for every kind of CASES; {kind: path}."""
    from model.verify import deformation_samples, field_samples

    out.mkdir(parents=True, exist_ok=True)
    F, labels = deformation_samples(SAMPLES, SEED)
    written = {}
    for kind, (law, params, _, yours, extra) in CASES.items():
        fields = field_samples(law, SAMPLES, SEED)
        a0 = fields.get("a0")
        with np.errstate(all="ignore"):
            values = yours(F, a0)
        path = out / f"{kind}.npz"
        np.savez(path, F=F, labels=np.array(labels), material=np.array(law), params_json=np.array(json.dumps(params)),
                 **fields, **values, **{k: np.array(v) for k, v in extra.items()})
        written[kind] = path
    return written


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("results/verify_diagnosis"))
    args = parser.parse_args()
    for kind, path in write_cases(args.out).items():
        print(f"{kind:13} {CASES[kind][2]:60} softtissue verify check {path}")


if __name__ == "__main__":
    main()
