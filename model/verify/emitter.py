"""``emit``: reference psi, P and A of a law at samples of F (and of its fields), written to a file.

The samples (model.verify.samples) are moved off points where the tangent is undefined (fibre
breakpoints, Law.tangent_undefined) unless ``include_undefined``; samples whose reference is not
finite (psi, P or A NaN/inf: ln J laws at det F < 0 with ``inverted``) are dropped, never written.
The file (model.verify.files: .npz, a directory of .npy, .csv or .json, by the path's suffix) holds F,
psi, P, the tangent A in ``layout`` (model.verify.layouts) with the layout's own stress as well (PK2 for
voigt-material, sigma for voigt-spatial and abaqus-ddsdde, in Voigt form), the law's fields, labels,
material, params_json (defaults included), layout and emit_json (what was moved or dropped).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from mpi4py import MPI

from model.verify import files, layouts
from model.verify.evaluator import ReferenceEvaluator
from model.verify.samples import avoid_undefined, deformation_samples, fibre_breakpoints, field_samples, kind_counts


def emit(material: str, params: dict[str, Any], samples: int, seed: int, out: Path, inverted: bool | None = None, *,
         fields: dict[str, np.ndarray] | None = None, include_undefined: bool = False,
         layout: str = "ijkl") -> dict[str, np.ndarray]:
    """Write exactly ``out`` (see module docstring) and return its arrays.

    ``inverted``: None (the default) draws a quarter of the samples with det F < 0 and, when the reference
    is finite at none of them (a ln J law), draws again without (recorded in emit_json["inverted"]);
    True always keeps them (those not finite are dropped), False never draws them.
    ``fields``: {name: one value} used for every sample instead of the drawn ones (--field).
    ``data["emit_json"]`` records {"requested", "written", "kinds": {label: count}, "moved":
    {reason: count}, "dropped": {reason: count}}.
    """
    if layout not in layouts.TANGENT_LAYOUTS:
        raise ValueError(f"--layout {layout!r}: unknown (choose from {', '.join(layouts.TANGENT_LAYOUTS)})")
    drawn = field_samples(material, samples, seed)
    for name, value in (fields or {}).items():
        if name not in drawn:
            raise ValueError(f"--field {name}: {material} does not take this field")
        drawn[name] = np.array(np.broadcast_to(value, drawn[name].shape))
    evaluator = ReferenceEvaluator(material, params, samples)
    inverted_note = "drawn" if inverted is not False else "not drawn (--no-inverted)"
    if inverted is None and not _finite_when_inverted(evaluator, samples, seed, drawn):
        inverted = False
        inverted_note = "not drawn: the reference is not finite at det F < 0 (e.g. ln J)"
    F, labels = deformation_samples(samples, seed, inverted, drawn.get("S"), at_kinks=include_undefined)
    if inverted is None and not any(label.startswith("inverted_") for label in labels):
        inverted_note = "not drawn: too few samples (none with distinct singular values to invert)"
    moved: dict[str, int] = {}
    dropped: dict[str, int] = {}
    keep = np.ones(samples, dtype=bool)
    if not include_undefined:
        F, labels, counts = avoid_undefined(F, labels, drawn, seed, evaluator.tangent_undefined)
        moved = {k: v for k, v in counts.items() if k != "stuck" and v}
        stuck = fibre_breakpoints(F, drawn) | evaluator.tangent_undefined(F, **drawn)
        if stuck.any():
            dropped["tangent undefined"] = int(stuck.sum())
            keep &= ~stuck
    values = evaluator.evaluate(F, **drawn)
    finite = np.ones(samples, dtype=bool)
    for q in ("psi", "P", "A"):
        finite &= np.all(np.isfinite(values[q].reshape(samples, -1)), axis=1)
    if (~finite & keep).any():
        dropped["reference not finite (e.g. ln J at det F <= 0)"] = int(np.sum(~finite & keep))
        keep &= finite
    if not keep.any():
        raise ValueError(f"{material}: every sample was dropped ({', '.join(f'{k}: {v}' for k, v in dropped.items())})")
    labels = [label for label, k in zip(labels, keep) if k]
    summary = {"requested": samples, "written": int(keep.sum()), "kinds": kind_counts(labels), "moved": moved,
               "dropped": dropped, "inverted": inverted_note}
    converted = layouts.from_reference(layout, F[keep], values["P"][keep], values["A"][keep])
    measure = layouts.NATURAL_STRESS[layout]
    stress = {} if measure == "P" else {files.STRESS_KEYS[measure]: converted["stress"]}
    data = {"F": F[keep], "psi": values["psi"][keep], "P": values["P"][keep], **stress, "A": converted["tangent"],
            "layout": np.array(layout),
            **{k: v[keep] for k, v in drawn.items()}, "labels": np.array(labels), "material": np.array(material),
            "params_json": np.array(json.dumps(evaluator.parameters(), sort_keys=True)),
            "emit_json": np.array(json.dumps(summary))}
    data["path"] = np.array(_write_once(Path(out), data))
    return data


def _finite_when_inverted(evaluator: ReferenceEvaluator, samples: int, seed: int,
                          fields: dict[str, np.ndarray]) -> bool:
    """True when the reference is finite at one or more of the inverted samples deformation_samples draws."""
    F, labels = deformation_samples(samples, seed, None, fields.get("S"))
    inverted = np.array([label.startswith("inverted_") for label in labels])
    with np.errstate(all="ignore"):
        values = evaluator.evaluate(F, **fields)
    finite = np.ones(samples, dtype=bool)
    for q in ("psi", "P", "A"):
        finite &= np.all(np.isfinite(values[q].reshape(samples, -1)), axis=1)
    return bool(np.any(finite & inverted))


def _write_once(out: Path, data: dict[str, np.ndarray]) -> str:
    """Write the file once per distinct path: when every rank names the same ``out`` (every rank computed the
    same arrays), rank 0 writes it and the path, or rank 0's error, reaches every rank (under mpirun every rank
    writing one file left a truncated .npz for a reader); ranks naming paths of their own write their own."""
    comm = MPI.COMM_WORLD
    if len(set(comm.allgather(str(out)))) > 1:
        return str(files.write_arrays(out, data))
    if comm.rank == 0:
        try:
            path = str(files.write_arrays(out, data))
        except Exception as err:
            comm.bcast(("", f"{type(err).__name__}: {err}"), root=0)
            raise
        comm.bcast((path, None), root=0)
        return path
    path, error = comm.bcast(None, root=0)
    if error is not None:
        raise OSError(f"rank 0 could not write {out}: {error}")
    return path


def summary_text(data: dict[str, np.ndarray]) -> str:
    """What emit wrote, for the command line: path, counts per kind, moved and dropped samples."""
    summary = json.loads(str(data["emit_json"]))
    kinds = ", ".join(f"{k} {v}" for k, v in summary["kinds"].items())
    lines = [f"wrote {data['path']}: {summary['written']} of {summary['requested']} samples of {data['material']} "
             f"({data['params_json']})", f"samples per kind: {kinds}"]
    for reason, count in summary["moved"].items():
        what = "a fibre breakpoint (fibre stretch 1)" if reason == "fibre_breakpoint" else \
            "a point where the law's tangent is undefined"
        lines.append(f"moved {count} sample(s) off {what} (labels perturbed_*; --at-breakpoints keeps them)")
    for reason, count in summary["dropped"].items():
        lines.append(f"dropped {count} sample(s): {reason}")
    if "inverted" in summary:
        lines.append(f"inverted samples (det F < 0): {summary['inverted']}")
    return "\n".join(lines)
