"""The thesis' painted pressure weight map (model.problem.membrane, ``pressure_weight``; ch. 3.3.3: artists paint
"a spatial weight map to create variations in the inflating behaviour"): every node's pressure is w(X) p.

A clamped StVK disc (a = 1, E = 1, nu = 0.3, h = 0.01, mesh size 0.15, from a paraboloid bump of 0.3), as in
tests/test_membrane_freeze.py:

- w = 2 everywhere is the pressure doubled: the equilibria of the energy W - 2p V to round-off;
- each node carries w(X_i) p exactly, and at rest (flat, normal +z) the load's total is p int w dA (a linear w:
  its P1 interpolant is w, so the two agree to round-off);
- a weight that grows along +x tilts the inflation: the membrane bulges more on the heavier side than under the
  uniform pressure, and less on the lighter one;
- with freeze_on_contact a frozen node keeps w_i times the pressure of the step it first touched at;
- from a config: the run is the solver's; a bad expression, t, or a weight < 0 on the mesh is a one-line
  ConfigError naming inflation.pressure_weight.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI

from forms.membrane import MembraneStVK
from forms.obstacles import Plane
from meshes.membrane import disc_surface
from model.config.expressions import compile_expression
from model.config.membrane import load_membrane
from model.domain.distribute import build_domain
from model.errors import ConfigError
from model.problem.membrane import MembraneProblem, axis_orientation
from model.problem.membrane_contact import ObstacleContact
from model.solvers.membrane import inflate

COMM = MPI.COMM_WORLD
STVK = MembraneStVK(young=1.0, nu=0.3, thickness=0.01)
PRESSURES = [2e-3, 4e-3, 6e-3]
TILT = "1 + 0.5 * x[0]"


def _disc(weight: str | None = None, freeze: bool = False, plane: bool = False) -> MembraneProblem:
    problem = MembraneProblem(build_domain(COMM, disc_surface(1.0, 0.15) if COMM.rank == 0 else None), STVK,
                              axis_orientation(), {"rim": (0, 1, 2)}, freeze_on_contact=freeze,
                              pressure_weight=compile_expression(weight) if weight is not None else None)
    problem.u.interpolate(lambda x: np.vstack([0 * x[0], 0 * x[0], 0.3 * (1 - x[0] ** 2 - x[1] ** 2)]))
    if plane:
        ObstacleContact(problem, Plane((0.0, 0.0, 0.45), (0.0, 0.0, -1.0)), 10.0)
    return problem


def _largest(values: np.ndarray) -> float:
    return COMM.allreduce(float(np.abs(values).max(initial=0.0)), op=MPI.MAX)


def test_a_uniform_weight_scales_the_pressure() -> None:
    """w = 2 at p: the equilibria of W - 2p V (the energy's path, no weight) to round-off (measured 1e-16 of
    max u_z 0.6), and each node carries 2p."""
    doubled, plain = _disc("2"), _disc()
    inflate(doubled, PRESSURES)
    inflate(plain, [2 * p for p in PRESSURES])
    assert _largest(doubled.u.x.array - plain.u.x.array) < 1e-10 * _largest(plain.u.x.array)
    assert plain.max_component(2) > 0.5
    assert np.all(doubled.nodal_pressures() == 2 * PRESSURES[-1])


def test_each_node_carries_its_weight_and_the_load_integrates_it() -> None:
    """w = 1 + 0.5 x + 0.25 y: p_i = w(X_i) p at every node (exactly), and at the flat rest state the load's total
    is (0, 0, p int w dA) to round-off (the P1 interpolant of a linear w is w)."""
    problem = _disc("1 + 0.5 * x[0] + 0.25 * x[1]")
    problem.u.x.array[:] = 0.0
    problem.set_pressure(3e-3)
    n = problem.V.dofmap.index_map.size_local
    X = problem.V.tabulate_dof_coordinates()[:n]
    assert np.array_equal(problem.nodal_pressures(), 3e-3 * (1 + 0.5 * X[:, 0] + 0.25 * X[:, 1]))
    x = ufl.SpatialCoordinate(problem.domain.mesh)
    weighted = COMM.allreduce(fem.assemble_scalar(fem.form((1 + 0.5 * x[0] + 0.25 * x[1]) * problem.dA)),
                              op=MPI.SUM)
    assert np.allclose(problem.pressure_force(), [0.0, 0.0, 3e-3 * weighted], rtol=1e-12, atol=1e-15)
    assert weighted == pytest.approx(problem.reference_area(), rel=1e-2)  # int x dA ~ 0 on the disc


def _deflection_at(problem: MembraneProblem, x0: float) -> float:
    """u_z at the owned node nearest to (x0, 0), every rank's nearest compared (collective)."""
    n = problem.V.dofmap.index_map.size_local
    X = problem.V.tabulate_dof_coordinates()[:n]
    d = np.hypot(X[:, 0] - x0, X[:, 1])
    i = int(np.argmin(d)) if n else -1
    best = COMM.allreduce((float(d[i]) if n else np.inf, float(problem.u.x.array[3 * i + 2]) if n else 0.0),
                          op=MPI.MIN)
    return best[1]


