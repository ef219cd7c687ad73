"""``python -m model converge CONFIG --refine KEY=V1,V2,V3 --qoi SPEC [--qoi ...] [--out DIR]``: a
mesh-convergence study (model.studies.convergence) from the command line.

Exit codes: 0 the study was written (its warnings are printed, they are findings), 1 a run failed and
fewer than three meshes were left for a QoI, 2 bad input (the one-line error names the key).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from mpi4py import MPI


def add_parser(sub: Any) -> argparse.ArgumentParser:
    """The ``converge`` parser, added to the top-level subparsers ``sub``; its handler is ``main``."""
    from model.helptext import Formatter

    parser = sub.add_parser(
        "converge", help="mesh-convergence study: observed order, Richardson extrapolation and GCI per QoI",
        description="Runs CONFIG once per value of the refined key and reports, per quantity of interest, the "
                    "observed order, the Richardson-extrapolated value and the grid convergence index of the three "
                    "finest meshes (Celik et al. 2008, ASME V&V 20).",
        epilog="examples:\n  softtissue converge examples/cook.toml --refine mesh.cells=[4,4,1],[8,8,1],[16,16,1] "
               "--qoi probe:top_right:y\n  softtissue converge examples/isometric.toml "
               "--refine mesh.size=0.004,0.003,0.0022 --qoi reaction:insertion:z --out results/iso_conv\n\n"
               "exit codes: 0 written (warnings are findings), 1 fewer than three meshes ran, 2 bad input",
        formatter_class=Formatter)
    parser.add_argument("config", type=Path, help="the configuration file")
    parser.add_argument("--refine", required=True, metavar="KEY=V1,V2,V3",
                        help="the key that sets the mesh size and its values (TOML; three or more), e.g. "
                             "mesh.cells=4,8,16 or mesh.size=0.004,0.003,0.002 or 'mesh.cells=[4,4,4],[8,8,8],...'")
    parser.add_argument("--qoi", action="append", required=True, metavar="SPEC",
                        help="probe:NAME:COMPONENT, reaction:BOUNDARY:COMPONENT (component x|y|z) or energy[:KEY] "
                             "(default strain_energy); repeat for several")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override a key of every run (TOML value), e.g. output.vtu=false")
    parser.add_argument("--order", type=float, default=None,
                        help="formal order of the QoIs, for the out-of-range warning (p > 2 x order)")
    parser.add_argument("--out", type=Path, default=None,
                        help="output folder (default results/converge_<config name>): mesh_K/ per run, "
                             "convergence.csv, convergence_meshes.csv, convergence.md, convergence.png")
    parser.set_defaults(handler=main)
    return parser


def main(args: argparse.Namespace) -> int:
    """Run the study of ``args``; the exit code."""
    from model.config.overrides import parse_assignment
    from model.errors import ConfigError
    from model.studies.convergence import converge, parse_refine

    rank0 = MPI.COMM_WORLD.rank == 0
    out = args.out if args.out is not None else Path("results") / f"converge_{args.config.stem}"
    try:
        key, values = parse_refine(args.refine)
        overrides = dict(parse_assignment(a) for a in args.set)
        study = converge(args.config, {key: values}, args.qoi, out, overrides=overrides, formal_order=args.order)
    except ConfigError as err:
        if rank0:
            print(f"error: {err}", file=sys.stderr, flush=True)
        return 2
    except ValueError as err:  # fewer than three meshes with a value (failed runs)
        if rank0:
            print(f"error: {err}", file=sys.stderr, flush=True)
        return 1
    if rank0:
        meshes = study.meshes
        for _, row in meshes.iterrows():
            print(f"{key} = {row[key]}: h {row['h']:.4g}, {row['cells']} cells, {row['dofs']} dofs, "
                  f"{row['wall_time_s']:.1f} s, {row['status']}")
        for label, r in study.results.items():
            print(f"{label}: p {r.p:.3f}, phi_ext {r.phi_ext21:.6g}, GCI_fine {100 * r.gci_fine21:.3g} %, "
                  f"GCI_medium {100 * r.gci_medium32:.3g} %, ratio {r.asymptotic_ratio:.3f}")
        for warning in study.warnings:
            print(f"warning: {warning}")
        print(f"written: {', '.join(str(p) for p in study.files.values())}")
    return 0
