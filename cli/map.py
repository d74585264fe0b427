"""``pefsim map``: the PEF map of a scenario (PNG figure, NPZ arrays, JSON summary).

It prints a short summary (``--json``: a machine-readable one) and writes only what it is asked
to: the figure with ``-o``, the arrays with ``--npz``, a recording with ``--rrd``.
"""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("map", help="PEF map, navigation region, markers, obstacles")
    p.add_argument("scenario", help="scenario file or built-in name")
    p.add_argument("--model", choices=("exact", "parallelogram", "strips", "gdop"),
                   help="PEF model (default: the scenario's planning.pef_model); exact is slow")
    p.add_argument("--resolution", type=float, metavar="R",
                   help="cell size in metres (default: the scenario's planning.resolution)")
    p.add_argument("--speed", type=float, metavar="V",
                   help="the motion-aware PEF: the promise of a fix ending at each cell, driven at V m/s "
                        "(ranges one after another, carried by odometry); default the paper's static PEF")
    p.add_argument("-o", "--output", metavar="FIG", help="write the figure here (.png, .pdf or .svg)")
    p.add_argument("--npz", metavar="FILE",
                   help="write arrays: tau (ny,nx) [m, inf = no fix], x (nx,), y (ny,) cell centres [m], "
                        "best (ny,nx,k) marker indices (-1 = none)")
    p.add_argument("--rrd", metavar="FILE",
                   help="write a rerun recording of the static layers (map, region, markers, docks)")
    p.add_argument("--json", action="store_true", help="print a machine-readable summary")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import pefsim
    from cli import print_json

    sc = pefsim.load(args.scenario)
    pef_map = pefsim.pef_map(sc, model=args.model, resolution=args.resolution, speed=args.speed,
                             out=args.output, npz=args.npz, rrd=args.rrd)
    eps_max = sc.planning.eps_max
    summary = pef_map.to_dict()
    if args.json:
        print_json(summary)
        return 0
    ny, nx = summary["shape"]
    kind = "static" if args.speed is None else f"moving at {args.speed:g} m/s"
    print(f"{sc.name}: PEF {summary['model']} model ({kind}), k = {sc.sensor.markers_per_fix}, {nx} x {ny} cells of "
          f"{pef_map.cell_size[0]:.3g} x {pef_map.cell_size[1]:.3g} m")
    if not sc.markers:
        print("no markers: tau = inf everywhere (pefsim place finds where to put reflectors)")
    elif summary["tau_min"] is None:
        print("no free cell sees enough markers for a fix")
    else:
        print(f"tau over free cells with a fix: min {summary['tau_min'] * 1e3:.3g} mm, "
              f"median {summary['tau_median'] * 1e3:.3g} mm, max {summary['tau_max'] * 1e3:.3g} mm")
    print(f"navigation region (tau < eps_max = {eps_max * 1e3:g} mm): "
          f"{100 * summary['fraction_navigable']:.1f} % of free space")
    for path in (args.npz, args.output, args.rrd):
        if path is not None:
            print(f"wrote {path}")
    return 0
