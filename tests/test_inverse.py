"""Activation estimation (model.experiments.inverse; issue 13 item 4): a target deformation made by a forward
run with hidden per-region activations (examples/activation_estimation.py: a two-region muscle block); L-BFGS-B
with adjoint gradients recovers them to 1e-4 without noise, and with 1 % noise on the target the error stays of
the order of the noise (the numbers are printed)."""

from __future__ import annotations

import numpy as np
from test_demos import example_module

example = example_module("activation_estimation")
HIDDEN = example.HIDDEN


def test_hidden_region_activations_are_recovered() -> None:
    estimate = example.recover(0.0)
    found = np.array([estimate.activations["lower"], estimate.activations["upper"]])
    print(f"recovered {found} (hidden {HIDDEN}, error {np.max(np.abs(found - HIDDEN)):.1e}) in {estimate.iterations} "
          f"iterations, {estimate.evaluations} evaluations: {estimate.message}")
    assert np.max(np.abs(found - HIDDEN)) < 1e-4, estimate


def test_noise_degrades_the_recovery_gracefully() -> None:
    """1 % noise (of the largest displacement, per node and component) on the target: the activations move by
    about 1e-2."""
    estimate = example.recover(0.01)
    found = np.array([estimate.activations["lower"], estimate.activations["upper"]])
    error = np.max(np.abs(found - HIDDEN))
    print(f"with 1 % noise: recovered {found} (hidden {HIDDEN}), error {error:.2e}")
    assert error < 0.05, estimate