def test_a_weight_along_x_tilts_the_inflation() -> None:
    """w = 1 + 0.5 x (1.5 at x = 1, 0.5 at x = -1): at x = +0.5 the membrane rises above the uniform pressure's
    membrane, at x = -0.5 below it (measured at p = 6e-3, the nodes nearest x = +-0.5: 0.478 and 0.439 against the
    uniform 0.452: the membrane's tension spreads the load), and the enclosed volume is near the uniform one
    (int w dA = the area)."""
    tilted, uniform = _disc(TILT), _disc()
    a, b = inflate(tilted, PRESSURES), inflate(uniform, PRESSURES)
    heavy, light = _deflection_at(tilted, 0.5), _deflection_at(tilted, -0.5)
    reference = _deflection_at(uniform, 0.5)
    assert reference == pytest.approx(_deflection_at(uniform, -0.5), rel=0.05)  # the uniform disc is symmetric
    assert heavy > 1.03 * reference and light < 0.99 * reference
    assert a[-1].volume == pytest.approx(b[-1].volume, rel=0.05)


def test_frozen_nodes_keep_their_weighted_pressure() -> None:
    """With freeze_on_contact against the plane z = 0.45: a frozen node carries w_i times the pressure of the step
    it first touched at, every other node w_i times the last pressure."""
    problem = _disc(TILT, freeze=True, plane=True)
    steps = inflate(problem, PRESSURES)
    assert steps[-1].frozen_nodes > 0
    ratio = problem.nodal_pressures() / problem.weight
    assert np.allclose(ratio[~problem.frozen], PRESSURES[-1], rtol=1e-14)
    frozen = np.concatenate(COMM.allgather(ratio[problem.frozen]))
    assert np.all(np.min(np.abs(frozen[:, None] - np.asarray(PRESSURES)[None, :]), axis=1) < 1e-14)
    assert len(set(np.round(frozen, 12))) >= 2  # frozen at different steps


BALLOON = Path(__file__).resolve().parent.parent / "examples" / "membrane_balloon.toml"
DISC = {"membrane.surface": "disc", "membrane.size": 0.15, "membrane.fixed": {"rim": [0, 1, 2]},
        "membrane.bump": 0.3, "output.xdmf": False, "output.vtu": False,
        "inflation": {"pressures": PRESSURES, "pressure_weight": TILT}}


def test_pressure_weight_from_the_config(shared_tmp: Path) -> None:
    """[inflation] pressure_weight: the run's volumes are the solver's, step by step."""
    from model.experiments.membrane_run import run_membrane

    summary = run_membrane(load_membrane(BALLOON, DISC), shared_tmp / "weight", COMM)
    steps = inflate(_disc(TILT), PRESSURES)
    assert [s["volume"] for s in summary["steps"]] == pytest.approx([s.volume for s in steps], rel=1e-12)
    assert summary["config"]["inflation"]["pressure_weight"] == TILT


@pytest.mark.parametrize(("weight", "message"), [
    ("x[3]", r"^inflation\.pressure_weight: invalid expression 'x\[3\]': only x\[0\], x\[1\] and x\[2\]"),
    ("1 + t", r"^inflation\.pressure_weight: must not mention t"),
    ("open('f')", r"^inflation\.pressure_weight: invalid expression"),
])
def test_bad_pressure_weight_names_the_key(weight: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message) as err:
        load_membrane(BALLOON, {**DISC, "inflation": {"pressures": PRESSURES, "pressure_weight": weight}})
    assert "\n" not in str(err.value)


def test_a_negative_weight_on_the_mesh_is_refused_before_the_solve(shared_tmp: Path) -> None:
    """w = x[0] is negative on half the disc: a one-line ConfigError naming the key, a node and its value, the
    same on every rank, before any solve."""
    from model.experiments.membrane_run import run_membrane

    config = load_membrane(BALLOON, {**DISC, "inflation": {"pressures": PRESSURES, "pressure_weight": "x[0]"}})
    with pytest.raises(ConfigError, match=r"^inflation\.pressure_weight: must be finite and >= 0 at every node, "
                                          r"got -[0-9.e-]+ at \(") as err:
        run_membrane(config, shared_tmp / "negative", COMM)
    assert "\n" not in str(err.value)
