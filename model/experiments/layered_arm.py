"""The layered arm segment against the conforming one (issue 14 item 3).

    conforming, layered = compare_arms(size=0.012, turn_elements=8)

Both runs are examples/arm_segment.toml's loading: two fusiform muscles in a fat cylinder, every end face clamped,
muscle a activated to 1 and muscle b to 0.3 (ramped with the load factor), the thesis' materials (muscle E 9 MPa,
tendon 15 MPa, fat 1 MPa, nu 0.45, StVK isotropic part), P1. The conforming run meshes the three bodies as one
(meshes.arm_segment: the muscles are glued to the fat); the layered run cuts the same mesh open along the
muscle-fat interfaces (meshes.layered_arm, same nodes) and couples the bodies by [[contact]] pairs between
bodies (model.problem.body_contact), as examples/layered_arm.toml:

    fat_cavity_a slides on a_lateral, fat_cavity_b on b_lateral   (zero-length normal springs, k_sliding)
    a_lateral against b_lateral                                    (frictionless contact, penalty k_contact,
                                                                    augmented Lagrangian)

Measured (:class:`ArmResult`, the same on every rank): the bulge, i.e. the radial displacement
u_r = u . (X, Y) / |(X, Y)| of the skin nodes in the middle fifth of the segment (|Z - L/2| <= L/10), its max and
mean; the skin's displacement at every skin node (both meshes have the same skin nodes); the slip of the fat on
each muscle, |u_fat - u_muscle| between the two copies of each interface node (zero by construction when glued);
and per contact pair its report (force on the slave body, penetration, gap, active points) and the smallest
gap between the muscles.

The elbow flexion (examples/layered_arm_flexion.toml; :func:`flexion_config`, :func:`compare_flexion`): the same
arms on two capsule bones. The humerus, a stationary capsule of radius 10 mm, lies behind the segment, parallel to
it, 1 mm behind the skin (axis y = -41 mm, from z = -2 cm to the elbow at z = L); the forearm, a capsule from the
elbow along +z, turns about the elbow axis (the x axis through the humerus' distal end point) by ``angle`` degrees
forward (rotation about -x), ramped with the load factor t, while the muscles' activations rise with t (a to 1, b to
0.3). The segment's proximal face (the muscles' origins and the fat's proximal face) is attached to the humerus,
its distal face (the insertions and the fat's distal face) to the forearm: u = Q(t) X + c(t) - X. The skin is in
frictionless penalty contact with the humerus (nodal rule). Measured as above, except that the bulge is the
radial part of the mid-length skin nodes' displacement relative to their mean (the bending's translation of the
section taken out), plus the humerus' contact (force on the arm, penetration, active nodes) and the reactions of
the attached faces (each body's equilibrium).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from mpi4py import MPI

from model.config import RunConfig, parse
from model.problem import ElasticityProblem

log = logging.getLogger(__name__)

__all__ = ["GAP_MESH", "PAIRS", "TOUCHING_PAIRS", "ArmResult", "arm_config", "arm_raw", "compare_arms",
           "compare_flexion", "flexion_bones", "flexion_config", "flexion_raw", "gap_raw", "run_arm", "run_flexion",
           "run_gap", "run_touching_flexion", "skin_difference", "body_balance", "touching_flexion_raw",
           "TOUCHING_FLEXION"]

#: The segment's length (meshes.arm_segment's default; the bulge band is its middle fifth).
LENGTH = 0.12
#: The contact pairs of the layered arm with touching muscles (layered_arm's touching = true): the fat slides on
#: each muscle's round surface, the muscles' flat faces are in contact.
TOUCHING_PAIRS = (("fat_on_a", "fat_cavity_a", "a_round", "sliding"),
                  ("fat_on_b", "fat_cavity_b", "b_round", "sliding"),
                  ("a_on_b", "a_flat", "b_flat", "contact"))
#: The contact pairs of the layered arm: (name, slave, master, kind).
PAIRS = (("fat_on_a", "fat_cavity_a", "a_lateral", "sliding"),
         ("fat_on_b", "fat_cavity_b", "b_lateral", "sliding"),
         ("a_on_b", "a_lateral", "b_lateral", "contact"))


#: The flexion's bones (:func:`flexion_bones`): the humerus' radius, its gap to the skin at rest, the forearm's radius.
HUMERUS_RADIUS = 0.01
BONE_GAP = 0.001
FOREARM_RADIUS = 0.008
#: The arm segment's radius (meshes.arm_segment's default).
RADIUS = 0.03


def _pairs(touching: float | None) -> tuple[tuple[str, str, str, str], ...]:
    """The layered arm's pairs: :data:`PAIRS`, or :data:`TOUCHING_PAIRS` with touching muscles (a spacing)."""
    return PAIRS if touching is None else TOUCHING_PAIRS


