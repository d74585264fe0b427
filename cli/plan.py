"""``pefsim plan``: candidate routes between two docks, their criteria, the choice and why."""

from __future__ import annotations

import argparse
import math


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("plan", help="candidate routes, criteria table, choice, schedule")
    p.add_argument("scenario", help="scenario file or built-in name")
    p.add_argument("--from", dest="start", metavar="A", help="start dock (default: the first task's)")
    p.add_argument("--to", dest="goal", metavar="B", help="goal dock (default: the first task's)")
    p.add_argument("--free", action="store_true",
                   help="free-space grid search even if there is a route network")
    p.add_argument("-o", "--output", metavar="FIG",
                   help="write the figure here (.png, .pdf or .svg; nothing is written without it)")
    p.add_argument("--rrd", metavar="FILE",
                   help="write a rerun recording of the map, the candidate routes and the schedule")
    p.add_argument("--alone", action="store_true",
                   help="a fleet: schedule each robot as if it drove alone (no traffic prediction)")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=run)


def _table(plan) -> str:
    head = (f"{'id':<4} {'route':<28} {'len[m]':>7} {'time[s]':>7} {'max τ[mm]':>9} {'mean τ[mm]':>10} "
            f"{'slow[s]':>7} {'traffic':>7} {'clear[m]':>8} {'turn[rad]':>9} {'score':>6}  note")
    rows = [head, "-" * len(head)]
    for i, c in enumerate(plan.candidates):
        route = "-".join(c.nodes) if c.nodes is not None else c.origin
        if len(route) > 28:
            route = route[:25] + "..."
        note = ("CHOSEN " if i == plan.chosen else "") + ("pareto" if c.pareto else "")
        if not c.admissible:
            note = "inadmissible: " + c.why_not
        score = f"{c.score:6.3f}" if math.isfinite(c.score) else "     -"
        slow = f"{c.slowdown:7.2f}" if math.isfinite(c.slowdown) else "      -"
        rows.append(f"{c.id:<4} {route:<28} {c.length:7.2f} {c.time:7.1f} {c.max_tau * 1000:9.2f} "
                    f"{c.mean_tau * 1000:10.2f} {slow} {c.traffic:7.2f} {c.min_clearance:8.2f} {c.turning:9.2f} "
                    f"{score}  {note.strip()}")
    return "\n".join(rows)


def run(args: argparse.Namespace) -> int:
    import pefsim
    from cli import print_json

    sc = pefsim.load(args.scenario)
    plan = pefsim.plan(sc, start=args.start, goal=args.goal, free=True if args.free else None, out=args.output,
                       rrd=args.rrd, traffic=not args.alone)
    if isinstance(plan, pefsim.FleetPlanSummary):  # a fleet's plan: a row per robot, no routes to compare
        if args.json:
            print_json(plan.to_dict())
        else:
            print(plan)
        return 0
    if args.json:
        print_json(plan.to_dict(sc))
        return 0
    kind = "free space" if plan.candidates and plan.candidates[0].nodes is None else "route network"
    print(f"{sc.name}: {plan.start} -> {plan.goal}, eps_max {plan.eps_max * 1000:g} mm, {kind}, "
          f"{len(plan.candidates)} candidates")
    print(_table(plan))
    print(f"chosen: {plan.reason}")
    if plan.schedule is not None:
        n_sw = sum(f.switch for f in plan.schedule.fixes)
        sch = plan.schedule
        n_slow = sum(f.slowed for f in sch.fixes)
        worst_fix = max(f.predicted_tau for f in sch.fixes)
        print(f"schedule: {len(sch.fixes)} fixes, {n_sw} marker switches, largest fix promise "
              f"{worst_fix * 1000:.2f} mm (moving fix), worst predicted error {sch.worst * 1000:.2f} mm; "
              f"{n_slow} fixes slowed down (+{sch.slowdown_time:.2f} s)")
    for path in (args.output, args.rrd):
        if path is not None:
            print(f"wrote {path}")
    return 0
