"""``pefsim place``: the fewest markers, among candidate sites, that keep the routes under eps_max.

Prints the marker count, whether it is proven optimal (else the lower bound), and the markers.
``-o`` writes the scenario with these markers (loadable, covering every coverable point);
``--png`` draws the sites, chosen markers and points to cover; ``--json`` prints the result.

The layout is then checked with the planner: while a task has no admissible route (the drift
between fixes needs room under eps_max), the cover is solved again for a tighter target
(:mod:`planner.placement.plannable`); the target used is printed. ``--cover-only`` skips that.

Points that no subset of candidate sites can cover are always reported: without ``--json``
the summary is printed and the command fails with one line naming how many and the first
few (exit 2); with ``--json`` they are listed under ``uncovered`` and the exit code is 2 as
well. ``-o`` and ``--png`` are still written in that case (covering the coverable points).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from scenarios.errors import output_errors

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
                   help="print markers (id, position), count, lower_bound, optimal, method, "
                        "points, sites, uncovered ([x, y] points no sites can cover)")
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


def summary(result, target: float | None = None, unplanned: tuple[str, ...] = ()) -> dict:
    """Build the ``--json`` document of a placement (positions in metres)."""
    return {
        "target": target,
        "unplanned": list(unplanned),
        "count": int(result.count),
        "lower_bound": int(result.lower_bound),
        "optimal": bool(result.optimal),
        "method": result.method,
        "markers": [{"id": i, "position": [float(x), float(y)]} for i, (x, y) in result.markers],
        "points": int(len(result.points)),
        "sites": int(len(result.sites)),
        "uncovered": [[float(x), float(y)] for x, y in result.uncovered],
    }


def _plot(path: Path, scenario, result) -> None:
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    from sim.report.scene import draw_scene


    w, h = scenario.workspace.size
    fig = Figure(figsize=(8, 8 * h / w + 0.6))
    ax = fig.add_subplot()
    draw_scene(ax, scenario, labels=False)
    pts, sites = result.points, result.sites
    ax.plot(pts[:, 0], pts[:, 1], ".", ms=2, color="tab:blue", label=f"points to cover ({len(pts)})")
    ax.plot(sites[:, 0], sites[:, 1], "o", ms=4, mfc="none", color="0.4",
            label=f"candidate sites ({len(sites)})")
    if len(result.uncovered):
        u = result.uncovered
        ax.plot(u[:, 0], u[:, 1], "x", ms=4, color="tab:red", label=f"uncoverable ({len(u)})")
    for mid, (x, y) in result.markers:
        ax.annotate(mid, (x, y), textcoords="offset points", xytext=(4, 4), fontsize=8)
    if result.markers:
        m = [p for _, p in result.markers]
        ax.plot(*zip(*m, strict=True), "*", ms=14, color="tab:orange", mec="black",
                label=f"markers ({len(m)})")
    state = "optimal" if result.optimal else f"lower bound {result.lower_bound}"
    ax.set_title(f"{scenario.name}: {result.count} markers ({state}), "
                 f"eps_max = {scenario.planning.eps_max:g} m")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=2, fontsize=8)
    fig.tight_layout()
    with output_errors(path, "write the figure"):
        fig.savefig(path, dpi=120, bbox_inches="tight")


def run(args: argparse.Namespace) -> int:
    import scenarios
    from planner.placement.placement import MILP_TIME_LIMIT, place, write_scenario_with_markers
    from planner.placement.plannable import place_plannable
    from scenarios.errors import PlanningError
    from sim.cli import print_json

    sc = scenarios.load(args.scenario)
    limit = MILP_TIME_LIMIT if args.time_limit is None else args.time_limit
    if not limit > 0:
        raise PlanningError(f"--time-limit: expected a positive number of seconds, got {limit}")
    if args.cover_only:
        result, target, unplanned = place(sc, method=args.method, time_limit=limit), sc.planning.eps_max, ()
    else:
        pp = place_plannable(sc, method=args.method, time_limit=limit)
        result, target, unplanned = pp.result, pp.target, pp.unplanned
    written = []
    written_toml = args.output is not None and result.count >= sc.sensor.markers_per_fix
    if written_toml:
        written.append(write_scenario_with_markers(sc, result, args.output))
    if args.png is not None:
        _plot(Path(args.png), sc, result)
        written.append(args.png)
    n_bad = len(result.uncovered)
    if args.json:
        print_json(summary(result, target, unplanned))
        return 2 if n_bad or unplanned else 0
    state = "optimal" if result.optimal else f"not proven optimal, lower bound {result.lower_bound}"
    n_pts = len(result.points)
    print(f"{sc.name}: {result.count} markers ({state}; {result.method}) cover {n_pts - n_bad} of {n_pts} "
          f"points under eps_max = {sc.planning.eps_max:g} m, from {len(result.sites)} candidate sites")
    if target < sc.planning.eps_max:
        print(f"cover target tightened to {target:g} m so that every task plans (the drift between "
              f"fixes needs room under eps_max); the count and its bound are for that target")
    for mid, (x, y) in result.markers:
        print(f"  {mid:<5} {x:8.3f} {y:8.3f}")
    for path in written:
        print(f"wrote {path}")
    if n_bad:
        first = ", ".join(f"({x:.2f}, {y:.2f})" for x, y in result.uncovered[:3])
        note = "; -o not written: no markers" if args.output and not written_toml else ""
        hint = ("" if sc.placement.candidates else
                f"; candidate sites lie placement.spacing = {sc.placement.spacing:g} m apart: a finer spacing"
                + (", or posts (placement.marker_kind)," if sc.placement.marker_kind.value == "flat" else "")
                + " may cover them")
        raise PlanningError(f"{n_bad} of {n_pts} points cannot be covered by any candidate sites "
                            f"(first: {first}){hint}{note}")
    if unplanned:
        raise PlanningError(f"{len(unplanned)} of {len(sc.tasks)} tasks have no admissible route on the "
                            f"placed markers, even with the cover target at {target:g} m: {unplanned[0]}")
    return 0
