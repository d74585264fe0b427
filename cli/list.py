"""``pefsim list``: the built-in scenarios."""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("list", help="built-in scenarios")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import pefsim
    from cli import print_json

    rows = [pefsim.load(name).overview() for name in pefsim.builtin_names()]
    if args.json:
        print_json(rows)
        return 0
    w = max(len(r["name"]) for r in rows)
    for r in rows:
        size = f"{r['size'][0]:g} x {r['size'][1]:g} m"
        print(f"{r['name']:<{w}}  {size:>12}  {r['markers']:>2} markers  {r['description']}")
    return 0