def _muscle(region: str, tendon: str, origin: str, insertion: str, activation: float) -> list[dict[str, Any]]:
    fibres = {"type": "laplace", "origin": origin, "insertion": insertion, "regions": [region, tendon]}
    return [{"region": region, "law": "muscle", "isotropic": "stvk", "E": 9.0e6, "nu": 0.45, "fibres": fibres,
             "activation": [[0.0, 0.0], [1.0, activation]]},
            {"region": tendon, "law": "tendon", "isotropic": "stvk", "E": 15.0e6, "nu": 0.45, "fibres": fibres}]


def arm_config(layered: bool, size: float = 0.008, turn_elements: int = 16, steps: int = 4,
               k_sliding: float = 1e10, k_contact: float = 1e10, tolerance: float = 1e-6,
               activations: tuple[float, float] = (1.0, 0.3), touching: float | None = None,
               augmented: bool = True) -> RunConfig:
    """:func:`arm_raw` checked: the RunConfig."""
    return parse(arm_raw(layered, size, turn_elements, steps, k_sliding, k_contact, tolerance, activations, touching,
                         augmented))


def arm_raw(layered: bool, size: float = 0.008, turn_elements: int = 16, steps: int = 4,
            k_sliding: float = 1e10, k_contact: float = 1e10, tolerance: float = 1e-6,
            activations: tuple[float, float] = (1.0, 0.3), touching: float | None = None,
            augmented: bool = True) -> dict[str, Any]:
    """examples/arm_segment.toml (``layered`` False) or its layered twin examples/layered_arm.toml (the mesh
    generator layered_arm, its region names, the [[contact]] pairs :data:`PAIRS` with penalties ``k_sliding`` and
    ``k_contact``, the muscles' contact augmented to ``tolerance`` x size unless ``augmented`` is False), with
    mesh ``size`` and ``turn_elements``, the muscles a and b activated to ``activations``; ``touching`` (layered
    only): the muscles' spacing, with layered_arm's touching = true (examples/layered_arm_touching.toml: bellies
    cut at x = 0, sharing a flat face, no fat between them) and the pairs :data:`TOUCHING_PAIRS`."""
    if layered:
        names = {"fat": "fat", "belly_a": "a_belly", "tendon_a": "a_tendon", "belly_b": "b_belly",
                 "tendon_b": "b_tendon", "proximal": "fat_proximal", "distal": "fat_distal"}
    else:
        names = {n: n for n in ("fat", "belly_a", "tendon_a", "belly_b", "tendon_b", "proximal", "distal")}
    raw: dict[str, Any] = {
        "mesh": {"generator": "layered_arm" if layered else "arm_segment", "size": size,
                 "turn_elements": turn_elements,
                 **({"spacing": touching, "touching": True} if touching is not None else {})},
        "discretization": {"degree": 1, "quadrature_degree": "auto"},
        "material": [{"region": names["fat"], "law": "stvk", "E": 1.0e6, "nu": 0.45},
                     *_muscle(names["belly_a"], names["tendon_a"], "a_origin", "a_insertion", activations[0]),
                     *_muscle(names["belly_b"], names["tendon_b"], "b_origin", "b_insertion", activations[1])],
        "boundary": [{"on": on, "type": "displacement", "value": [0.0, 0.0, 0.0]}
                     for on in (names["proximal"], names["distal"], "a_origin", "a_insertion", "b_origin",
                                "b_insertion")],
        "loading": {"steps": steps},
    }
    if layered:
        augment = {"augmented": True, "tolerance": tolerance} if augmented else {}
        raw["contact"] = [{"surface": slave, "master": master, "method": "penalty",
                           **({"penalty": k_contact, **augment} if kind == "contact"
                              else {"penalty": k_sliding, "sliding": True})}
                          for _, slave, master, kind in _pairs(touching)]
        # the lagged pairing converges linearly (model.problem.body_contact: the nodal normals)
        raw["solver"] = {"petsc_options": {"snes_max_it": 80, "snes_rtol": 1e-8}}
    return raw


