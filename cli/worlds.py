"""``pefsim worlds``: random honest worlds that plan, written as scenario files.

Prints one line per world (its file, the draws it took and what was drawn); ``--json`` prints
the same as a list. Files are written only into ``--out``.
"""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("worlds", help="random honest worlds that plan, as scenario files",
                       description="Draw random honest worlds (declared sensor and robot = the simulated "
                                   "ones) spanning layouts, reflectors, PEF models, noise, bearings, robots, "
                                   "origins and redundancy; redraw those that do not plan; write them "
                                   "into --out. The same seed gives the same files.")
    p.add_argument("--count", type=int, required=True, metavar="N", help="number of worlds")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="root seed (default 0)")
    p.add_argument("--out", required=True, metavar="DIR", help="directory to write <name>.toml into")
    p.add_argument("--max-size", type=float, default=None, metavar="M",
                   help="cap on the floors' sides in metres (12 and up): small floors, short tasks")
    p.add_argument("--bounded", action="store_true",
                   help="only uniform noise and set-membership PEF models (gdop drawn becomes strips), where "
                        "containment and the promise are deterministic claims")
    p.add_argument("--workers", type=int, default=1, metavar="K",
                   help="processes drawing worlds at once (default 1); the files are the same whatever K")
    p.add_argument("--json", action="store_true", help="print name, path, attempts and summary per world")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import pefsim
    from cli import print_json

    drawn = pefsim.iter_worlds(args.count, seed=args.seed, out=args.out, max_size=args.max_size,
                               bounded=args.bounded, workers=args.workers)
    if args.json:  # the small records only: the worlds themselves are not kept
        print_json([w.to_dict() for w in drawn])
        return 0
    for w in drawn:  # a line as each world is written
        print(f"wrote {w.path} (draw {w.attempts}): {w.summary[0]}", flush=True)
        for line in w.summary[1:]:
            print(f"    {line}")
    return 0
