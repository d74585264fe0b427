"""``pefsim place``: the fewest markers, among candidate sites, that keep the routes under eps_max.

Prints the marker count, whether it is proven optimal (else the lower bound), and the markers.
``-o`` writes the scenario with these markers (loadable, covering every coverable point);
``--png`` draws the sites, chosen markers and points to cover; ``--json`` prints the result.
With ``placement.existing = "keep"`` the scenario's markers stay and the listing marks which
markers are new. The work is :func:`pefsim.place`; this module parses and prints.

The layout is then checked with the planner: while a task has no admissible route (the drift
between fixes needs room under eps_max), the cover is solved again for a tighter target
(:mod:`planner.placement.plannable`); the target used is printed. ``--cover-only`` skips that.

Points that no subset of candidate sites can cover are always reported: without ``--json``
the summary is printed and the command fails with one line naming how many and the first
few (exit 2); with ``--json`` they are listed under ``uncovered`` as well, and the same line
goes to stderr (exit 2). ``-o`` and ``--png`` are still written in that case (covering the
coverable points).
"""

from __future__ import annotations

import argparse
import sys
import time

EPILOG = ("exit codes: 0 every point covered and every task plans; 2 bad input, some points cannot be "
          "covered by any candidate sites (listed under 'uncovered' with --json, else named in one error "
          "line), or a task has no admissible route even with the tightest cover target ('unplanned'); "
          "-o and --png are still written")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("place", help="fewest markers that keep the routes under eps_max",
                       description="The fewest markers, among candidate sites, that keep the routes "
                                   "(or free space) under eps_max.", epilog=EPILOG)
    p.add_argument("scenario", help="scenario file or built-in name")
    p.add_argument("-o", "--output", metavar="TOML", help="write the scenario with the placed markers")
    p.add_argument("--png", metavar="FILE", help="figure: candidate sites, chosen markers, points to cover")
    p.add_argument("--json", action="store_true",
                   help="print markers (id, position, kind, facing_deg, new), kept and new ids, count and "
                        "lower_bound (of the added markers), optimal, method, target, unplanned, points, sites, "
                        "finest_spacing, uncovered ([x, y] points no sites can cover)")
    p.add_argument("--method", choices=("auto", "milp", "greedy"), default="auto",
                   help="auto: exact (cutting planes, local search, HiGHS MILP) for small instances, else "
                        "greedy: LP rounding and local search with the LP lower bound")
    p.add_argument("--cover-only", action="store_true",
                   help="cover the routes under eps_max and stop: do not plan the tasks on the layout "
                        "(nor tighten the cover target until they plan)")
    p.add_argument("--time-limit", type=float, default=None, metavar="S",
                   help="safety time limit of the exact solver's LP and MILP rounds in seconds (default 30; "
                        "the result is decided by round, node and work counts, the same under any load)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import pefsim
    from cli import print_json

    sc = pefsim.load(args.scenario)
    t0 = time.monotonic()

    def progress(line: str) -> None:
        # stderr, so that --json keeps stdout to itself; a line per phase, flushed as it starts
        print(f"place [{time.monotonic() - t0:5.1f} s] {line}", file=sys.stderr, flush=True)

    result = pefsim.place(sc, method=args.method, out=args.output, png=args.png, plannable=not args.cover_only,
                          time_limit=args.time_limit, progress=progress)
    wrote_toml = result.written is not None
    n_bad = len(result.uncovered)
    if args.json:
        print_json(result.to_dict())
        _refuse(sc, result, args.output is not None and not wrote_toml)
        return 0
    state = "optimal" if result.optimal else f"not proven optimal, lower bound {result.lower_bound}"
    n_pts = len(result.points)
    eps = sc.planning.eps_max
    what = (f"{len(result.kept)} markers kept, {result.count} added" if result.kept
            else f"{result.count} markers")
    print(f"{sc.name}: {what} ({state}; {result.method}) cover {n_pts - n_bad} of {n_pts} "
          f"points under eps_max = {eps:g} m, from {len(result.sites)} candidate sites")
    if result.finest_spacing is not None:
        print(f"candidate sites refined to {result.finest_spacing:g} m where {sc.placement.spacing:g} m "
              "left points uncovered")
    if result.target < eps:
        why = ("so that every task plans (the drift between fixes needs room under eps_max)" if not result.unplanned
               else "trying to make every task plan")
        print(f"cover target tightened to {result.target:g} m {why}; the count and its bound are for that target")
    new = set(result.new_ids)
    for m in result.layout():
        tag = "new" if result.kept and m.id in new else ("kept" if result.kept else "")
        print(f"  {m.id:<5} {m.position[0]:8.3f} {m.position[1]:8.3f}  {tag}".rstrip())
    if wrote_toml:
        print(f"wrote {args.output}")
    if args.png is not None:
        print(f"wrote {args.png}")
    _refuse(sc, result, args.output is not None and not wrote_toml)
    return 0


def _refuse(sc, result, unwritten: bool) -> None:
    """Raise the one-line PlanningError of a placement that left points uncovered or tasks unplanned.

    ``unwritten``: ``-o`` was asked for but not written (no markers). With ``--json`` the
    summary is on stdout already; the line still goes to stderr (exit 2).
    """
    from scenarios.errors import PlanningError

    shortfall = result.shortfall(sc, unwritten=unwritten)
    if shortfall is not None:
        raise PlanningError(shortfall)