def flexion_bones(angle: float) -> list[dict[str, Any]]:
    """The [[bone]] tables of the flexion (module docstring): the humerus behind the segment (axis y = -(R + gap +
    r_h), from z = -2 cm to the elbow at z = L) and the forearm (from the elbow along +z), turning by ``angle``
    degrees about the elbow axis -x through the humerus' distal end point (forward: towards +y)."""
    y = -(RADIUS + BONE_GAP + HUMERUS_RADIUS)
    elbow = [0.0, y, LENGTH]
    return [{"name": "humerus", "obstacle": "capsule", "a": [0.0, y, -0.02], "b": elbow, "radius": HUMERUS_RADIUS},
            {"name": "forearm", "obstacle": "capsule", "a": elbow, "b": [0.0, y, LENGTH + 0.24],
             "radius": FOREARM_RADIUS,
             "hinge": {"axis": [-1.0, 0.0, 0.0], "point": elbow, "angles": [[0.0, 0.0], [1.0, float(angle)]]}}]


def flexion_config(layered: bool, angle: float = 30.0, size: float = 0.015, turn_elements: int = 8, steps: int = 3,
                   **kwargs: Any) -> RunConfig:
    """:func:`flexion_raw` (its keyword arguments ``kwargs``) checked: the RunConfig."""
    return parse(flexion_raw(layered, angle, size, turn_elements, steps, **kwargs))


def flexion_raw(layered: bool, angle: float = 30.0, size: float = 0.015, turn_elements: int = 8, steps: int = 3,
                k_sliding: float = 1e10, k_contact: float = 1e10, k_bone: float = 1e10,
                tolerance: float = 1e-6, activations: tuple[float, float] = (1.0, 0.3),
                petsc_options: dict[str, Any] | None = None, touching: float | None = None,
                sequential: bool = False) -> dict[str, Any]:
    """The elbow flexion by ``angle`` degrees of the conforming (``layered`` False) or the layered arm
    (examples/layered_arm_flexion.toml; module docstring): :func:`arm_config`'s materials, activations and (layered)
    pairs, with the segment's end faces attached to the bones :func:`flexion_bones` instead of clamped, and the
    skin in frictionless penalty contact (``k_bone``, nodal rule) with the humerus; ``petsc_options`` are added to
    the solver's. ``touching`` (layered only): the muscles' spacing with layered_arm's touching = true
    (examples/layered_arm_touching_flexion.toml: the bellies share a flat face, :data:`TOUCHING_PAIRS`, the muscles'
    contact a plain penalty). ``sequential``: the activations rise over the first half of the load (t in [0,
    1/2]) and the forearm turns over the second (t in [1/2, 1]), instead of both over the whole."""
    raw = arm_raw(layered, size, turn_elements, steps, k_sliding, k_contact, tolerance, activations, touching,
                  augmented=touching is None)
    prefix = "fat_" if layered else ""
    raw["bone"] = flexion_bones(angle)
    if sequential:
        for material in raw["material"]:
            if "activation" in material:
                a = material["activation"][-1][1]
                material["activation"] = [[0.0, 0.0], [0.5, a], [1.0, a]]
        raw["bone"][1]["hinge"]["angles"] = [[0.0, 0.0], [0.5, 0.0], [1.0, float(angle)]]
    raw["boundary"] = [{"on": on, "type": "attached", "bone": bone}
                       for on, bone in ((f"{prefix}proximal", "humerus"), ("a_origin", "humerus"),
                                        ("b_origin", "humerus"), (f"{prefix}distal", "forearm"),
                                        ("a_insertion", "forearm"), ("b_insertion", "forearm"))]
    raw["contact"] = [*raw.get("contact", []),
                      {"surface": f"{prefix}skin", "bone": "humerus", "method": "penalty", "penalty": k_bone,
                       "quadrature_degree": "vertex"}]
    # the default line search (model.solvers.newton.default_line_search): full Newton steps with the layered arm's
    # sliding pairs (no consistent potential), backtracking on the total potential for the conforming arm
    raw["solver"] = {"petsc_options": {"snes_max_it": 80, "snes_rtol": 1e-8, **(petsc_options or {})}}
    return raw


#: The flexion of the touching arm (examples/layered_arm_touching_flexion.toml, :func:`touching_flexion_raw`):
#: both muscles activated to 1 over the first half of the load, then the forearm turned by 5 degrees; 4 steps.
TOUCHING_FLEXION = {"angle": 5.0, "steps": 4, "touching": 0.019, "k_contact": 1e11, "activations": (1.0, 1.0),
                    "sequential": True}


