"""Checkpoints of a run after every completed step, for ``python -m model run CONFIG --restart DIR``.

One file per step, checkpoint_SSSS.npz (SSSS the number of completed steps; written on rank 0), holding
for each saved Function (the solution u or the mixed (u, p); dynamics' u_n, v_n, a_n; contact i's Uzawa
multipliers "multiplier_i") its owned dof values gathered from every rank, each keyed by a description of
the dof that does not depend on the partition:

    (sub-space, component, x, y, z)   x, y, z the dof's coordinates quantized to 1e-9 of the largest extent of
                                      the whole mesh's bounding box (the same number on every partition)

and the scalars (JSON in "meta"): the load factor (dynamics: also the time and the dissipated energy), the
increment the next step takes (the cut-back state), the number of summary steps. Activation and
procedural targets are functions of the load factor (time) and follow from it.

Reading maps the values back by those keys onto the dofs of each rank, so a restart may use another
number of ranks (and partition) than the run it continues, on the same mesh and discretization. A dof's
coordinates are computed from one of its cells, which the partition picks, so they may differ in the last bit:
a key not found exactly is looked up among its 26 neighbours on the quantization grid (1e-9 of the size apart);
a dof found neither way gives a one-line error. Rank 0 holds the whole state while writing and reading (the limit of
this format on large meshes). Writing goes through a temporary name, fsync and os.replace; the
pipeline then rewrites summary.json to name the new checkpoint and only then removes the previous one
(remove_checkpoint): after a kill at any moment the checkpoint summary.json names exists, complete.
"""

from __future__ import annotations

import io
import itertools
import json
import os
import weakref
from pathlib import Path
from typing import Any

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from model.output.writer import discard, named, on_rank0


def checkpoint_name(step: int) -> str:
    return f"checkpoint_{step:04d}.npz"


def dof_keys(space: Any) -> np.ndarray:
    """Per local dof (owned and ghost, the order of Function.x.array): (sub-space, component, x, y, z) as
    floats, x, y, z the dof's coordinates. A blocked (vector) space: sub-space 0 and the block component; a
    mixed space: the sub-space and the component within it."""
    bs = space.dofmap.index_map_bs
    n_local = (space.dofmap.index_map.size_local + space.dofmap.index_map.num_ghosts) * bs
    if bs == 1 and space.num_sub_spaces > 0:  # mixed: per collapsed sub-space
        keys = np.zeros((n_local, 5))
        for i in range(space.num_sub_spaces):
            sub, parent = space.sub(i).collapse()
            sub_keys = dof_keys(sub)
            sub_keys[:, 0] = i
            keys[np.asarray(parent)] = sub_keys
        return keys
    coords = space.tabulate_dof_coordinates()[:, :3]
    nodes = np.repeat(np.arange(coords.shape[0]), bs)
    return np.column_stack([np.zeros(nodes.size), np.tile(np.arange(bs), coords.shape[0]), coords[nodes]])


def _quantize(keys: np.ndarray, scale: float) -> np.ndarray:
    q = keys.copy()
    q[:, 2:] = np.round(keys[:, 2:] / scale)
    return q.astype(np.int64)


#: the quantized keys of the owned dofs of each function space written so far (they do not change in a run)
#: (FunctionSpace is unhashable: keyed by id, with a weak reference that tells a reused id apart)
_OWNED_KEYS: dict[int, tuple[Any, np.ndarray]] = {}


def _owned_keys(space: Any) -> np.ndarray:
    cached = _OWNED_KEYS.get(id(space))
    if cached is not None and cached[0]() is space:
        return cached[1]
    owned = space.dofmap.index_map.size_local * space.dofmap.index_map_bs
    keys = _quantize(dof_keys(space), _scale(space.mesh))[:owned]
    for key in [k for k, (ref, _) in _OWNED_KEYS.items() if ref() is None]:
        del _OWNED_KEYS[key]
    _OWNED_KEYS[id(space)] = (weakref.ref(space), keys)
    return keys


def _scale(msh: Any) -> float:
    """1e-9 of the largest extent of the whole mesh's bounding box (an allreduce of every rank's box: the same
    number on any partition; the largest of the ranks' own extents would depend on how the mesh is cut)."""
    x = msh.geometry.x
    box = np.concatenate([-np.min(x, axis=0, initial=np.inf), np.max(x, axis=0, initial=-np.inf)])
    msh.comm.Allreduce(MPI.IN_PLACE, box, op=MPI.MAX)  # -low, high of the whole mesh
    return 1e-9 * (float(np.max(box[3:] + box[:3])) or 1.0)


