"""``pefsim run``: one episode of a scenario task, with optional TUM trajectories and recording."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("run", help="one episode: plan, drive, sense, estimate",
                       description="Plan a task, drive it in PyBullet on the EKF estimate and report "
                                   "the errors against the PEF's prediction.")
    p.add_argument("scenario", help="built-in scenario name or path to a TOML file")
    p.add_argument("--task", type=int, default=None, metavar="I",
                   help="index of the task a lone robot drives (default 0; a fleet's robots drive theirs)")
    p.add_argument("--seed", type=int, default=None, metavar="N",
                   help="episode seed (default: the scenario's seed)")
    p.add_argument("--tum", metavar="DIR", help="write groundtruth.txt and estimate.txt (TUM format) into DIR "
                                                "(a fleet's: into DIR/<robot>/)")
    p.add_argument("--rrd", metavar="FILE", help="write a rerun recording of the episode")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import pefsim
    from cli import print_json

    scenario = pefsim.load(args.scenario)
    result = pefsim.run_episode(scenario, args.seed, task=args.task, rrd=args.rrd, tum=args.tum)
    if args.json:
        print_json(result.to_dict())
        return 0
    print("\n".join(result.lines(scenario)))
    if args.tum:
        from interop.export.tum import TUM_FILES

        for r in result.robots:
            folder = Path(args.tum) if r.name is None else Path(args.tum) / r.name
            for name in TUM_FILES:
                print(f"wrote {folder / name}")
    if args.rrd:
        print(f"wrote {args.rrd}")
    return 0