def touching_flexion_raw(**kwargs: Any) -> dict[str, Any]:
    """The layered arm with touching muscles (examples/layered_arm_touching.toml: the bellies share a flat face,
    no fat between them, penalty k = 1e11) on the flexion's bones: :func:`flexion_raw` with
    :data:`TOUCHING_FLEXION` (``kwargs`` override it): the activation presses the muscles' shared face together,
    then the flexion unloads it."""
    return flexion_raw(True, **{**TOUCHING_FLEXION, **kwargs})


def run_touching_flexion(comm: MPI.Comm = MPI.COMM_WORLD, **kwargs: Any) -> ArmResult:
    """:func:`run_flexion` of :func:`touching_flexion_raw` (``kwargs`` override :data:`TOUCHING_FLEXION`), with the
    muscles' contact report at rest and after every converged step (ArmResult.history). Collective."""
    return run_flexion(True, comm=comm, **{**TOUCHING_FLEXION, **kwargs})


def _nodes_on(problem: ElasticityProblem, boundary: str) -> tuple[np.ndarray, np.ndarray]:
    """Reference coordinates and displacements of the nodes of ``boundary``, every rank's, sorted by coordinates
    (the same arrays on every rank). Collective."""
    from dolfinx import fem

    V = problem.space
    msh = problem.domain.mesh
    fdim = msh.topology.dim - 1
    blocks = np.asarray(fem.locate_dofs_topological(V, fdim, problem.domain.boundary_facets(boundary)))
    blocks = blocks[blocks < V.dofmap.index_map.size_local]
    X = V.tabulate_dof_coordinates()[blocks, :3]
    u = problem.solution.x.array.reshape(-1, 3)[blocks]
    parts = msh.comm.allgather((X, u))
    X = np.concatenate([p[0] for p in parts])
    u = np.concatenate([p[1] for p in parts])
    order = np.lexsort(np.round(X / LENGTH, 9).T[::-1])
    return X[order], u[order]


@dataclass
class ArmResult:
    """One run's measurements (module docstring), the same on every rank."""

    layered: bool
    cells: int
    dofs: int
    completed: bool
    newton_iterations: list[int]
    skin_X: np.ndarray
    skin_u: np.ndarray
    bulge_max: float
    bulge_mean: float
    slip: dict[str, dict[str, float]] = field(default_factory=dict)
    pairs: dict[str, dict[str, Any]] = field(default_factory=dict)
    muscle_gap: float = float("nan")
    reactions: dict[str, np.ndarray] = field(default_factory=dict)
    seconds: float = 0.0
    angle: float = 0.0
    bone: dict[str, Any] = field(default_factory=dict)
    distal_X: np.ndarray | None = None
    distal_u: np.ndarray | None = None
    history: list[dict[str, Any]] = field(default_factory=list)


def _bulge(X: np.ndarray, u: np.ndarray, relative: bool = False) -> tuple[float, float]:
    """max and mean over the skin nodes of the middle fifth of u_r = u . (X, Y) / |(X, Y)|; ``relative``: of
    (u - mean u) . (X, Y) / |(X, Y)|, the mean over those nodes (the section's translation) taken out."""
    middle = np.abs(X[:, 2] - 0.5 * LENGTH) <= 0.1 * LENGTH
    radial = X[middle, :2] / np.linalg.norm(X[middle, :2], axis=1, keepdims=True)
    um = u[middle, :2] - (u[middle, :2].mean(axis=0) if relative else 0.0)
    ur = np.einsum("ij,ij->i", um, radial)
    return float(ur.max()), float(ur.mean())


def _slip(problem: ElasticityProblem, fat: str, muscle: str) -> dict[str, float]:
    """|u_fat - u_muscle| between the two copies of each interface node (matched by coordinates): max, mean."""
    Xf, uf = _nodes_on(problem, fat)
    Xm, um = _nodes_on(problem, muscle)
    if Xf.shape != Xm.shape or not np.allclose(Xf, Xm, rtol=0.0, atol=1e-12):
        raise RuntimeError(f"{fat} and {muscle} do not have the same nodes")
    d = np.linalg.norm(uf - um, axis=1)
    return {"max": float(d.max()), "mean": float(d.mean()), "nodes": int(len(d))}


