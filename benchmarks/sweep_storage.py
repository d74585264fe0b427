"""Benchmark a sweep directory's size and read time on ``warehouse``; the last line printed is one JSON object.

Measures, in one process:

- ``bytes_per_run_{all,fixes,none}``: the mean bytes per run of the ``runs``, ``steps`` and
  ``fixes`` parts (``sweep.json``'s ``bytes_per_run``) of a sweep written with each
  ``--steps`` mode, the same runs (seeds) in each; the target for the steps of ``all`` is
  <= 150 kB per warehouse run (``steps_target``);
- ``read_validation_vs_all``: the time validation takes to read the columns it needs
  (:data:`validation.data.STEP_COLUMNS` and ``FIX_COLUMNS``) against reading every column
  of the same parts, as a ratio of medians over ``--repeats`` alternating reads, so that other
  load on the machine hits both alike; ``read_report_vs_all`` likewise for the report's columns.

Usage: ``python benchmarks/sweep_storage.py [--runs N] [--workers K] [--repeats R]``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np  # noqa: E402

import scenarios  # noqa: E402
from sim.montecarlo import results  # noqa: E402
from sim.montecarlo.engine import sweep  # noqa: E402
from validation import data as vdata  # noqa: E402
from validation.report import page  # noqa: E402

SCENARIO = "warehouse"
STEPS_TARGET = 150_000


def read_times(root: Path, repeats: int) -> dict[str, float]:
    """Median seconds to read validation's, the report's, and all columns of ``root``'s steps and fixes."""
    readers = {
        "validation": lambda: (results.read_steps(root, columns=vdata.STEP_COLUMNS),
                               results.read_fixes(root, columns=vdata.FIX_COLUMNS)),
        "report": lambda: (results.read_steps(root, columns=page.STEP_COLUMNS),
                           results.read_fixes(root, columns=page.FIX_COLUMNS)),
        "all": lambda: (results.read_steps(root), results.read_fixes(root)),
    }
    times: dict[str, list[float]] = {k: [] for k in readers}
    for _ in range(repeats):  # alternate, so that a busy spell slows every reader alike
        for name, read in readers.items():
            start = time.perf_counter()
            read()
            times[name].append(time.perf_counter() - start)
    return {k: float(np.median(v)) for k, v in times.items()}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=4, help="runs per sweep (one sweep per --steps mode)")
    parser.add_argument("--workers", type=int, default=2, help="worker processes")
    parser.add_argument("--repeats", type=int, default=15, help="reads per reader for the read-time ratio")
    args = parser.parse_args(argv)
    scenario = scenarios.load(SCENARIO)
    out: dict = {"scenario": SCENARIO, "runs": args.runs, "cpus": os.cpu_count(), "load_before": os.getloadavg()[0]}
    with tempfile.TemporaryDirectory(prefix="pefsim-bench-storage-") as tmp:
        for mode in ("all", "fixes", "none"):
            summary = sweep(scenario, Path(tmp) / mode, runs=args.runs, workers=args.workers, steps=mode,
                            progress=False)
            if summary.crashed:
                raise RuntimeError(f"{summary.crashed} runs crashed in {summary.out}")
            out[f"bytes_per_run_{mode}"] = summary.bytes_per_run
        out["steps_target"] = STEPS_TARGET
        out["steps_within_target"] = out["bytes_per_run_all"]["steps"] <= STEPS_TARGET
        t = read_times(Path(tmp) / "all", args.repeats)
        out.update(read_all_s=round(t["all"], 4), read_validation_s=round(t["validation"], 4),
                   read_report_s=round(t["report"], 4),
                   read_validation_vs_all=round(t["validation"] / t["all"], 3),
                   read_report_vs_all=round(t["report"] / t["all"], 3))
    out["load_after"] = os.getloadavg()[0]
    for key, value in out.items():
        print(f"{key:>24}: {value}", file=sys.stderr)
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main()
