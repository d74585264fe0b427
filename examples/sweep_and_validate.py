"""Sweep a scenario with seeded episodes and validate the PEF's predictions against it.

    python examples/sweep_and_validate.py [OUT_DIR] [RUNS]

Writes the sweep (Parquet tables and ``report.html``) into OUT_DIR (default ``sweep``); run it
again to complete an interrupted sweep. Exits 1 when a check fails, like ``pefsim validate``.
"""

import sys

import pefsim


def main() -> int:
    """Sweep, validate, print the checks; 1 when a check fails."""
    out = sys.argv[1] if len(sys.argv) > 1 else "sweep"
    runs = int(sys.argv[2]) if len(sys.argv) > 2 else 8

    sc = pefsim.load("paper-two-markers")
    swept = pefsim.sweep(sc, out=out, runs=runs, workers=2, resume=True)
    report = pefsim.validate(swept)
    print(f"{report.scenario}: {report.runs} runs, {report.fixes} fixes, family alpha {report.alpha:g}")
    for c in report.checks:
        print(f"  {c.name:<12} {c.status.value:<15} {c.statistic:<28} {c.acceptance}")
    print("all checks pass" if report.passed else f"failed: {', '.join(report.failed)}")
    return 0 if report.passed else 1


if __name__ == "__main__":  # the sweep's worker processes import this file: run only as a script
    sys.exit(main())
