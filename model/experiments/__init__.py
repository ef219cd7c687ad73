"""Experiments built on runs: guided simulation (shape targeting) and the muscle experiments."""
