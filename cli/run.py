"""``pefsim run``: one episode of a scenario task, with optional TUM trajectories and recording."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("run", help="one episode: plan, drive, sense, estimate",
                       description="Plan a task, drive it in PyBullet on the EKF estimate and report "
                                   "the errors against the PEF's prediction.")
    p.add_argument("scenario", help="built-in scenario name or path to a TOML file")
    p.add_argument("--task", type=int, default=0, metavar="I", help="index of the task to drive (default 0)")
    p.add_argument("--seed", type=int, default=None, metavar="N",
                   help="episode seed (default: the scenario's seed)")
    p.add_argument("--tum", metavar="DIR", help="write groundtruth.txt and estimate.txt (TUM format) into DIR")
    p.add_argument("--rrd", metavar="FILE", help="write a rerun recording of the episode")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import pefsim
    from cli import print_json
    from sim.jsonable import json_number

    scenario = pefsim.load(args.scenario)
    if scenario.is_fleet:
        return _run_fleet(args, scenario)
    result = pefsim.run_episode(scenario, args.seed, task=args.task, rrd=args.rrd, tum=args.tum)
    summary = dict(result.summary)
    if args.json:
        print_json({k: json_number(v) for k, v in summary.items()})
        return 0
    _print_human(scenario, args.task, summary)
    if args.tum:
        from interop.export.tum import TUM_FILES

        for name in TUM_FILES:
            print(f"wrote {Path(args.tum) / name}")
    if args.rrd:
        print(f"wrote {args.rrd}")
    return 0


def _run_fleet(args: argparse.Namespace, scenario) -> int:
    import pefsim
    from cli import print_json
    from scenarios import ScenarioError
    from sim.jsonable import json_number

    if args.tum:
        raise ScenarioError(f"--tum: not yet for a fleet scenario ({scenario.source} has [[robots]])")
    result = pefsim.run_fleet(scenario, args.seed, rrd=args.rrd)
    if args.json:
        print_json({"collisions": result.collisions, "duration": result.duration,
                    "robots": [{k: json_number(v) for k, v in r.result.summary.items()} for r in result.robots]})
        return 0
    mm = 1000.0
    print(f"{scenario.name}: fleet of {len(result.robots)}, seed {result.robots[0].result.summary['seed']}, "
          f"{result.duration:.1f} s, footprints overlapped {result.collisions} times")
    for r in result.robots:
        s = r.result.summary
        print(f"  {r.name}: {status_line(s)}")
        arrived = f"reached its dock at {s['arrival']:.1f} s" if s["reached"] else "NOT reached"
        print(f"  {r.name}: {arrived}, "
              f"waited {s['wait_time']:.1f} s; {s['fixes']} fixes, {s['robot_blocked']} scheduled lines of "
              f"sight hidden by robots, {s['fallback_fixes']} fallback, {s['failed_fixes']} failed; "
              f"max error {s['max_error'] * mm:.2f} mm (eps_max {s['eps_max'] * mm:.1f} mm), "
              f"{s['violations']} samples over")
    if args.rrd:
        print(f"wrote {args.rrd}")
    return 0


def status_line(s: dict) -> str:
    """Say what a run did (its ``status``, and where it touched, stalled or waited) in one line."""
    parts = [f"status {s.get('status', 'ok')}"]
    if s.get("collisions"):
        at = f"({s['contact_x']:.2f}, {s['contact_y']:.2f})" if s.get("contact_x") is not None else "(?)"
        along = f" s={s['contact_s']:.1f} m" if s.get("contact_s") is not None else ""
        parts.append(f"{s['collisions']} contact(s), first with {s.get('contact_with') or 'something'} at {at}"
                     f"{along} t={s['contact_t']:.1f} s")
    if s.get("stuck"):
        parts.append(f"no progress for {s['stall_time']:.1f} s (bound {s['stuck_bound']:.1f} s) from "
                     f"({s['stall_x']:.2f}, {s['stall_y']:.2f}) t={s['stall_t']:.1f} s")
    if s.get("deadlocked"):
        other = f" for {s['waited_for']}" if s.get("waited_for") else ""
        parts.append(f"waited {s['longest_wait']:.1f} s (bound {s['wait_bound']:.1f} s) at "
                     f"({s['wait_x']:.2f}, {s['wait_y']:.2f}){other}")
    return "; ".join(parts)


def _print_human(scenario, task_index: int, s: dict) -> None:
    task = scenario.tasks[task_index]
    mm = 1000.0
    print(f"{scenario.name}: task {task_index} {task.start} -> {task.goal}, seed {s['seed']}")
    print(f"  {status_line(s)}")
    print(f"  {'reached' if s['reached'] else 'NOT reached'} after {s['duration']:.1f} s "
          f"({s['steps']} steps, {s['fixes']} fixes)")
    print(f"  position error: rmse {s['rmse'] * mm:.2f} mm, max {s['max_error'] * mm:.2f} mm; "
          f"predicted bound max {s['max_predicted_tau'] * mm:.2f} mm; eps_max {s['eps_max'] * mm:.1f} mm")
    print(f"  samples over eps_max: {s['violations']}; mean NEES {s['mean_nees']:.2f} (3 dof), "
          f"mean NIS {s['mean_nis']:.2f} (1 dof)")
