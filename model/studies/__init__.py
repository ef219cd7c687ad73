"""Studies over many runs: mesh convergence."""
