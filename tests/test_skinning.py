"""The skinning inverse problem (model.experiments.skinning): the adjoint gradient of the pose objective in the
sample angles passes the Taylor test (second-order remainder), and L-BFGS-B recovers the angles of a target pose
made by known angles."""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

from meshes.gingerbread import gingerbread
from model.domain.distribute import build_domain
from model.experiments.skinning import SkinningModel

TRUTH = np.array([0.2, 0.1, -0.7, 0.6, 0.15, -0.1])  # head, chest, hands, legs (SAMPLE_POINTS)


@pytest.fixture(scope="module")
def domain():
    comm = MPI.COMM_WORLD
    return build_domain(comm, gingerbread(size=0.12) if comm.rank == 0 else None)


def test_skinning_adjoint_gradient_taylor(domain) -> None:
    """J(theta + h d) - J(theta) - h g . d shrinks as h^2 (without g: as h), with the seed's terms (gamma = 1),
    the tracking of hands and head, at angles away from the rest pose."""
    model = SkinningModel(domain, gamma=1.0)
    model.set_target(model.pose(TRUTH))
    theta = 0.5 * TRUTH[::-1]
    direction = np.random.default_rng(4).standard_normal(len(TRUTH))
    J0, g = model.evaluate(theta)
    assert model.problem.solve() < 1e-10  # the KKT solve's relative residual
    with_g, without = [], []
    for k in range(4):
        h = 1e-2 / 2**k
        Jh = model.evaluate(theta + h * direction)[0]
        with_g.append(abs(Jh - J0 - h * g @ direction))
        without.append(abs(Jh - J0))
    order = [float(np.log2(a / b)) for a, b in zip(with_g, with_g[1:])]
    first = [float(np.log2(a / b)) for a, b in zip(without, without[1:])]
    assert all(abs(o - 2.0) < 0.1 for o in order), (order, first)
    assert all(o < 1.2 for o in first), (order, first)


def test_skinning_recovers_known_angles(domain) -> None:
    """Pose tracking over the whole body: the angles of the target are recovered to 1e-6 from zero."""
    model = SkinningModel(domain, tracked=("body",))
    target = model.pose(TRUTH)
    fit = model.fit(target)
    found = np.array(list(fit.angles.values()))
    assert np.max(np.abs(found - TRUTH)) < 1e-6, (fit.angles, fit.message)
    assert fit.objective < 1e-14 * max(fit.history[0][1], 1.0)
    values = MPI.COMM_WORLD.allgather(found)
    assert all(np.array_equal(v, values[0]) for v in values)  # the same iterates on every rank
