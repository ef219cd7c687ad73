"""Implicit elastodynamics (model.solvers.dynamics): M a + D v + f_int(u) = f_ext(t).

- Every scheme follows, in the modal coordinate of the first mode, its own discrete solution of the
  modal equation q'' + (a_M + b_K w^2) q' + w^2 q = 0 (2e-4).
- Newmark average acceleration, undamped, on a clamped bar vibrating in its first bending mode at
  small amplitude: kinetic + strain energy is conserved (1e-4 relative over 100 steps), and the
  period is the trapezoidal rule's, w_h = (2/dt) atan(w dt/2).
- Rayleigh damping: the measured damping ratio of the first mode (Prony fit of the modal
  coordinate) matches zeta = a_M/(2 w) + b_K w/2 (5%; and, after undoing the trapezoidal rule's
  Cayley map, 0.5%), w from the generalized eigenproblem K phi = w^2 M phi (dense, scipy); the
  energy balance kinetic + strain + dissipated is conserved.
- Backward Euler without damping dissipates: the energy decreases every step.
- Free fall under a body force, no supports: a_0 = b/rho from the mass solve, and u(t) is exact
  (Newmark: b t^2/(2 rho); backward Euler: b t (t + dt)/(2 rho)), also mixed.
- Generalized alpha: rho_inf = 1 conserves energy, rho_inf < 1 dissipates numerically.
- The Jacobian (ufl.derivative of the residual with inertia and damping) against central
  differences of the residual, every scheme, displacement and mixed.
- Time-step cut-back and regrowth, giving up, restoring the state; parse_dynamics errors name the key.
- Slow: Taylor-Hood (P2/P1, nu = 0.45) Newmark conserves kinetic + mixed potential; a P2 neo-Hookean
  bar whose clamped end is moved and then held jiggles about its new position and the Rayleigh damping
  takes the energy out.

Every test is collective and gives the same numbers serially and under mpirun -n 2.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
import scipy.linalg
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

import forms
import meshes
from model import compat
from model.config.dynamics import DynamicsSpec, parse_dynamics
from model.domain import Probes, build_domain
from model.errors import ConfigError
from model.problem import ElasticityProblem
from model.solvers.dynamics import Dynamics, TimeStepRecord, step_time
from model.solvers.newton import NewtonSolver, SolveResult

E, NU, RHO = 1.0e3, 0.3, 1.0
BAR = {"size": (1.0, 0.2, 0.1), "cells": (8, 2, 1)}  # first mode: bending across the thin side


def bar_problem(law: str = "stvk", degree: int = 1, formulation: str = "displacement",
                clamped: bool = True) -> ElasticityProblem:
    comm = MPI.COMM_WORLD
    data = meshes.box(**BAR) if comm.rank == 0 else None
    domain = build_domain(comm, data)
    nu = 0.45 if formulation == "mixed" else NU
    problem = ElasticityProblem(domain, [("all", forms.make_law(law, E=E, nu=nu))], degree, 2 * degree, formulation)
    if clamped:
        problem.add_dirichlet("xmin", [0, 1, 2], [0.0, 0.0, 0.0])
    return problem


def dense(A: PETSc.Mat) -> np.ndarray:
    """A distributed PETSc matrix as a dense array on every rank (small matrices only)."""
    r0, r1 = A.getOwnershipRange()
    indptr, indices, values = A.getValuesCSR()
    n = A.getSize()[0]
    out = np.zeros((n, n))
    for start, stop, ip, ix, v in MPI.COMM_WORLD.allgather((r0, r1, indptr, indices, values)):
        for i in range(stop - start):
            out[start + i, ix[ip[i]:ip[i + 1]]] = v[ip[i]:ip[i + 1]]
    return out


def first_mode(problem: ElasticityProblem) -> tuple[float, fem.Function, PETSc.Mat]:
    """w and phi of the lowest mode of K phi = w^2 M phi at the reference state (Dirichlet dofs removed),
    phi as a Function scaled to max |phi| = 1, and the mass matrix (identity rows at Dirichlet dofs)."""
    comm = MPI.COMM_WORLD
    problem.solution.x.array[:] = 0.0
    K = fem_petsc.assemble_matrix(problem.forms[1], bcs=problem.bcs)
    K.assemble()
    mass = fem.form(RHO * ufl.inner(ufl.TrialFunction(problem.space), problem.v) * problem.dx)
    M = fem_petsc.assemble_matrix(mass, bcs=problem.bcs)
    M.assemble()
    owned = problem.space.dofmap.index_map.size_local * problem.space.dofmap.index_map_bs
    constrained = np.zeros(owned, dtype=bool)
    for entry in problem.dirichlet:
        for dofs in entry.dofs:
            constrained[dofs[dofs < owned]] = True
    free = ~np.concatenate(comm.allgather(constrained))
    w2, vectors = scipy.linalg.eigh(dense(K)[np.ix_(free, free)], dense(M)[np.ix_(free, free)],
                                    subset_by_index=[0, 0])
    phi = np.zeros(free.size)
    phi[free] = vectors[:, 0]
    phi /= np.abs(phi).max() * np.sign(phi[np.abs(phi).argmax()])
    r0, r1 = M.getOwnershipRange()
    mode = fem.Function(problem.space)
    compat.petsc_vector(mode).array[:] = phi[r0:r1]
    mode.x.scatter_forward()
    K.destroy()
    return math.sqrt(w2[0]), mode, M


def prony(q: np.ndarray, dt: float) -> complex:
    """The continuous eigenvalue lambda = log(z)/dt of samples q_n ~ Re(c z^n): least squares on
    q_{n+1} = c1 q_n + c2 q_{n-1}, z the root with positive imaginary part."""
    c = np.linalg.lstsq(np.column_stack([q[1:-1], q[:-2]]), q[2:], rcond=None)[0]
    z = np.roots([1.0, -c[0], -c[1]]).astype(complex)
    z = z[np.argmax(z.imag)]
    return complex(np.log(z) / dt)


def vibrate(rayleigh: tuple[float, float], dt: float, steps: int, amplitude: float = 1e-3, scheme: str = "newmark",
            **options: float) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    """Release the clamped bar from amplitude * (first mode), at rest.

    Returns w, the modal coordinate q_n = phi^T M u_n / phi^T M u_0, the energy kinetic + strain
    and the dissipated energy per step (index 0 = initial)."""
    reference = bar_problem()
    w, mode, M = first_mode(reference)
    problem = bar_problem()
    dynamics = Dynamics(problem, RHO, scheme, rayleigh=rayleigh, dt=dt, **options)
    solver = NewtonSolver(problem)
    initial = fem.Function(problem.space)
    initial.x.array[:] = amplitude * mode.x.array
    dynamics.initialize(u0=initial)
    Mphi = M.createVecLeft()
    M.mult(compat.petsc_vector(mode), Mphi)
    q = [Mphi.dot(compat.petsc_vector(problem.solution))]
    energy = [dynamics.total_energy()]
    dissipated = [0.0]

    def on_step(record: TimeStepRecord) -> None:
        assert record.result.converged
        q.append(Mphi.dot(compat.petsc_vector(problem.solution)))
        energy.append(dynamics.kinetic_energy() + problem.total_energy())
        dissipated.append(dynamics.dissipated_energy)

    assert step_time(solver, dynamics, steps * dt, dt, on_step)
    assert len(q) == steps + 1 and dynamics.time == steps * dt
    solver.destroy()
    M.destroy()
    Mphi.destroy()
    return w, np.array(q) / q[0], np.array(energy), np.array(dissipated)


def single_mode(scheme: str, w: float, damping: float, dt: float, steps: int, rho_infinity: float = 1.0
                ) -> np.ndarray:
    """The scheme applied to q'' + c q' + w^2 q = 0, q(0) = 1, q'(0) = 0 (c = a_M + b_K w^2): q_n.

    Newmark / generalized alpha (Chung & Hulbert 1993) written for u_{n+1} directly:
    (1 - am) a_{n+1} + am a_n + c ((1 - af) v_{n+1} + af v_n) + k ((1 - af) u_{n+1} + af u_n) = 0."""
    k, c = w * w, damping
    am = af = 0.0
    beta, gamma = 0.25, 0.5
    if scheme == "generalized_alpha":
        am, af = (2 * rho_infinity - 1) / (rho_infinity + 1), rho_infinity / (rho_infinity + 1)
        gamma, beta = 0.5 - am + af, 0.25 * (1 - am + af) ** 2
    u, v = 1.0, 0.0
    a = -(c * v + k * u)
    out = [u]
    for _ in range(steps):
        # a_{n+1} = A1 u_{n+1} + A0, v_{n+1} = V1 u_{n+1} + V0
        A1, A0 = 1 / (beta * dt**2), -(u + dt * v) / (beta * dt**2) - (1 / (2 * beta) - 1) * a
        V1, V0 = gamma * dt * A1, v + dt * ((1 - gamma) * a + gamma * A0)
        u_new = -((1 - am) * A0 + am * a + c * ((1 - af) * V0 + af * v) + k * af * u) / (
            (1 - am) * A1 + c * (1 - af) * V1 + k * (1 - af))
        u, v, a = u_new, V1 * u_new + V0, A1 * u_new + A0
        out.append(u)
    return np.array(out)


def test_newmark_conserves_energy_and_gives_the_trapezoidal_period() -> None:
    dt = 0.02
    w, q, energy, dissipated = vibrate((0.0, 0.0), dt, 100)
    assert np.all(dissipated == 0.0)
    drift = np.abs(energy - energy[0]).max() / energy[0]
    lam = prony(q, dt)
    if MPI.COMM_WORLD.rank == 0:
        print(f"undamped Newmark: w = {w:.6f}, 100 steps of {dt}, energy drift {drift:.2e}, "
              f"measured w_h = {abs(lam):.6f} (trapezoidal {2 / dt * math.atan(w * dt / 2):.6f})")
    assert drift < 1e-4
    assert abs(lam.real) < 1e-5 * abs(lam)  # no numerical damping
    assert abs(abs(lam) - 2 / dt * math.atan(w * dt / 2)) < 1e-4 * w  # period error: the rule's own
    theta = 2 * math.atan(w * dt / 2)  # the trapezoidal rule's rotation per step
    error = np.abs(q - np.cos(theta * np.arange(q.size))).max()
    assert error < 2e-4  # the exact discrete solution (phase error of cos(w t) itself: 2e-2)
    assert q.min() < -0.99  # it does swing through


def test_rayleigh_damping_ratio_matches_closed_form() -> None:
    w_estimate = 7.094  # w of this mesh; only used to pick comparable mass and stiffness shares
    a_M, b_K = 0.05 * w_estimate, 0.05 / w_estimate
    dt = 0.02  # 44 steps per period: the trapezoidal rule's period error is 0.17%
    w, q, energy, dissipated = vibrate((a_M, b_K), dt, 130)
    zeta = a_M / (2 * w) + b_K * w / 2
    lam = prony(q, dt)
    measured = -lam.real / abs(lam)
    z = np.exp(lam * dt)
    exact = 2 / dt * (z - 1) / (z + 1)  # the eigenvalue whose trapezoidal image is z
    corrected = -exact.real / abs(exact)
    balance = np.abs(energy + dissipated - energy[0]).max() / energy[0]
    if MPI.COMM_WORLD.rank == 0:
        print(f"Rayleigh a_M = {a_M:.4g}, b_K = {b_K:.4g}: w = {w:.6f}, zeta closed form {zeta:.6f}, measured "
              f"{measured:.6f} ({measured / zeta - 1:+.2%}), Cayley-corrected {corrected:.6f} "
              f"({corrected / zeta - 1:+.3%}); kinetic + strain decayed to {energy[-1] / energy[0]:.3g} of its "
              f"initial value; energy balance with the dissipated energy {balance:.2e}")
    assert abs(measured / zeta - 1) < 0.05
    assert abs(corrected / zeta - 1) < 0.005
    assert np.abs(q - single_mode("newmark", w, a_M + b_K * w**2, dt, q.size - 1)).max() < 2e-4
    assert abs(q[-1]) < math.exp(-0.9 * zeta * w * 130 * dt)  # it decays
    assert energy[-1] < 0.2 * energy[0]
    assert balance < 1e-4  # kinetic + strain + dissipated = initial energy


@pytest.mark.parametrize("rho_infinity,rayleigh,dt,steps", [(1.0, (0.0, 0.0), 0.05, 60), (0.5, (0.35, 0.007), 0.05, 60),
                                                        (0.0, (0.0, 0.0), 0.15, 40)])
def test_generalized_alpha_follows_its_discrete_solution(rho_infinity: float, rayleigh: tuple[float, float], dt: float,
                                                         steps: int) -> None:
    """First mode, generalized alpha: q_n equals the scheme applied to the modal equation. rho_inf = 1 conserves
    the energy; rho_inf = 0 dissipates (w dt = 1.06 here), without any Rayleigh damping."""
    w, q, energy, dissipated = vibrate(rayleigh, dt, steps, scheme="generalized_alpha", rho_infinity=rho_infinity)
    a_M, b_K = rayleigh
    expected = single_mode("generalized_alpha", w, a_M + b_K * w**2, dt, steps, rho_infinity)
    error = np.abs(q - expected).max()
    drift = np.abs(energy + dissipated - energy[0]).max() / energy[0]
    if MPI.COMM_WORLD.rank == 0:
        print(f"generalized alpha rho_inf = {rho_infinity}, Rayleigh {rayleigh}, w dt = {w * dt:.3f}: max |q_n - "
              f"discrete solution| {error:.2e}; (energy + dissipated) / initial - 1 in "
              f"[{(energy + dissipated).min() / energy[0] - 1:.2e}, {(energy + dissipated).max() / energy[0] - 1:.2e}]")
    assert error < 2e-4
    if rho_infinity == 1.0:
        assert drift < 1e-4
    if rho_infinity == 0.0:  # numerical dissipation only
        assert np.all(dissipated == 0.0) and energy[-1] < 0.5 * energy[0]


def test_backward_euler_follows_its_discrete_solution() -> None:
    """First mode, backward Euler: q_n is the first component of B^-n (1, 0), B = [[1, -dt], [dt w^2, 1]]
    (u_{n+1} - dt v_{n+1} = u_n, v_{n+1} + dt w^2 u_{n+1} = v_n): amplitude decay and period of the scheme."""
    dt, steps = 0.02, 50
    w, q, energy, _ = vibrate((0.0, 0.0), dt, steps, scheme="backward_euler")
    step = np.linalg.inv(np.array([[1.0, -dt], [dt * w**2, 1.0]]))
    state, expected = np.array([1.0, 0.0]), [1.0]
    for _ in range(steps):
        state = step @ state
        expected.append(state[0])
    error = np.abs(q - np.array(expected)).max()
    if MPI.COMM_WORLD.rank == 0:
        print(f"backward Euler, first mode: max |q_n - discrete solution| {error:.2e}, amplitude "
              f"{np.abs(q[-10:]).max():.3f} after {steps} steps")
    assert error < 2e-4
    assert np.all(np.diff(energy) < 0.0)


def test_backward_euler_dissipates_energy() -> None:
    problem = bar_problem()
    dynamics = Dynamics(problem, RHO, "backward_euler", dt=0.02)
    solver = NewtonSolver(problem)
    dynamics.initialize(v0=lambda x: np.stack([0 * x[0], 0 * x[0], 1e-3 * x[0] ** 2]))
    energy = [dynamics.total_energy()]
    step_time(solver, dynamics, 1.0, 0.02, lambda record: energy.append(dynamics.total_energy()))
    energy = np.array(energy)
    if MPI.COMM_WORLD.rank == 0:
        print(f"backward Euler: energy {energy[0]:.4e} -> {energy[-1]:.4e} in {energy.size - 1} steps")
    assert energy.size == 51
    assert np.all(np.diff(energy) < 0.0)
    assert energy[-1] < 0.5 * energy[0]
    solver.destroy()


@pytest.mark.parametrize("scheme,formulation", [("newmark", "displacement"), ("backward_euler", "displacement"),
                                                ("newmark", "mixed")])
def test_free_fall_is_exact(scheme: str, formulation: str) -> None:
    """No supports, a constant body force b: a_0 = b/rho from the mass solve, rigid translation."""
    degree = 2 if formulation == "mixed" else 1
    problem = bar_problem("neo_hookean", degree, formulation, clamped=False)
    b = np.array([0.0, -3.0, 1.5])
    problem.add_body_force("all", b.tolist())
    dynamics = Dynamics(problem, {"body": 2.0}, scheme, dt=0.1)
    solver = NewtonSolver(problem)
    dynamics.initialize(load_factor=1.0)
    g = b / 2.0
    if scheme == "newmark":
        acceleration = dynamics.a_n.sub(0).collapse() if formulation == "mixed" else dynamics.a_n
        np.testing.assert_allclose(acceleration.x.array.reshape(-1, 3), np.tile(g, (acceleration.x.array.size // 3, 1)),
                                   atol=1e-12)
    dt = 0.1
    assert step_time(solver, dynamics, 1.0, dt, time_to_load=lambda t: 1.0)
    t = dynamics.time
    expected = 0.5 * g * t**2 if scheme == "newmark" else 0.5 * g * t * (t + dt)
    u = problem.displacement()
    np.testing.assert_allclose(u.x.array.reshape(-1, 3), np.tile(expected, (u.x.array.size // 3, 1)), atol=1e-10)
    mass = 2.0 * 0.02  # rho * volume; v = g t for both schemes
    assert dynamics.kinetic_energy() == pytest.approx(0.5 * mass * float(g @ g) * t**2, rel=1e-10)
    solver.destroy()


def _direction(problem: ElasticityProblem, seed: int) -> tuple[PETSc.Vec, np.ndarray]:
    rng = np.random.default_rng(seed + MPI.COMM_WORLD.rank)
    owned = problem.space.dofmap.index_map.size_local * problem.space.dofmap.index_map_bs
    direction = compat.petsc_vector(problem.solution).copy()
    direction.array[:] = rng.uniform(-1.0, 1.0, owned)
    direction.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    with direction.localForm() as local:
        return direction, local.array.copy()


def _residual(problem: ElasticityProblem) -> np.ndarray:
    problem.update_state()
    b = fem_petsc.assemble_vector(problem.forms[0])
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    out = b.array.copy()
    b.destroy()
    return out


def _field(scale: float, shift: float) -> Callable[[np.ndarray], np.ndarray]:
    return lambda x: scale * np.stack([0.2 * x[1] * x[2] + 0.1 * x[0] ** 2 + shift,
                                       -0.15 * x[0] * x[2] + 0.2 * np.sin(x[1] + shift),
                                       0.25 * x[0] * x[1] - 0.1 * x[2] ** 2])


@pytest.mark.parametrize("scheme,formulation", [("newmark", "displacement"), ("backward_euler", "displacement"),
                                                ("generalized_alpha", "displacement"), ("newmark", "mixed"),
                                                ("generalized_alpha", "mixed")])
def test_jacobian_with_inertia_and_damping_matches_finite_differences(scheme: str, formulation: str) -> None:
    comm = MPI.COMM_WORLD
    data = meshes.box(size=(1.0, 1.0, 1.0), cells=(2, 2, 2)) if comm.rank == 0 else None
    domain = build_domain(comm, data)
    problem = ElasticityProblem(domain, [("all", forms.make_law("neo_hookean", E=1e4, nu=0.3))], 2, 4, formulation)
    problem.add_traction("xmax", [100.0, 50.0, -30.0])
    problem.add_dirichlet("xmin", [0, 1, 2], [0.0, 0.0, 0.0])
    # inertia M/(beta dt^2) and damping comparable to the stiffness; b_K only in the displacement formulation
    rayleigh = (3.0, 0.02) if formulation == "displacement" else (3.0, 0.0)
    dynamics = Dynamics(problem, 100.0, scheme, rayleigh=rayleigh, dt=0.1)
    problem.set_load_factor(1.0)
    for function, scale, shift in ((dynamics.u_n, 0.5, 0.1), (dynamics.v_n, 2.0, 0.3), (dynamics.a_n, 5.0, 0.7),
                                   (problem.solution, 1.0, 0.0)):
        (function.sub(0) if formulation == "mixed" else function).interpolate(_field(scale, shift))
        function.x.scatter_forward()
    if formulation == "mixed":
        problem.solution.sub(1).interpolate(lambda x: 100.0 * (x[0] - 0.3 * x[1] + 0.2))
        problem.solution.x.scatter_forward()
    A = fem_petsc.assemble_matrix(problem.forms[1])
    A.assemble()
    direction, d = _direction(problem, 11)
    if formulation == "mixed":  # scale the pressure part like the pressure
        _, pdofs = problem.space.sub(1).collapse()
        d[np.asarray(pdofs)] *= 100.0
        owned = direction.getLocalSize()
        direction.array[:] = d[:owned]
    tangent = A.createVecLeft()
    A.mult(direction, tangent)
    x = problem.solution.x
    x0 = x.array.copy()
    h = 1e-6
    x.array[:] = x0 + h * d
    r_plus = _residual(problem)
    x.array[:] = x0 - h * d
    r_minus = _residual(problem)
    x.array[:] = x0
    fd = (r_plus - r_minus) / (2 * h)
    error = comm.allreduce(np.abs(fd - tangent.array).max(), op=MPI.MAX)
    scale = comm.allreduce(np.abs(tangent.array).max(), op=MPI.MAX)
    assert error / scale < 1e-7, f"{scheme} {formulation}: relative FD mismatch {error / scale:.2e}"
    A.destroy()
    tangent.destroy()
    direction.destroy()


class FlakySolver:
    """Wraps a NewtonSolver: the listed attempts (0-based) fail without solving, after scribbling on the
    solution; every attempt checks that it starts from the last accepted state."""

    def __init__(self, solver: NewtonSolver | None, dynamics: Dynamics, fail: Callable[[int], bool]) -> None:
        self.solver, self.dynamics, self.fail = solver, dynamics, fail
        self.problem = dynamics.problem
        self.attempts = 0

    def solve(self) -> SolveResult:
        np.testing.assert_array_equal(self.problem.solution.x.array, self.dynamics.u_n.x.array)
        attempt = self.attempts
        self.attempts += 1
        if self.fail(attempt):
            self.problem.solution.x.array[:] += 1.0
            return SolveResult(False, -5, "DIVERGED_FUNCTION_COUNT", 3, 3, 1.0)
        assert self.solver is not None
        return self.solver.solve()


def test_time_step_cut_back_regrowth_and_giving_up() -> None:
    problem = bar_problem()
    dynamics = Dynamics(problem, RHO, "newmark", dt=0.05)
    solver = NewtonSolver(problem)
    dynamics.initialize(v0=lambda x: np.stack([0 * x[0], 0 * x[0], 1e-3 * x[0]]))
    records: list[TimeStepRecord] = []
    flaky = FlakySolver(solver, dynamics, lambda attempt: attempt in (1, 2))
    compiled = problem.forms
    assert step_time(flaky, dynamics, 0.3, 0.05, records.append, growth=2.0)
    assert problem.forms is compiled  # dt is a Constant: changing it recompiles nothing
    converged = [(r.time, r.dt) for r in records if r.result.converged]
    failed = [r.dt for r in records if not r.result.converged]
    np.testing.assert_allclose(failed, [0.05, 0.025])
    np.testing.assert_allclose([dt for _, dt in converged], [0.05, 0.0125, 0.025, 0.05, 0.05, 0.05, 0.05, 0.0125])
    assert converged[-1][0] == 0.3 and dynamics.time == 0.3
    assert records[-1].load_factor == 0.3
    # a solver that never converges: give up after max_cutbacks, the state stays at the last accepted step
    before = dynamics.u_n.x.array.copy()
    stuck = FlakySolver(None, dynamics, lambda attempt: True)
    assert not step_time(stuck, dynamics, 1.0, 0.05, max_cutbacks=3)
    assert stuck.attempts == 4 and dynamics.time == 0.3
    np.testing.assert_array_equal(problem.solution.x.array, before)
    assert float(problem.load_factor.value) == pytest.approx(0.3)
    solver.destroy()


def test_refusals() -> None:
    problem = bar_problem("neo_hookean", 2, "mixed")
    with pytest.raises(ValueError, match="stiffness damping"):
        Dynamics(problem, RHO, "newmark", rayleigh=(0.0, 0.01))
    with pytest.raises(ValueError, match="scheme"):
        Dynamics(problem, RHO, "quasi_static")
    with pytest.raises(ValueError, match="no region named 'belly'"):
        Dynamics(problem, {"belly": 1.0}, "newmark")
    with pytest.raises(ValueError, match="density"):
        Dynamics(problem, -1.0, "newmark")
    with pytest.raises(ValueError, match="density"):
        Dynamics(problem, {}, "newmark")
    with pytest.raises(ValueError, match="Rayleigh"):
        Dynamics(problem, 1.0, "newmark", rayleigh=(-1.0, 0.0))
    dynamics = Dynamics(problem, RHO, "newmark", rayleigh=(0.5, 0.0))  # mass damping is fine with mixed
    with pytest.raises(RuntimeError, match="initialize"):
        step_time(None, dynamics, 1.0, 0.1)  # type: ignore[arg-type]


def test_parse_dynamics_accepts_valid_sections() -> None:
    assert parse_dynamics({}) == DynamicsSpec()
    assert not parse_dynamics({"scheme": "quasi_static"}).is_dynamic
    spec = parse_dynamics({"scheme": "newmark", "dt": 0.01, "end_time": 2, "rayleigh": [0.5, 1e-3]})
    assert spec == DynamicsSpec("newmark", 0.01, 2.0, (0.5, 1e-3)) and spec.is_dynamic
    assert parse_dynamics({"scheme": "backward_euler", "dt": 1}) == DynamicsSpec("backward_euler", 1.0, 1.0, (0, 0))
    assert parse_dynamics({"scheme": "generalized_alpha", "dt": 0.1, "rho_infinity": 0.5}).rho_infinity == 0.5


@pytest.mark.parametrize("raw,key", [
    ({"schme": "newmark"}, "dynamics.schme"),
    ({"scheme": 2}, "dynamics.scheme"),
    ({"scheme": "runge_kutta", "dt": 0.1}, "dynamics.scheme"),
    ({"scheme": "newmark"}, "dynamics.dt"),
    ({"scheme": "newmark", "dt": 0.0}, "dynamics.dt"),
    ({"scheme": "newmark", "dt": -0.1}, "dynamics.dt"),
    ({"scheme": "newmark", "dt": "0.1"}, "dynamics.dt"),
    ({"scheme": "newmark", "dt": True}, "dynamics.dt"),
    ({"scheme": "newmark", "dt": float("nan")}, "dynamics.dt"),
    ({"scheme": "newmark", "dt": 0.1, "end_time": 0}, "dynamics.end_time"),
    ({"scheme": "newmark", "dt": 0.1, "end_time": [1.0]}, "dynamics.end_time"),
    ({"scheme": "newmark", "dt": 0.1, "rayleigh": [-0.1, 0.0]}, "dynamics.rayleigh[0]"),
    ({"scheme": "newmark", "dt": 0.1, "rayleigh": [0.0, -1e-3]}, "dynamics.rayleigh[1]"),
    ({"scheme": "newmark", "dt": 0.1, "rayleigh": [0.1]}, "dynamics.rayleigh"),
    ({"scheme": "newmark", "dt": 0.1, "rayleigh": 0.1}, "dynamics.rayleigh"),
    ({"scheme": "newmark", "dt": 0.1, "rayleigh": [0.1, "x"]}, "dynamics.rayleigh[1]"),
    ({"dt": 0.1}, "dynamics.dt"),
    ({"scheme": "quasi_static", "rayleigh": [0.0, 0.0]}, "dynamics.rayleigh"),
    ({"scheme": "newmark", "dt": 0.1, "rho_infinity": 0.5}, "dynamics.rho_infinity"),
    ({"scheme": "generalized_alpha", "dt": 0.1, "rho_infinity": 1.5}, "dynamics.rho_infinity"),
    ({"scheme": "generalized_alpha", "dt": 0.1, "rho_infinity": "high"}, "dynamics.rho_infinity"),
])
def test_parse_dynamics_errors_name_the_key(raw: dict, key: str) -> None:
    with pytest.raises(ConfigError) as err:
        parse_dynamics(raw)
    assert str(err.value).startswith(f"{key}: "), str(err.value)
    assert "\n" not in str(err.value)


def test_parse_dynamics_refuses_a_non_table() -> None:
    with pytest.raises(ConfigError, match="^dynamics: must be a table"):
        parse_dynamics([1, 2])


@pytest.mark.slow
def test_mixed_taylor_hood_newmark_conserves_energy() -> None:
    """Nearly incompressible (nu = 0.45) P2/P1 bar with an initial velocity: kinetic energy + the mixed
    potential int W + p g - p^2/(2 kappa) dx is conserved by the average-acceleration rule."""
    problem = bar_problem("neo_hookean", 2, "mixed")
    dynamics = Dynamics(problem, RHO, "newmark", rayleigh=(0.0, 0.0), dt=0.02)
    solver = NewtonSolver(problem)
    dynamics.initialize(v0=lambda x: np.stack([0 * x[0], 0 * x[0], 1e-3 * x[0] ** 2]))
    energy = [dynamics.total_energy()]
    assert step_time(solver, dynamics, 2.0, 0.02, lambda record: energy.append(dynamics.total_energy()))
    energy = np.array(energy)
    drift = np.abs(energy - energy[0]).max() / energy[0]
    if MPI.COMM_WORLD.rank == 0:
        print(f"mixed P2/P1 Newmark: {energy.size - 1} steps, energy drift {drift:.2e}")
    assert energy.size == 101
    assert drift < 1e-4
    solver.destroy()


@pytest.mark.slow
def test_jiggle_after_the_support_stops() -> None:
    """The clamped end of a neo-Hookean P2 bar is moved sideways by A = 0.1 (smooth step over 0.3 s, a
    load-factor-dependent Dirichlet condition), then held: the bar overshoots and jiggles about its new rest
    position; Rayleigh damping takes the energy out (monotonically once the support holds) and
    kinetic + strain + dissipated stays nearly constant."""
    A, ramp = 0.1, 0.3

    def support(x: np.ndarray, t: float) -> np.ndarray:
        s = min(t / ramp, 1.0)
        return np.full(x.shape[1], A * s * s * (3.0 - 2.0 * s))

    problem = bar_problem("neo_hookean", 2, clamped=False)
    problem.add_dirichlet("xmin", [0, 1, 2], [0.0, support, 0.0], [False, True, False])
    dynamics = Dynamics(problem, RHO, "newmark", rayleigh=(1.0, 0.005), dt=0.02)
    solver = NewtonSolver(problem)
    dynamics.initialize(load_factor=0.0)
    tip = np.array([1.0, 0.1, 0.05])
    probes = Probes(problem.domain.mesh, {"tip": tip.tolist()})
    times, tips, energy, dissipated = [], [], [], []

    def on_step(record: TimeStepRecord) -> None:
        times.append(record.time)
        tips.append(probes.evaluate(problem.displacement())["tip"][1])
        energy.append(dynamics.kinetic_energy() + problem.total_energy())
        dissipated.append(dynamics.dissipated_energy)

    assert step_time(solver, dynamics, 3.0, 0.02, on_step)
    times, tips, energy, dissipated = map(np.array, (times, tips, energy, dissipated))
    held = times >= ramp - 1e-12
    overshoot = tips[held].max() - A
    e, d = energy[held], dissipated[held]
    balance = np.abs(e + d - (e[0] + d[0])).max() / e[0]
    if MPI.COMM_WORLD.rank == 0:
        print(f"jiggle: overshoot {overshoot:.4f} (A = {A}), tip at t = 3: {tips[-1]:.5f}, energy after hold "
              f"{e[0]:.3e} -> {e[-1]:.3e}, balance {balance:.2e}, tip mean/min/max last second "
              f"{tips[times > 2].mean():.4f} {tips[times > 2].min():.4f} {tips[times > 2].max():.4f}")
    assert overshoot > 0.1 * A  # it jiggles
    assert abs(tips[times > 2].mean() - A) < 0.1 * A  # about the new rest position
    assert np.all(np.diff(e) < 0.0)
    assert e[-1] < 0.1 * e[0]
    # the average-acceleration rule conserves energy exactly only for linear systems; at this amplitude,
    # with many modes excited, its nonlinear energy error is a few 1e-3
    assert balance < 1e-2
    solver.destroy()
