"""``pefsim plan``: candidate routes between two docks, their criteria, the choice and why."""

from __future__ import annotations

import argparse
import math

from scenarios.jsonable import json_number


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


def _fleet(args: argparse.Namespace, sc) -> int:
    import pefsim
    from cli import print_json
    from planner.fleet.summary import fleet_density

    fleet, summary = pefsim.plan_fleet(sc, traffic=not args.alone)
    if args.json:
        near, far = fleet_density(summary)
        print_json({"scenario": sc.name, "traffic": fleet.traffic,
                    "robots": [{k: json_number(v) for k, v in r.to_dict().items()} for r in summary],
                    "fleet": {"fixes_per_m_near": json_number(near), "fixes_per_m_far": json_number(far)}})
        return 0
    mode = "each scheduled as if it drove alone" if args.alone else "traffic-aware schedules"
    print(f"{sc.name}: a fleet of {len(summary)} robots, eps_max {sc.planning.eps_max * 1000:g} mm, {mode}")
    head = (f"{'robot':<8} {'tasks':<22} {'fixes':>5} {'E blocked LOS':>13} {'E blocked fixes':>15} "
            f"{'unprotected':>11} {'wait[s]':>7} {'time[s]':>7} {'alone[s]':>8} {'traffic[s]':>10} "
            f"{'fix/m near':>10} {'fix/m else':>10}")
    print(head)
    print("-" * len(head))
    for r in summary:
        tasks = ", ".join(r.tasks)
        tasks = tasks if len(tasks) <= 22 else tasks[:19] + "..."
        print(f"{r.name:<8} {tasks:<22} {r.fixes:5d} {r.expected_blocked_los:13.2f} {r.expected_blocked_fixes:15.2f} "
              f"{r.expected_unprotected:11.2f} {r.wait_time:7.1f} {r.time:7.1f} {r.alone_time:8.1f} "
              f"{r.traffic_cost:+10.1f} {r.fixes_per_m_near:10.2f} {r.fixes_per_m_far:10.2f}")
    near, far = fleet_density(summary)
    los, fixes = sum(r.expected_blocked_los for r in summary), sum(r.expected_blocked_fixes for r in summary)
    print(f"{'fleet':<8} {'':<22} {sum(r.fixes for r in summary):5d} {los:13.2f} {fixes:15.2f} "
          f"{sum(r.expected_unprotected for r in summary):11.2f} {'':>7} {'':>7} {'':>8} {'':>10} "
          f"{near:10.2f} {far:10.2f}")
    if fleet.note is not None and fleet.note.unprotected:
        left = ", ".join(f"{name} task {q}" for name, q in fleet.note.unprotected)
        print(f"not protected (no schedule survives a hidden marker there even slowed): {left}")
    print("E: expected over the timing spread of the robots; unprotected: blocked fixes without a fallback "
          "for every marker; traffic: time - alone (waits and slow-downs); near: within 1 m of a fix that, planned "
          "alone, others would likely hide; fleet: the robots' fixes near and elsewhere over their lengths there")
    return 0


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
    if sc.is_fleet and args.start is None and args.goal is None:
        return _fleet(args, sc)
    plan = pefsim.plan(sc, start=args.start, goal=args.goal, free=True if args.free else None, out=args.output,
                       rrd=args.rrd)
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