def run_arm(layered: bool, size: float = 0.008, turn_elements: int = 16, steps: int = 4, k_sliding: float = 1e10,
            k_contact: float = 1e10, comm: MPI.Comm = MPI.COMM_WORLD, activations: tuple[float, float] = (1.0, 0.3),
            touching: float | None = None, augmented: bool = True) -> ArmResult:
    """Run the conforming (``layered`` False) or the layered arm to full activation and measure it (module
    docstring; ``activations``, ``touching`` and ``augmented``: :func:`arm_config`). Collective."""
    config = arm_config(layered, size, turn_elements, steps, k_sliding, k_contact, activations=activations,
                        touching=touching, augmented=augmented)
    return _run(config, layered, _pairs(touching), steps, comm)


def run_flexion(layered: bool, angle: float = 30.0, size: float = 0.015, turn_elements: int = 8, steps: int = 3,
                comm: MPI.Comm = MPI.COMM_WORLD, **kwargs: Any) -> ArmResult:
    """Run the elbow flexion (:func:`flexion_config`, whose keyword arguments ``kwargs`` takes) of the conforming
    or the layered arm and measure it (module docstring: the bulge relative to the section's mean displacement;
    ``bone``: the humerus' contact report; ``reactions``: the attached faces'). Collective."""
    config = flexion_config(layered, angle, size, turn_elements, steps, **kwargs)
    touching = kwargs.get("touching")
    result = _run(config, layered, _pairs(touching), steps, comm, flexion=True,
                  track="a_on_b" if touching is not None else None)
    result.angle = float(angle)
    return result


def _run(config: RunConfig, layered: bool, names: tuple[tuple[str, str, str, str], ...], steps: int,
         comm: MPI.Comm, flexion: bool = False, track: str | None = None) -> ArmResult:
    """Build and solve ``config`` to load factor 1 in ``steps`` steps (cut back where Newton fails) and measure
    it. ``names``: the layered run's pairs (the first contacts of ``config``, in order); ``flexion``: the last
    contact is the humerus' and the bulge is relative to the band's mean displacement; ``track``: a pair whose
    report, the load factor ("load_factor") and the smallest gap ("min_gap") are recorded at rest and after every
    converged step (ArmResult.history).
    Collective."""
    import time

    from model.pipeline import build, make_solver
    from model.problem.measurements import reactions
    from model.solvers.loadstepping import step_loads

    start = time.perf_counter()
    setup = build(config, comm)
    problem = setup.problem
    pairs = {name: setup.contacts[i] for i, (name, *_) in enumerate(names)} if layered else {}
    solver = make_solver(problem, config, setup.contacts)
    records: list[Any] = []
    history: list[dict[str, Any]] = []

    def measure(load_factor: float) -> None:
        gaps = pairs[track].nodal_gaps()
        history.append({"load_factor": load_factor, **pairs[track].report(),
                        "min_gap": float(comm.allreduce(float(gaps.min(initial=np.inf)), op=MPI.MIN))})

    def on_step(record: Any) -> None:
        records.append(record)
        if track is not None and record.result.converged:
            measure(float(record.load_factor))

    if track is not None:
        measure(0.0)
    outcome = step_loads(solver, steps, on_step=on_step)
    iterations = [int(r.result.iterations) for r in records if r.result.converged]
    skin = "fat_skin" if layered else "skin"
    X, u = _nodes_on(problem, skin)
    bulge_max, bulge_mean = _bulge(X, u, relative=flexion)
    msh = problem.domain.mesh
    result = ArmResult(layered, msh.topology.index_map(3).size_global, problem.space.dofmap.index_map.size_global * 3,
                       bool(outcome.completed), iterations, X, u, bulge_max, bulge_mean, history=history)
    if layered or flexion:
        residual = solver.unconstrained_residual()
        result.reactions = {name: np.asarray(f) for name, f in reactions(problem, residual).items()}
        residual.destroy()
    if layered:
        result.slip = {m: _slip(problem, f"fat_cavity_{m}", names[i][2]) for i, m in enumerate("ab")}
        result.pairs = {name: pair.report() for name, pair in pairs.items()}
        gaps = pairs["a_on_b"].nodal_gaps()
        result.muscle_gap = float(comm.allreduce(float(gaps.min(initial=np.inf)), op=MPI.MIN))
    if flexion:
        result.bone = setup.contacts[-1].contact_report()
        result.distal_X, result.distal_u = _nodes_on(problem, "fat_distal" if layered else "distal")
    solver.destroy()
    result.seconds = time.perf_counter() - start
    log.info("%s arm%s: %d cells, Newton %s, bulge max %.4g mean %.4g m in %.1f s",
             "layered" if layered else "conforming", " (flexion)" if flexion else "", result.cells, iterations,
             bulge_max, bulge_mean, result.seconds)
    return result


