"""``pefsim mc``: a Monte-Carlo sweep of seeded episodes, written as Parquet, with a report."""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("mc", help="Monte-Carlo sweep: N seeded episodes to Parquet, with a report",
                       description="Run N seeded episodes of a scenario headless, write one row per run "
                                   "(runs.parquet), per step (steps/) and per fix (fixes/) as runs finish, "
                                   "and an HTML report (report.html).")
    p.add_argument("scenario", help="scenario file or built-in name")
    p.add_argument("--runs", type=int, help="number of runs (default: the scenario's montecarlo.runs, "
                                            "or the earlier sweep's with --resume)")
    p.add_argument("--task", type=int, help="drive only this task index (default: run i drives task i %% n)")
    p.add_argument("--workers", type=int, help="worker processes or Ray actors (default: CPU count)")
    p.add_argument("--executor", default="local", choices=("local", "ray"), help="where runs execute")
    p.add_argument("--address", help="Ray cluster address (with --executor ray; default starts one)")
    p.add_argument("--out", help="output directory (default: mc-<scenario name>)")
    p.add_argument("--resume", action="store_true", help="complete the missing runs of --out")
    p.add_argument("--rrd-every", type=int, default=0, metavar="M",
                   help="write a rerun recording of every M-th run to OUT/recordings/")
    p.add_argument("--steps", choices=("all", "fixes", "none"), default=None,
                   help="per-step rows to keep: every control step (all, the default), the steps at fix "
                        "times (fixes: the N-run NEES test then does not apply), or none; --resume keeps "
                        "the sweep's choice")
    p.add_argument("--alone", action="store_true",
                   help="NEGATIVE CONTROL ONLY, fleets: plan each robot's measurement schedule as if it drove "
                        "alone (no traffic prediction); the directory records it")
    p.add_argument("--no-report", action="store_true", help="skip report.html")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import pefsim
    from cli import print_json

    scenario = pefsim.load(args.scenario)
    summary = pefsim.sweep(scenario, args.out, runs=args.runs, task=args.task, workers=args.workers,
                           executor=args.executor, address=args.address, resume=args.resume,
                           rrd_every=args.rrd_every, steps=args.steps, alone=args.alone, progress=None,
                           report=not args.no_report)
    if args.json:
        print_json(summary.to_dict())
        return 0
    print(format_summary(summary))
    return 0


def format_summary(s) -> str:
    """Format a :class:`~sim.montecarlo.engine.SweepSummary` as the lines ``pefsim mc`` prints."""
    did = f"{s.ok} ok, {s.collided} collided, {s.stuck} stuck, {s.deadlocked} deadlocked, {s.crashed} crashed"
    lines = [f"{s.runs} runs in {s.out}: {did}, {s.reached} reached the goal, {s.violation_runs} exceeded eps_max"]
    if getattr(s, "robots", 0):
        lines[0] = (f"{s.runs} robot runs ({s.robots} robots a run) in {s.out}: {did}, "
                    f"{s.reached} reached the goal, {s.violation_runs} exceeded eps_max")
    if s.runs:
        lo, hi = s.success_ci
        lines.append(f"success {s.success_fraction:.3f} (95% CI {lo:.3f} .. {hi:.3f}), "
                     f"target {s.success_target:.3f}")
    if s.executed:
        rate = f", {s.runs_per_minute:.1f} runs/min" if s.runs_per_minute else ""
        lines.append(f"this invocation ran {s.executed} runs in {s.wall_time:.1f} s{rate}")
    else:
        lines.append("nothing to run: every run was already finished")
    if s.bytes_per_run:
        b = s.bytes_per_run
        lines.append(f"bytes per run: {b['total'] / 1e3:.1f} kB (steps {b['steps'] / 1e3:.1f} kB, --steps "
                     f"{s.steps}; fixes {b['fixes'] / 1e3:.1f} kB; runs {b['runs'] / 1e3:.1f} kB)")
    if s.report:
        lines.append(f"report: {s.report}")
    return "\n".join(lines)