def _neighbour(saved: dict[tuple[int, ...], int], key: np.ndarray) -> int:
    """The index of the saved key next to ``key`` on the quantization grid (same sub-space and component,
    coordinates off by at most one quantum each), -1 when there is none."""
    head = tuple(int(k) for k in key[:2])
    for offset in itertools.product((0, -1, 1), repeat=3):
        found = saved.get(head + tuple(int(k + o) for k, o in zip(key[2:], offset)), -1)
        if found >= 0:
            return found
    return -1


def write_checkpoint(directory: Path, step: int, functions: dict[str, fem.Function],
                     meta: dict[str, Any]) -> list[str]:
    """Write checkpoint ``step`` of ``functions`` (collective; rank 0 writes); returns [the file's name] on
    every rank. The previous checkpoint stays until remove_checkpoint (after summary.json names this one)."""
    directory = Path(directory)
    comm = next(iter(functions.values())).function_space.mesh.comm
    arrays: dict[str, np.ndarray] = {}
    for name, f in functions.items():
        space = f.function_space
        owned = space.dofmap.index_map.size_local * space.dofmap.index_map_bs
        parts = comm.gather((_owned_keys(space), f.x.array[:owned].copy()), root=0)
        if comm.rank == 0:
            arrays[f"{name}.keys"] = np.concatenate([p[0] for p in parts])
            arrays[f"{name}.values"] = np.concatenate([p[1] for p in parts])
    name = checkpoint_name(step)

    def write() -> None:
        tmp = directory / (name + ".tmp")
        data = io.BytesIO()  # the zip in memory: a full disk fails the one write below, not the zip file's close
        np.savez(data, meta=np.array(json.dumps(meta)), **arrays)
        try:
            with open(tmp, "wb") as out:
                out.write(data.getbuffer())
                out.flush()
                os.fsync(out.fileno())
            os.replace(tmp, directory / name)
        except OSError as err:  # a full disk: the half-written file goes, the error names it, on every rank
            discard(tmp)
            raise named(err, tmp) from None

    on_rank0(comm, write)
    return [name]


def remove_checkpoint(directory: Path, step: int, comm: MPI.Comm) -> None:
    """Remove checkpoint ``step`` (rank 0; collective), if it exists."""
    if comm.rank == 0:
        try:
            (Path(directory) / checkpoint_name(step)).unlink()
        except FileNotFoundError:
            pass
    comm.barrier()


def read_checkpoint(directory: Path, step: int, functions: dict[str, fem.Function]) -> dict[str, Any]:
    """Set ``functions`` (those of them the checkpoint holds) from checkpoint ``step`` (collective) and return
    its meta data; ValueError (one line) when the file is missing or a dof of this mesh is not in it."""
    path = Path(directory) / checkpoint_name(step)
    comm = next(iter(functions.values())).function_space.mesh.comm
    data, error = None, None
    if comm.rank == 0:
        if not path.is_file():
            error = f"{path} is missing (the restart needs the checkpoint summary.json names)"
        else:
            with np.load(path, allow_pickle=False) as f:
                data = {k: f[k] for k in f.files}
    data, error = comm.bcast((data, error), root=0)
    if error:
        raise ValueError(error)
    meta = json.loads(str(data["meta"]))
    for name, f in functions.items():
        if f"{name}.keys" not in data:
            continue
        space = f.function_space
        keys = _quantize(dof_keys(space), _scale(space.mesh))
        saved = {tuple(k): i for i, k in enumerate(data[f"{name}.keys"].tolist())}
        index = np.array([saved.get(tuple(k), -1) for k in keys.tolist()], dtype=np.int64)
        for i in np.flatnonzero(index < 0):  # the last bit of a coordinate across a rounding boundary
            index[i] = _neighbour(saved, keys[i])
        missing = comm.allreduce(int(np.sum(index < 0)), op=MPI.SUM)
        if missing:
            raise ValueError(f"{path}: {missing} dofs of {name!r} are not in the checkpoint: restart with the "
                             "mesh and discretization of the run it continues")
        f.x.array[:] = data[f"{name}.values"][index]
    return meta
