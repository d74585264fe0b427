"""``pefsim watch``: a live rerun view of a scenario, updated whenever its files are saved.

Shows the map and the route network of each version first and its plans when they follow, then
prints one line per update (``updated in 0.23 s, planned in 0.61 s: hall.toml: 14 markers, 3 tasks
planned``: the times to the map shown and to the plans shown) and
one ``pefsim: error: ...`` line on stderr for a version of the files that is refused (the last
good view stays). Ctrl-C ends it with exit 0 and a finished recording.
"""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("watch", help="live rerun view of a scenario, updated whenever its files are saved")
    p.add_argument("scenario", help="scenario file (a built-in name follows the library's file)")
    out = p.add_mutually_exclusive_group()
    out.add_argument("--save", metavar="FILE.rrd", help="write the recording here instead of opening a viewer")
    out.add_argument("--connect", metavar="ADDR", nargs="?", const="",
                     help="stream to a running viewer (default rerun+http://127.0.0.1:9876/proxy)")
    # for tests and scripts: end after N updates (the first view included)
    p.add_argument("--max-updates", type=int, metavar="N", help=argparse.SUPPRESS)
    p.add_argument("--interval", type=float, metavar="S", help=argparse.SUPPRESS)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import sys

    import pefsim

    def on_update(update) -> None:
        print(update.line(), flush=True)

    def on_error(exc: pefsim.PefsimError) -> None:
        print(f"pefsim: error: {exc}", file=sys.stderr, flush=True)

    try:
        pefsim.watch(args.scenario, save=args.save, connect=args.connect, on_update=on_update, on_error=on_error,
                     interval=args.interval, max_updates=args.max_updates)
    except KeyboardInterrupt:  # Ctrl-C is how a watch ends; the recording was finished on the way out
        pass
    if args.save is not None:
        print(f"wrote {args.save}")
    return 0
