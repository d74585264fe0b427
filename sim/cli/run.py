"""``pefsim run``: one episode of a scenario task, with optional TUM trajectories and recording."""

from __future__ import annotations

import argparse
import sys


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
    import scenarios
    from scenarios import OutputError, SimulationError
    from sim.cli import print_json
    from sim.episode.drive import check_task, prepare, run_episode
    from sim.jsonable import json_number

    scenario = scenarios.load(args.scenario)
    check_task(scenario, args.task)
    seed = scenario.seed if args.seed is None else args.seed
    if seed < 0:
        raise SimulationError(f"--seed: expected a non-negative integer, got {seed}")
    prepared = prepare(scenario, args.task)
    result = run_episode(scenario, args.task, seed=seed, prepared=prepared)
    summary = dict(result.summary)

    # Outputs after the episode: a failure to write one is reported, and the result is still printed.
    failures = []
    if args.tum:
        from sim.export.tum import write_tum

        try:
            write_tum(args.tum, result.steps.t, result.steps.true_pose, result.steps.est_pose)
        except OutputError as exc:
            failures.append(str(exc))
    if args.rrd:
        from sim.recording import write_episode_rrd

        try:
            write_episode_rrd(args.rrd, scenario, result, pef_map=prepared.pef.grid())
        except OutputError as exc:
            failures.append(str(exc))

    if args.json:
        print_json({k: json_number(v) for k, v in summary.items()})
    else:
        _print_human(scenario, args.task, summary)
    for msg in failures:
        print(f"pefsim: error: {msg}", file=sys.stderr)
    return 2 if failures else 0


def _print_human(scenario, task_index: int, s: dict) -> None:
    task = scenario.tasks[task_index]
    mm = 1000.0
    print(f"{scenario.name}: task {task_index} {task.start} -> {task.goal}, seed {s['seed']}")
    print(f"  {'reached' if s['reached'] else 'NOT reached'} after {s['duration']:.1f} s "
          f"({s['steps']} steps, {s['fixes']} fixes)")
    print(f"  position error: rmse {s['rmse'] * mm:.2f} mm, max {s['max_error'] * mm:.2f} mm; "
          f"predicted bound max {s['max_predicted_tau'] * mm:.2f} mm; eps_max {s['eps_max'] * mm:.1f} mm")
    print(f"  samples over eps_max: {s['violations']}; mean NEES {s['mean_nees']:.2f} (3 dof), "
          f"mean NIS {s['mean_nis']:.2f} (1 dof)")
