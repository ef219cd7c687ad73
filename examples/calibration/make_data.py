"""Synthetic measurements for the calibration example: the specimen (specimen.toml) run with the "true"
parameters E = 1e4, nu = 0.3, its pulling force (reaction.xmax.x) and mid-length thinning (probe.top.z) at the
five load factors, with Gaussian noise of 1 % of each quantity's largest value (its sigma column). Writes
measured.csv next to this file (or to the path given).

    python examples/calibration/make_data.py [OUT.csv]
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from model.config import parse, read
from model.config.overrides import apply
from model.pipeline import run

HERE = Path(__file__).resolve().parent
TRUE = {"material.0.E": 1.0e4, "material.0.nu": 0.3}
NOISE = 0.01  # of each quantity's largest magnitude
SEED = 1
QUANTITIES = (("reaction", "xmax", 0, "reaction.xmax.x"), ("probes", "top", 2, "probe.top.z"))


def measurements(noise: float = NOISE, seed: int = SEED) -> pd.DataFrame:
    """The synthetic table: load_factor, quantity, value (with noise), sigma, and the exact value."""
    config = parse(apply(read(HERE / "specimen.toml"), TRUE), HERE)
    with tempfile.TemporaryDirectory() as tmp:
        summary = run(config, out=Path(tmp))
    rows = []
    for step in summary["steps"]:
        if not step["converged"]:
            continue
        for kind, name, component, quantity in QUANTITIES:
            source = step["reactions"] if kind == "reaction" else step["probes"]
            rows.append({"load_factor": round(step["load_factor"], 12), "quantity": quantity,
                         "exact": source[name][component]})
    frame = pd.DataFrame(rows)
    scale = frame.groupby("quantity")["exact"].transform(lambda v: v.abs().max())
    frame["sigma"] = noise * scale
    frame["value"] = frame["exact"] + np.random.default_rng(seed).normal(0.0, 1.0, len(frame)) * frame["sigma"]
    return frame[["load_factor", "quantity", "value", "sigma", "exact"]]


def main(out: Path) -> None:
    frame = measurements()
    frame[["load_factor", "quantity", "value", "sigma"]].to_csv(out, index=False, float_format="%.9g")
    print(f"{len(frame)} measurements written to {out}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "measured.csv")
