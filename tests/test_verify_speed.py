"""ReferenceEvaluator in chunks: a mesh of at most CHUNK cells, evaluate looping over chunks of any number
of samples (the last one padded with F = I). Chunked values must equal those of one chunk holding every
sample (the same compiled kernels on the same inputs; 1e-14 relative to each quantity's largest value),
for a plain law, a polar law (PolarField refreshed per chunk, inverted samples included) and a law with
fields (muscle: a0, alpha), at any number of samples, and be the same on every rank (the evaluator is
on MPI.COMM_SELF)."""

from __future__ import annotations

import hashlib
from typing import Any

import numpy as np
import pytest
from mpi4py import MPI

from model.verify import evaluator
from model.verify.evaluator import QUANTITIES, ReferenceEvaluator
from model.verify.samples import deformation_samples, field_samples

LAWS: dict[str, dict[str, Any]] = {
    "neo_hookean": {"mu": 3.0, "lmbda": 7.0},
    "corotated": {"mu": 1.0, "lmbda": 0.0},
    "muscle": {},
}
N = 10


def samples(material: str, n: int = N, seed: int = 5) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """n samples of F (with det F < 0 for the polar law) and the law's fields."""
    F, _ = deformation_samples(n, seed, inverted=material == "corotated")
    return F, field_samples(material, n, seed)


def assert_same(chunked: dict[str, np.ndarray], whole: dict[str, np.ndarray]) -> None:
    for q in QUANTITIES:
        assert chunked[q].shape == whole[q].shape, q
        scale = max(float(np.max(np.abs(whole[q]))), 1e-300)
        np.testing.assert_allclose(chunked[q], whole[q], rtol=0, atol=1e-14 * scale, err_msg=q)


def same_on_every_rank(values: dict[str, np.ndarray]) -> bool:
    digest = hashlib.sha256(b"".join(np.ascontiguousarray(values[q]).tobytes() for q in QUANTITIES)).hexdigest()
    return len(set(MPI.COMM_WORLD.allgather(digest))) == 1


@pytest.mark.parametrize("material", list(LAWS))
def test_chunks_give_the_values_of_one_chunk(material: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """CHUNK = 3: 10 samples in 4 chunks (the last one 1 sample and 2 of padding) against one chunk of 10."""
    F, fields = samples(material)
    whole = ReferenceEvaluator(material, LAWS[material], N)
    assert whole.chunk == N
    reference = whole.evaluate(F, **fields)
    monkeypatch.setattr(evaluator, "CHUNK", 3)
    chunked = ReferenceEvaluator(material, LAWS[material], N)
    assert chunked.chunk == 3 and chunked.num_samples == N and chunked.material == material
    values = chunked.evaluate(F, **fields)
    assert_same(values, reference)
    assert values["psi"].shape == (N,) and values["P"].shape == (N, 3, 3) and values["A"].shape == (N, 3, 3, 3, 3)
    assert np.all(np.isfinite(values["A"]))
    assert same_on_every_rank(values)


@pytest.mark.parametrize("material", ["corotated", "muscle"])
def test_any_number_of_samples(material: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """An evaluator made for 10 samples evaluates 1, 7, 10 (F transposed) and 0 samples, chunked (CHUNK = 3)
    or not, each sample as in one evaluation of all 10."""
    F, fields = samples(material)
    reference = ReferenceEvaluator(material, LAWS[material], N).evaluate(F, **fields)
    FT = np.transpose(F, (0, 2, 1))
    reference_T = ReferenceEvaluator(material, LAWS[material], N).evaluate(FT, **fields)
    for chunk in (3, 4096):
        monkeypatch.setattr(evaluator, "CHUNK", chunk)
        ev = ReferenceEvaluator(material, LAWS[material], N)
        for rows in (slice(0, 1), slice(2, 9), slice(0, N)):
            part = {name: value[rows] for name, value in fields.items()}
            assert_same(ev.evaluate(F[rows], **part), {q: reference[q][rows] for q in QUANTITIES})
        assert_same(ev.evaluate(FT, **fields), reference_T)
        empty = ev.evaluate(np.zeros((0, 3, 3)), **{name: value[:0] for name, value in fields.items()})
        assert {q: empty[q].shape for q in QUANTITIES} == {"psi": (0,), "P": (0, 3, 3), "A": (0, 3, 3, 3, 3)}
    # a mesh smaller than the samples: an evaluator made for 4 evaluates all 10 in chunks of 4
    monkeypatch.undo()
    small = ReferenceEvaluator(material, LAWS[material], 4)
    assert small.chunk == 4
    assert_same(small.evaluate(F, **fields), reference)


def test_fields_of_the_wrong_size() -> None:
    F, fields = samples("muscle")
    ev = ReferenceEvaluator("muscle", {}, N)
    with pytest.raises(ValueError, match="alpha"):
        ev.evaluate(F, a0=fields["a0"], alpha=fields["alpha"][:-1])
    with pytest.raises(ValueError, match="needs the field a0"):
        ev.evaluate(F, alpha=fields["alpha"])
    # one value of a field's shape is used for every sample
    one = ev.evaluate(F, a0=np.array([1.0, 0.0, 0.0]), alpha=0.5)
    each = ev.evaluate(F, a0=np.tile([1.0, 0.0, 0.0], (N, 1)), alpha=np.full(N, 0.5))
    assert_same(one, each)


def test_renumbered_cells(monkeypatch: pytest.MonkeyPatch) -> None:
    """dolfinx may renumber the cells (the sample of local cell c is original_cell_index[c]; on these meshes it
    keeps them in order): with the samples placed in reversed cells, the values are those of each sample."""
    F, fields = samples("corotated")
    reference = ReferenceEvaluator("corotated", LAWS["corotated"], N).evaluate(F, **fields)
    monkeypatch.setattr(evaluator, "CHUNK", 4)
    ev = ReferenceEvaluator("corotated", LAWS["corotated"], N)
    ev._place_samples(np.arange(ev.chunk)[::-1])
    assert_same(ev.evaluate(F, **fields), reference)
