"""Skinning by the adjoint method: the gingerbread man reaches a pose by rotation angles at six sample points.

    .venv/bin/python examples/skinning.py [--size 0.1] [--out results/skinning]

The gingerbread mesh (meshes.gingerbread), feet pinned at rest (penalty k = 100), mixed ARAP (per-triangle
symmetric S, P1 positions x, multiplier of grad x = R(theta) S); angles theta_j at SAMPLE_POINTS (head, chest,
hands, legs) spread to every triangle by biharmonic weights (model.experiments.skinning). A target pose is made by
the known angles TRUTH; L-BFGS-B with adjoint gradients starts from zero angles and minimises the pose objective
1/2 int_tracked |x - x_target|^2, tracking either the whole body or only the hands and head. Prints a table
(truth, found, error per angle, J, iterations, time) and writes it (table.md) with a picture (poses.png: rest,
target, found) to --out. Used by notebooks/skinning.py.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from mpi4py import MPI

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from meshes.gingerbread import gingerbread  # noqa: E402
from model.domain.distribute import build_domain  # noqa: E402
from model.experiments.skinning import SAMPLE_POINTS, TRACKED, SkinningModel  # noqa: E402

#: the known angles of the target pose (radians), in the order of SAMPLE_POINTS
TRUTH = np.array([0.2, 0.1, -0.7, 0.6, 0.15, -0.1])
CASES = {"body": ("body",), "hands+head": TRACKED}


def run(size: float = 0.1, cases: dict[str, tuple[str, ...]] | None = None) -> dict:
    """Fit each case (name -> tracked regions) to the target of TRUTH; returns the domain, the rest, target
    and found positions (P1 Functions) and per case the SkinningFit."""
    comm = MPI.COMM_WORLD
    domain = build_domain(comm, gingerbread(size=size) if comm.rank == 0 else None)
    out: dict = {"domain": domain, "fits": {}, "found": {}}
    for name, tracked in (cases or CASES).items():
        model = SkinningModel(domain, tracked=tracked)
        out.setdefault("rest", model.pose(np.zeros(len(TRUTH))))
        target = model.pose(TRUTH)
        out.setdefault("target", target)
        out["fits"][name] = model.fit(target)
        out["found"][name] = model.positions()
        out.setdefault("dofs", model.problem.space.dofmap.index_map.size_global)
        model.problem.destroy()
    return out


def gather_triangulation(domain, positions) -> tuple[np.ndarray, np.ndarray] | None:
    """(points (n, 2), triangles (m, 3)) of the positions on rank 0 (None elsewhere): each rank's owned cells
    with the coordinates of their vertices."""
    from model import compat

    V = positions.function_space
    owned = domain.mesh.topology.index_map(2).size_local
    dofs = compat.cell_dofs(V.dofmap)[:owned]
    values = positions.x.array.reshape(-1, 2)
    local = values[dofs].reshape(-1, 2)
    parts = domain.mesh.comm.gather(local, root=0)
    if domain.mesh.comm.rank != 0:
        return None
    points = np.concatenate(parts)
    return points, np.arange(len(points)).reshape(-1, 3)


def table(out: dict) -> str:
    """The results as a markdown table."""
    names = list(SAMPLE_POINTS)
    lines = ["| tracked | " + " | ".join(names) + " | max error | J | iterations | evaluations | time (s) |",
             "|---" * (len(names) + 6) + "|",
             "| truth | " + " | ".join(f"{t:.4f}" for t in TRUTH) + " | | | | | |"]
    for case, fit in out["fits"].items():
        found = np.array([fit.angles[n] for n in names])
        lines.append(f"| {case} | " + " | ".join(f"{v:.4f}" for v in found)
                     + f" | {np.max(np.abs(found - TRUTH)):.1e} | {fit.objective:.2e} | {fit.iterations} | "
                     f"{fit.evaluations} | {fit.time_s:.1f} |")
    return "\n".join(lines)


def picture(out: dict, path: Path) -> None:
    """rest, target and found poses (triplot) side by side."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shapes = {"rest": out["rest"], "target (known angles)": out["target"]}
    shapes.update({f"found ({case})": x for case, x in out["found"].items()})
    gathered = {name: gather_triangulation(out["domain"], x) for name, x in shapes.items()}
    if MPI.COMM_WORLD.rank != 0:
        return
    fig, axes = plt.subplots(1, len(gathered), figsize=(3.2 * len(gathered), 3.6))
    for ax, (name, (points, triangles)) in zip(axes, gathered.items()):
        ax.triplot(points[:, 0], points[:, 1], triangles, lw=0.3, color="C0" if name == "rest" else "C1")
        ax.set_title(name, fontsize=9)
        ax.set_aspect("equal")
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=float, default=0.1, help="element size of the gingerbread mesh")
    parser.add_argument("--out", type=Path, default=Path("results/skinning"), help="folder for table.md and poses.png")
    args = parser.parse_args(argv)
    out = run(args.size)
    text = table(out)
    if MPI.COMM_WORLD.rank == 0:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "table.md").write_text(text + "\n")
        print(f"gingerbread size {args.size}: {out['dofs']} unknowns (S, x, lambda)")
        print(text)
    picture(out, args.out / "poses.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
