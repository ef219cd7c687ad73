"""Membranes (thesis sec. 3.3.3.1): a spherical balloon against its closed form, Hencky's clamped disc, inflation.

    .venv/bin/python examples/membrane_balloon.py [--size H] [--law stvk|neo_hookean] [--stretch L]
                                                  [--target-volume V]

1. Balloon: the octant x, y, z >= 0 of a unit sphere (symmetry conditions on its three edges), a plane-stress
   StVK or incompressible neo-Hookean membrane (forms.membrane) under the pressure p(lambda) of the closed form
   for stretches up to ``--stretch``; prints the stretch lambda = (V/V0)^(1/3) reached and the pressure's
   relative error against p = w'(lambda) / (R lambda^2).
2. Hencky: a clamped unit disc, StVK E = 1, nu = 0.3, h = 0.01, p a / (E h) = 1e-4; prints the centre
   deflection against Hencky's w0 = 0.6534 a (p a / E h)^(1/3).
3. Inflation workflow: the clamped disc inflated (neo-Hookean) until the enclosed volume is ``--target-volume``,
   closed with its base, tetrahedralised by gmsh, Laplace fibres; prints the pressure and the mesh size.
4. Contact: the balloon (StVK octant, ``--size``) in a rigid concentric sphere R_c = 1.1 (penalty k = 1); prints
   the mean node radius against the closed form (free, then R_c + delta, delta = lambda^2 (p - p_m(lambda))/k)
   and the contact fraction; then the inflation stopped when half the balloon touches (p against p_m(1.1)).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from mpi4py import MPI

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from forms.membrane import MembraneNeoHookean, MembraneStVK  # noqa: E402
from forms.obstacles import Sphere  # noqa: E402
from meshes.membrane import disc_surface, sphere_octant  # noqa: E402
from model.domain.distribute import build_domain  # noqa: E402
from model.experiments.membrane import inflate_patch  # noqa: E402
from model.problem import membrane as pm  # noqa: E402
from model.problem.membrane_contact import ObstacleContact  # noqa: E402
from model.solvers.membrane import inflate, inflate_to_volume  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=float, default=0.1, help="triangle size (sphere radius and disc radius 1)")
    parser.add_argument("--law", choices=("stvk", "neo_hookean"), default="neo_hookean")
    parser.add_argument("--stretch", type=float, default=1.3, help="largest balloon stretch (neo-Hookean: < 1.383)")
    parser.add_argument("--target-volume", type=float, default=0.5, help="volume of the inflated patch")
    args = parser.parse_args(argv)
    comm = MPI.COMM_WORLD
    say = print if comm.rank == 0 else (lambda *a, **k: None)
    law = MembraneStVK(1.0, 0.3, 0.01) if args.law == "stvk" else MembraneNeoHookean(1.0, 0.01)

    domain = build_domain(comm, sphere_octant(1.0, args.size) if comm.rank == 0 else None)
    problem = pm.MembraneProblem(domain, law, pm.radial_orientation(), {"x0": (0,), "y0": (1,), "z0": (2,)})
    V0 = problem.volume()
    steps = inflate(problem, pm.balloon_pressure(law, 1.0, np.linspace(1.02, args.stretch, 8)))
    say(f"balloon ({law.name}, size {args.size}): lambda, p, p / p_closed_form - 1")
    for s in steps:
        lam = (s.volume / V0) ** (1.0 / 3.0)
        say(f"  {lam:.4f}  {s.pressure:.6e}  {s.pressure / pm.balloon_pressure(law, 1.0, lam) - 1:+.2e}")

    stvk, ref = MembraneStVK(1.0, 0.3, 0.01), pm.hencky(0.3)
    disc = build_domain(comm, disc_surface(1.0, args.size) if comm.rank == 0 else None)
    problem = pm.MembraneProblem(disc, stvk, pm.axis_orientation(), {"rim": (0, 1, 2)})
    p = 1e-6
    w0 = ref.centre_deflection(1.0, p, stvk.young, stvk.thickness)
    problem.u.interpolate(lambda x: np.vstack([0 * x[0], 0 * x[0], w0 * (1 - x[0] ** 2 - x[1] ** 2)]))
    inflate(problem, [p])
    w = problem.max_component(2)
    say(f"Hencky (nu = 0.3, b0 = {ref.b0:.4f}, coefficient {ref.coefficient:.4f}): w0 = {w:.6e}, "
        f"closed form {w0:.6e}, error {w / w0 - 1:+.2e}")

    result = inflate_patch(MembraneNeoHookean(1.0, 0.01), args.target_volume, size=max(args.size, 0.1))
    cells = comm.allreduce(result.domain.mesh.topology.index_map(3).size_local, op=MPI.SUM)
    say(f"inflation: V = {result.steps[-1].volume:.6f} at p = {result.steps[-1].pressure:.6e} after "
        f"{len(result.steps)} steps; {cells} tetrahedra with Laplace fibres")
    stvk, R_c, k = MembraneStVK(1.0, 0.3, 0.01), 1.1, 1.0
    domain = build_domain(comm, sphere_octant(1.0, args.size) if comm.rank == 0 else None)
    problem = pm.MembraneProblem(domain, stvk, pm.radial_orientation(), {"x0": (0,), "y0": (1,), "z0": (2,)})
    cavity = ObstacleContact(problem, Sphere((0.0, 0.0, 0.0), R_c), k, inside=True)
    p_touch = float(pm.balloon_pressure(stvk, 1.0, R_c))
    say(f"cavity (R_c = {R_c}, k = {k}, p_m(R_c) = {p_touch:.6e}): p / p_m, mean radius, closed form, fraction")
    grid = np.linspace(1.0, 1.6, 4001)
    for factor in (0.5, 0.9, 1.5, 3.0):
        p = factor * p_touch
        inflate(problem, [p])
        x, area = cavity.positions(), cavity.lumped_area
        mean = comm.allreduce(float(np.linalg.norm(x, axis=1) @ area)) / comm.allreduce(float(area.sum()))
        lam = float(np.interp(p, pm.balloon_pressure(stvk, 1.0, grid), grid))
        if lam > R_c:
            lam = R_c
            for _ in range(60):
                lam = R_c + lam**2 * (p - float(pm.balloon_pressure(stvk, 1.0, lam))) / k
        say(f"cavity: {factor:.2f}  {mean:.6f}  {lam:.6f}  {cavity.contact_fraction():.3f}")
    problem = pm.MembraneProblem(build_domain(comm, sphere_octant(1.0, args.size) if comm.rank == 0 else None),
                                 stvk, pm.radial_orientation(), {"x0": (0,), "y0": (1,), "z0": (2,)})
    ObstacleContact(problem, Sphere((0.0, 0.0, 0.0), R_c), k, inside=True)
    steps = inflate_to_volume(problem, 10.0, 0.3 * p_touch, contact_fraction=0.5)
    say(f"contact-fraction stop (0.5): fraction {steps[-1].contact_fraction:.3f} at p = {steps[-1].pressure:.6e}, "
        f"p / p_m(R_c) - 1 = {steps[-1].pressure / p_touch - 1:+.2e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
