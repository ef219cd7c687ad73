"""Results to compare across Debian releases (dolfinx 0.5.2 on Debian 12, 0.9 on Debian 13).

    python tests/release_data.py INPUTS OUT

Runs, on this machine's dolfinx, five configurations (uniaxial, Cook's membrane Taylor-Hood, the
isometric contraction on its coarsest mesh, the contact block, shape-target bending) and the
``verify`` reference (psi, P, A) of every law, and writes OUT/summaries/NAME.json and
OUT/verify/LAW.npz. ``tests/test_releases.py`` compares two such OUT folders.

Both legs must compute from the same inputs, so the first leg to run writes them into INPUTS and
the other reads them: every mesh as a gmsh file (the gmsh versions of the two releases mesh the
fusiform muscle differently) and the verify samples F and fields (scipy's random rotations may
differ between releases). Nothing in INPUTS or OUT is edited by hand.
"""

from __future__ import annotations

import copy
import json
import sys
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
from mpi4py import MPI

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks"), str(ROOT / "tests")]

#: law -> parameters for the verify references (defaults fill the rest)
VERIFY_PARAMS: dict[str, dict[str, Any]] = {
    "stvk": {"E": 1e4, "nu": 0.3}, "neo_hookean": {"E": 1e4, "nu": 0.3},
    "mooney_rivlin": {"c1": 1500.0, "c2": 400.0, "K": 8000.0}, "corotated": {"E": 1e4, "nu": 0.3},
    "shape_target": {"mu": 1e3, "kappa": 1e4}, "volume": {"kappa": 1e4}, "muscle": {}, "tendon": {},
    "fixed_corotated": {"E": 1e4, "nu": 0.3}, "arap": {"mu": 1e3},
    "stable_neo_hookean": {"E": 1e4, "nu": 0.3, "variant": "paper"}, "yeoh": {"c1": 1500.0, "c2": -50.0, "kappa": 1e4},
    "ogden": {"c1": 2000.0, "m1": 4.0, "c2": 300.0, "m2": -2.0, "kappa": 1e4},
    "holzapfel_ogden": {}, "trans_iso_mooney_rivlin": {}, "blemker": {},
}
VERIFY_SAMPLES = 40


def _example(name: str) -> dict[str, Any]:
    return tomllib.loads((ROOT / "examples" / f"{name}.toml").read_text())


def configurations() -> dict[str, dict[str, Any]]:
    """The configurations compared across releases (outputs other than summary.json switched off)."""
    from shape_targeting import configuration as bending

    isometric = _example("isometric")
    isometric["mesh"]["size"] = 0.006  # the coarsest mesh of benchmarks/isometric.py
    out = {"uniaxial": _example("uniaxial"), "cook": _example("cook"), "isometric": isometric,
           "contact_block": _example("contact_block"), "bending": bending((16, 4, 4), 4)}
    for raw in out.values():
        raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    return out


def _mesh_file(name: str, raw: dict[str, Any], inputs: Path, comm: MPI.Comm) -> Path:
    """The mesh of a configuration as a gmsh file in INPUTS, generated here when the file is absent."""
    import meshes

    path = inputs / "meshes" / f"{name}.msh"
    if comm.rank == 0 and not path.exists():
        params = {k: v for k, v in raw["mesh"].items() if k != "generator"}
        path.parent.mkdir(parents=True, exist_ok=True)
        meshes.write_msh(meshes.generate(raw["mesh"]["generator"], **params), path)
    comm.barrier()
    return path


def run_configurations(inputs: Path, out: Path, comm: MPI.Comm) -> None:
    from model.config import parse
    from model.pipeline import run

    for name, raw in configurations().items():
        raw = copy.deepcopy(raw)
        raw["mesh"] = {"file": str(_mesh_file(name, raw, inputs, comm))}
        summary = run(parse(raw, ROOT / "examples"), out / "runs" / name, comm)
        if comm.rank == 0:
            (out / "summaries").mkdir(parents=True, exist_ok=True)
            (out / "summaries" / f"{name}.json").write_text(json.dumps(summary, indent=1))


def verify_references(inputs: Path, out: Path, comm: MPI.Comm) -> None:
    """psi, P, A of every law at the samples of INPUTS/verify/LAW.npz (written here when absent)."""
    import forms
    from model.verify import ReferenceEvaluator, deformation_samples, field_samples

    if comm.rank != 0:
        return
    (inputs / "verify").mkdir(parents=True, exist_ok=True)
    (out / "verify").mkdir(parents=True, exist_ok=True)
    for law in sorted(forms.LAWS):
        sample_file = inputs / "verify" / f"{law}.npz"
        if not sample_file.exists():
            fields = field_samples(law, VERIFY_SAMPLES, 11)
            F, _ = deformation_samples(VERIFY_SAMPLES, 11, inverted=False, targets=fields.get("S"))
            np.savez(sample_file, F=F, **fields)
        samples = dict(np.load(sample_file))
        F = samples.pop("F")
        values = ReferenceEvaluator(law, VERIFY_PARAMS[law], len(F)).evaluate(F, **samples)
        np.savez(out / "verify" / f"{law}.npz", F=F, **values)


def main(argv: list[str]) -> int:
    import logging

    from model import compat

    logging.root.handlers[:] = [logging.StreamHandler()]  # the JIT's compiler lines (INFO) stay quiet
    logging.root.handlers[0].setLevel(logging.WARNING)
    inputs, out = Path(argv[0]).resolve(), Path(argv[1]).resolve()
    comm = MPI.COMM_WORLD
    if comm.rank == 0:
        out.mkdir(parents=True, exist_ok=True)
        inputs.mkdir(parents=True, exist_ok=True)
    comm.barrier()
    run_configurations(inputs, out, comm)
    verify_references(inputs, out, comm)
    if comm.rank == 0:
        (out / "versions.json").write_text(json.dumps(compat.versions(), indent=1))
        print(f"release data in {out} ({compat.versions()['dolfinx']})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