def body_balance(result: ArmResult) -> dict[str, np.ndarray]:
    """Each body's force balance in a layered run (N, zero at equilibrium): its faces' reactions plus the forces of
    its pairs, the force on muscle b from a taken as minus the reported force on a from b and the force on a muscle
    from the fat as minus the force on the fat, and the humerus' push on the fat (flexion runs):

        a:   R_a_origin + R_a_insertion + f_ab - f_fa
        b:   R_b_origin + R_b_insertion - f_ab - f_fb
        fat: R_fat_proximal + R_fat_distal + f_fa + f_fb + f_bone
        all: sum of every reaction + f_bone"""
    R, pairs = result.reactions, result.pairs
    f_ab, f_fa, f_fb = (np.asarray(pairs[n]["force"]) for n in ("a_on_b", "fat_on_a", "fat_on_b"))
    bone = np.asarray(result.bone.get("force", np.zeros(3)), dtype=float)
    return {"a": R["a_origin"] + R["a_insertion"] + f_ab - f_fa,
            "b": R["b_origin"] + R["b_insertion"] - f_ab - f_fb,
            "fat": R["fat_proximal"] + R["fat_distal"] + f_fa + f_fb + bone,
            "all": sum(R.values()) + bone}


def skin_difference(conforming: ArmResult, layered: ArmResult) -> dict[str, float]:
    """max and root-mean-square |u_layered - u_conforming| over the skin nodes (the same nodes), and the max
    |u_conforming| there."""
    if conforming.skin_X.shape != layered.skin_X.shape or \
            not np.allclose(conforming.skin_X, layered.skin_X, rtol=0.0, atol=1e-12):
        raise ValueError("the two runs do not have the same skin nodes (not the same mesh parameters)")
    d = np.linalg.norm(layered.skin_u - conforming.skin_u, axis=1)
    return {"max": float(d.max()), "rms": float(np.sqrt(np.mean(d**2))),
            "max_conforming": float(np.linalg.norm(conforming.skin_u, axis=1).max())}


def compare_arms(**kwargs: Any) -> tuple[ArmResult, ArmResult]:
    """:func:`run_arm` conforming and layered with the same keyword arguments. Collective."""
    return run_arm(False, **kwargs), run_arm(True, **kwargs)


def compare_flexion(**kwargs: Any) -> tuple[ArmResult, ArmResult]:
    """:func:`run_flexion` conforming and layered with the same keyword arguments. Collective."""
    return run_flexion(False, **kwargs), run_flexion(True, **kwargs)


# --- muscles that start apart and close a gap (layered_arm's touching = true with gap > 0) -------------------------

#: The gap run's mesh (examples/layered_arm_gap.toml): the touching arm's coarse mesh with the flat faces apart.
GAP_MESH = {"size": 0.015, "turn_elements": 8, "spacing": 0.019}


def gap_raw(gap: float, steps: int = 4, k_contact: float = 1e11, k_sliding: float = 1e10,
            activations: tuple[float, float] = (1.0, 1.0), **mesh: Any) -> dict[str, Any]:
    """The layered arm with its muscles' flat faces ``gap`` apart across a void (examples/layered_arm_gap.toml):
    :func:`arm_raw`'s touching arm (``mesh``: :data:`GAP_MESH`'s keys, its values by default) with layered_arm's
    ``gap``, both muscles activated to ``activations`` in ``steps`` steps, the pairs :data:`TOUCHING_PAIRS`
    (a_flat against b_flat: penalty ``k_contact``, not augmented)."""
    params = {**GAP_MESH, **mesh}
    raw = arm_raw(True, params["size"], params["turn_elements"], steps, k_sliding, k_contact,
                  activations=activations, touching=params["spacing"], augmented=False)
    raw["mesh"]["gap"] = gap
    return raw


def run_gap(gap: float, steps: int = 4, comm: MPI.Comm = MPI.COMM_WORLD, **kwargs: Any) -> ArmResult:
    """Run :func:`gap_raw` (its keyword arguments ``kwargs``) and measure it as :func:`run_arm`, with the muscles'
    contact report after every converged step (ArmResult.history: the gap closing). Collective."""
    config = parse(gap_raw(gap, steps, **kwargs))
    return _run(config, True, TOUCHING_PAIRS, steps, comm, track="a_on_b")
