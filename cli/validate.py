"""``pefsim validate``: statistical validation of the PEF predictions against Monte-Carlo.

Runs a sweep with :func:`pefsim.sweep` (or takes one with ``--from``), judges it with
:func:`pefsim.validate` (every check of :mod:`validation.suite`) and prints a table; exit 1
when a check fails, 0 when all pass or do not apply.
"""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "validate", help="statistical validation: containment, bound, coverage, NEES/NIS, the plan",
        description="Run a Monte-Carlo sweep of a scenario (or read one with --from) and check the "
                    "predictions: the true position lies in every realised fault area, snapshot errors stay "
                    "under the PEF's tau and reach it, gaussian fixes cover their ellipses, the filter's "
                    "NEES and NIS lie in their chi2 intervals, and enough runs stay under eps_max. "
                    "Thresholds come from the family false-alarm probability --alpha, split evenly over the "
                    "statistical checks that apply. Exit 1 when a check fails.")
    p.add_argument("scenario", nargs="?", help="scenario file or built-in name (optional with --from)")
    p.add_argument("--runs", type=int, help="runs of the sweep (default: the scenario's montecarlo.runs)")
    p.add_argument("--from", dest="from_dir", metavar="DIR",
                   help="validate the existing sweep directory DIR (of pefsim mc) instead of running one")
    p.add_argument("--out", metavar="DIR", help="keep the sweep in DIR (default: a temporary directory)")
    p.add_argument("--workers", type=int, help="worker processes (default: CPU count)")
    p.add_argument("--alpha", type=float, default=None,
                   help="family false-alarm probability (default 0.01)")
    p.add_argument("--q-scale", type=float, default=None, metavar="Q",
                   help="NEGATIVE CONTROL ONLY: multiply the filter's process noise by Q (1 = as "
                        "declared) to see the consistency checks fail on a mis-tuned filter")
    p.add_argument("--alone", action="store_true",
                   help="NEGATIVE CONTROL ONLY, fleets: plan each robot's measurement schedule as if it drove "
                        "alone (no traffic prediction) to see the plan check fail when the others are ignored")
    p.add_argument("--blocking-scale", type=float, default=None, metavar="K",
                   help="NEGATIVE CONTROL ONLY, fleets: multiply the plan's predicted robot blocking by K "
                        "(also with --from) to see the blocking check fail on a prediction K times off")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.set_defaults(func=run)


def _check_args(args: argparse.Namespace) -> None:
    """Refuse flags that do not go together (each value is checked by the library, once)."""
    from scenarios.errors import ScenarioError

    if args.from_dir is not None:
        given = (("--runs", args.runs), ("--out", args.out), ("--workers", args.workers),
                 ("--q-scale", args.q_scale), ("--alone", args.alone or None))
        stray = [flag for flag, value in given if value is not None]
        if stray:
            raise ScenarioError(f"{stray[0]}: not with --from (the sweep in {args.from_dir} is already run)")
    elif args.scenario is None:
        raise ScenarioError("scenario: expected a scenario name or file (or --from DIR)")


def run(args: argparse.Namespace) -> int:
    import pefsim
    from cli import EXIT_CHECK_FAILED, EXIT_OK, print_json

    _check_args(args)
    if args.from_dir is not None:
        scenario = pefsim.load(args.scenario) if args.scenario is not None else None
        report = pefsim.validate(args.from_dir, alpha=args.alpha, scenario=scenario,
                                 blocking_scale=1.0 if args.blocking_scale is None else args.blocking_scale)
    else:
        report = pefsim.validate_scenario(args.scenario, runs=args.runs, out=args.out, workers=args.workers,
                                          alpha=args.alpha, q_scale=1.0 if args.q_scale is None else args.q_scale,
                                          alone=args.alone, progress=None,
                                          blocking_scale=1.0 if args.blocking_scale is None else args.blocking_scale)
    if args.json:
        print_json(report.to_dict())
    else:
        print(format_report(report))
    return EXIT_CHECK_FAILED if report.failed else EXIT_OK


def format_report(report) -> str:
    """Format the lines ``pefsim validate`` prints for a :class:`~validation.suite.ValidationReport`."""
    kept = report.sweep
    where = f"sweep {kept}" if kept else "temporary sweep, deleted"
    lines = [f"pefsim validate: {report.scenario}, {report.runs} runs, {report.fixes} fixes ({where}, "
             f"{report.wall_time or 0.0:.1f} s)"]
    if report.missing:
        lines.append(f"incomplete sweep: {report.missing} runs missing (pefsim mc SCENARIO --out {kept} --resume "
                     f"completes it); judged on the finished ones")
    # what made runs fail comes before any statistic: a robot pressed against a pillar fails every check
    lines.extend(report.causes)
    if report.q_scale != 1.0:
        lines.append(f"NEGATIVE CONTROL: the filter's process noise was multiplied by {report.q_scale:g}")
    if report.blocking_scale != 1.0:
        lines.append(f"NEGATIVE CONTROL: the plan's predicted robot blocking was multiplied by "
                     f"{report.blocking_scale:g}")
    if report.alone:
        lines.append("NEGATIVE CONTROL: each robot's measurement schedule was planned as if it drove alone "
                     "(no traffic prediction)")
    if report.alpha_per_check is not None:
        lines.append(f"family alpha {report.alpha:g} over {report.statistical} statistical checks: "
                     f"{report.alpha_per_check:.3g} each (Bonferroni)")
    rows = [("check", "statistic", "acceptance region", "alpha", "verdict")]
    for c in report.checks:
        a = "" if c.alpha is None else ("0 (exact)" if c.alpha == 0 else f"{c.alpha:.3g}")
        rows.append((c.name, c.statistic, c.acceptance, a, c.status.value))
    widths = [max(len(r[i]) for r in rows) for i in range(5)]
    for r in rows:
        lines.append("  ".join(cell.ljust(w) for cell, w in zip(r, widths, strict=True)).rstrip())
    if report.waits:
        lines.append("waits for zones (plan against simulation):")
        lines.extend(f"  {w}" for w in report.waits)
    lines.append("notes:")
    lines.extend(f"  {c.name}: {c.detail}" for c in report.checks)
    lines.append("FAILED: " + ", ".join(report.failed) if report.failed else "all applicable checks passed")
    return "\n".join(lines)

