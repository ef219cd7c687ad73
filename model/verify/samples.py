"""Samples of F and of the laws' fields for ``verify emit``, away from points where the reference is
undefined.

Deformation kinds (``deformation_samples``): the identity (once: no sample is drawn twice); pure
rotations; repeated singular values (uniaxial (a, b, b), isotropic (a, a, a)); large stretches
(singular values in [0.3, 3]); nearly flat elements (smallest singular value 1e-4 to 1e-2); random F
near I; and, unless ``inverted=False``, a quarter with det F < 0 (F times a reflection).

Fields (``field_samples``) are made for every field the law takes, generically over
forms.metadata.FIELD_SHAPES: S symmetric positive definite, a0 and s0 unit vectors (s0 orthogonal
to a0), alpha in [0, 1].

Where the tangent is undefined (``avoid_undefined``): a fibre law's curves break at the fibre
stretch 1, and the identity, every rotation and every isotropic stretch c R has

    lambda = |F d| = 1 (rotations)   or   lbar = |F d| |J|^(-1/3) = 1 (all three)

for every unit direction field d (a0, s0). Such samples are moved off by a stretch along the
directions, F <- F (I + e1 a0 a0^T + e2 s0 s0^T), |e| in [0.01, 0.05], so that |lambda - 1| and
|lbar - 1| exceed ``BREAKPOINT_MARGIN``; samples where the law itself says A is undefined
(Law.tangent_undefined) are moved by F <- F (I + 0.02 G), G a random matrix of unit entries' scale.
The label of a moved sample gets the prefix ``perturbed_``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.spatial.transform import Rotation

from forms.metadata import FIELD_SHAPES
from model.verify.evaluator import law_fields

#: fibre stretches closer to 1 than this (relative) count as on the breakpoint: wider than round-off so
#: that a user's branch test (lbar > 1) decides as the reference does.
BREAKPOINT_MARGIN = 1e-4
#: the fields that are unit directions (normalised when given with --field)
DIRECTIONS = tuple(name for name, shape in FIELD_SHAPES.items() if shape == (3,))
KINDS = ("identity", "rotation", "uniaxial", "isotropic", "large_stretch", "nearly_flat", "random")
PERTURBED = "perturbed_"


def _rotations(rng: np.random.Generator, n: int) -> np.ndarray:
    return Rotation.random(n, random_state=rng.integers(2**31)).as_matrix() if n else np.zeros((0, 3, 3))


def _from_singular_values(rng: np.random.Generator, sigma: np.ndarray) -> np.ndarray:
    return _rotations(rng, len(sigma)) @ (sigma[:, :, None] * np.eye(3)) @ _rotations(rng, len(sigma))


def deformation_samples(n: int, seed: int, inverted: bool | None = None,
                        targets: np.ndarray | None = None, at_kinks: bool = False) -> tuple[np.ndarray, list[str]]:
    """n deformation gradients covering the hard cases, and a label for each (module docstring).

    The first sample is the identity, the others cycle through the other kinds. With ``inverted``
    (None, the default: when some sample can be inverted, see below; True: ValueError when none can; a law
    whose reference is not finite at det F < 0, ln J, has those samples left out of a check with a count),
    a quarter of them get det F < 0 (F times a reflection), chosen among samples
    where the two smallest singular values of the matrix whose rotation the law uses (F D, or F D S
    with the shape targets ``targets``) differ by more than 5%: for det < 0 the rotation variant of
    the polar decomposition has no derivative where they coincide (K = tr(Sigma) I - Sigma is
    singular, the nearest rotation is not unique). With ``at_kinks`` as well (emit --inverted
    --at-breakpoints) half of that quarter (at least one) is chosen where they do coincide (the identity,
    rotations, isotropic and uniaxial (a, b, b), a > b, stretches), labelled ``inverted_..._kink``.
    """
    if n < 1:
        raise ValueError("--samples must be >= 1")
    rng = np.random.default_rng(seed)
    kind = np.concatenate([[0], 1 + np.arange(n - 1) % (len(KINDS) - 1)])  # the identity once, then cycling
    labels = [KINDS[k] for k in kind]
    F = np.empty((n, 3, 3))
    at = {name: np.flatnonzero(kind == k) for k, name in enumerate(KINDS)}  # each kind drawn as one array
    F[at["identity"]] = np.eye(3)
    i = at["rotation"]
    F[i] = _rotations(rng, len(i))
    i = at["uniaxial"]
    ab = rng.uniform(0.5, 2.0, (len(i), 2))
    F[i] = _from_singular_values(rng, ab[:, [0, 1, 1]])
    i = at["isotropic"]
    F[i] = rng.uniform(0.6, 1.6, len(i))[:, None, None] * _rotations(rng, len(i))
    i = at["large_stretch"]
    F[i] = _from_singular_values(rng, rng.uniform(0.3, 3.0, (len(i), 3)))
    i = at["nearly_flat"]
    sigma = np.column_stack([rng.uniform(0.8, 1.5, len(i)), rng.uniform(0.8, 1.5, len(i)),
                             10 ** rng.uniform(-4, -2, len(i))])
    F[i] = _from_singular_values(rng, sigma)
    i = at["random"]
    G = np.eye(3) + 0.3 * rng.standard_normal((len(i), 3, 3))
    negative = np.linalg.det(G) <= 0
    G[negative] = G[negative] @ np.diag([1.0, 1.0, -1.0])
    F[i] = G
    if inverted is not False:
        reflection = np.diag([1.0, 1.0, -1.0])
        M = F @ reflection if targets is None else F @ reflection @ targets
        sigma = np.linalg.svd(M, compute_uv=False)
        distinct = np.flatnonzero(sigma[:, 1] - sigma[:, 2] > 0.05 * sigma[:, 1])
        if len(distinct) == 0 and inverted is None:  # too few samples (the identity, a rotation, ...): none
            return F, labels
        if len(distinct) == 0:
            raise ValueError("--inverted needs more samples (none with distinct singular values)")
        count = max(1, n // 4)
        kinks = np.zeros(0, dtype=int)
        if at_kinks:
            repeated = np.flatnonzero(sigma[:, 1] - sigma[:, 2] <= 1e-12 * sigma[:, 1])
            kinks = rng.permutation(repeated)[: max(1, count // 2)]
        flip = np.concatenate([kinks, rng.permutation(distinct)[: count - len(kinks)]])
        F[flip] = F[flip] @ reflection
        is_kink = set(kinks.tolist())
        for i in flip:
            labels[i] = f"inverted_{labels[i]}" + ("_kink" if i in is_kink else "")
    return F, labels


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def field_samples(material: str, n: int, seed: int) -> dict[str, np.ndarray]:
    """Per-sample fields of a law, one generator per name of FIELD_SHAPES: S symmetric positive definite
    (identity, repeated and distinct eigenvalues); a0 unit fibre directions (axis-aligned and random);
    s0 unit sheet directions orthogonal to a0; alpha in [0, 1] (0, 1 and between)."""
    rng = np.random.default_rng(seed + 7919)
    wanted = law_fields(material)
    out: dict[str, np.ndarray] = {}
    if "a0" in wanted:
        a0 = rng.standard_normal((n, 3))
        a0[0::4] = [1.0, 0.0, 0.0]
        out["a0"] = _unit(a0)
    if "alpha" in wanted:
        alpha = rng.uniform(0.0, 1.0, n)
        alpha[0::3], alpha[1::3] = 0.0, 1.0
        out["alpha"] = alpha
    if "S" in wanted:
        eig = rng.uniform(0.5, 2.0, (n, 3))
        eig[0::3] = 1.0  # identity targets
        eig[1::3, 1] = eig[1::3, 2]  # repeated eigenvalues
        Q = _rotations(rng, n)
        out["S"] = Q @ (eig[:, :, None] * np.eye(3)) @ np.transpose(Q, (0, 2, 1))
    if "s0" in wanted:
        s0 = rng.standard_normal((n, 3))
        s0[0::4] = [0.0, 1.0, 0.0]
        if "a0" in out:  # orthogonal to the fibre
            s0 = s0 - np.sum(s0 * out["a0"], axis=1)[:, None] * out["a0"]
        out["s0"] = _unit(s0)
    for name in wanted:  # a field FIELD_SHAPES gained later: random values of its shape
        if name not in out:
            out[name] = rng.uniform(0.5, 1.5, (n, *FIELD_SHAPES[name]))
    return out


def parse_field(material: str, text: str) -> tuple[str, np.ndarray]:
    """``--field NAME=VALUE`` for every sample: S=identity or 9 numbers (row by row), a0=1,0,0 (unit
    directions are normalised), alpha=0.5. ValueError naming the field otherwise."""
    name, sep, value = text.partition("=")
    name, value = name.strip(), value.strip()
    wanted = law_fields(material)
    if not sep or not name:
        raise ValueError(f"--field {text!r}: write NAME=VALUE (e.g. a0=1,0,0, S=identity, alpha=0.5)")
    if name not in wanted:
        takes = ", ".join(wanted) if wanted else "none"
        raise ValueError(f"--field {name}: {material} does not take this field (its fields: {takes})")
    shape = FIELD_SHAPES[name]
    if value == "identity" and shape == (3, 3):
        array = np.eye(3)
    else:
        try:
            numbers = [float(x) for x in value.split(",")]
        except ValueError:
            raise ValueError(f"--field {name}: {value!r} is not a comma-separated list of numbers") from None
        size = int(np.prod(shape, dtype=int))
        if len(numbers) != size or not np.all(np.isfinite(numbers)):
            raise ValueError(f"--field {name}: {len(numbers)} value(s) given, {name} takes {size} finite number(s) "
                             f"(shape {shape})")
        array = np.reshape(numbers, shape)
    if name in DIRECTIONS:
        if np.linalg.norm(array) == 0:
            raise ValueError(f"--field {name}: a direction must not be zero")
        array = array / np.linalg.norm(array)
    if name == "S":
        from forms.shape_target import check_shape_targets

        check_shape_targets(array, "--field S")
    return name, array


def fibre_breakpoints(F: np.ndarray, fields: dict[str, np.ndarray], margin: float = BREAKPOINT_MARGIN) -> np.ndarray:
    """(N,) bool: lambda = |F d| or lbar = |F d| |det F|^(-1/3) within ``margin`` of 1 for a direction field d."""
    F = np.reshape(F, (-1, 3, 3))
    near = np.zeros(len(F), dtype=bool)
    J = np.abs(np.linalg.det(F))
    for name in DIRECTIONS:
        if name not in fields:
            continue
        d = np.broadcast_to(fields[name], (len(F), 3))
        stretch = np.linalg.norm(np.einsum("nij,nj->ni", F, d), axis=1)
        lbar = stretch / np.cbrt(np.maximum(J, 1e-300))
        near |= (np.abs(stretch - 1.0) < margin) | (np.abs(lbar - 1.0) < margin)
    return near


def avoid_undefined(F: np.ndarray, labels: list[str], fields: dict[str, np.ndarray], seed: int,
                    undefined: Callable[..., np.ndarray] | None = None,
                    rounds: int = 50) -> tuple[np.ndarray, list[str], dict[str, int]]:
    """Move samples off fibre breakpoints and off points the law declares undefined (module docstring).

    Returns (F, labels, counts) with counts {"fibre_breakpoint": moved, "tangent_undefined": moved,
    "stuck": still undefined after ``rounds`` attempts}.
    """
    rng = np.random.default_rng(seed + 104729)
    F = np.array(F, dtype=np.float64, copy=True)
    labels = list(labels)
    n = len(F)
    counts = {"fibre_breakpoint": 0, "tangent_undefined": 0, "stuck": 0}
    directions = {k: np.broadcast_to(fields[k], (n, 3)) for k in DIRECTIONS if k in fields}
    moved = np.zeros(n, dtype=bool)
    for _ in range(rounds):  # every sample near a breakpoint moved at once
        near = np.flatnonzero(fibre_breakpoints(F, directions))
        if not len(near):
            break
        counts["fibre_breakpoint"] += int(np.sum(~moved[near]))
        moved[near] = True
        stretch = np.broadcast_to(np.eye(3), (len(near), 3, 3)).copy()
        for d in directions.values():
            e = rng.uniform(0.01, 0.05, len(near)) * rng.choice([-1.0, 1.0], len(near))
            stretch += e[:, None, None] * np.einsum("ni,nj->nij", d[near], d[near])
        F[near] = F[near] @ stretch
    if undefined is not None:
        for _ in range(rounds):
            bad = np.flatnonzero(np.asarray(undefined(F, **fields), dtype=bool))
            if not len(bad):
                break
            counts["tangent_undefined"] += int(np.sum(~moved[bad]))
            moved[bad] = True
            F[bad] = F[bad] @ (np.eye(3) + 0.02 * rng.standard_normal((len(bad), 3, 3)))
        counts["stuck"] = int(np.sum(undefined(F, **fields)))
    counts["stuck"] += int(np.sum(fibre_breakpoints(F, directions)))
    for i in np.flatnonzero(moved):
        labels[i] = PERTURBED + labels[i]
    return F, labels, counts


def kind_counts(labels: list[str] | np.ndarray) -> dict[str, int]:
    """{label: number of samples} in order of first appearance."""
    counts: dict[str, int] = {}
    for label in labels:
        counts[str(label)] = counts.get(str(label), 0) + 1
    return counts
