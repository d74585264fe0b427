"""Benchmark the Monte-Carlo harness on ``paper-docks``; the last line printed is one JSON object.

Measures, in one process and against baselines taken in the same run:

- ``episode_s``: one bare ``run_episode`` call (world reused, plan prepared, no harness);
- ``harness_overhead``: a ``--workers 1`` sweep's wall time against the sum of its episodes'
  own times (the runs table's ``wall_time``), minus 1: what the harness adds per run (records,
  Parquet parts, progress), measured in the same time window so other load cancels out
  (target <= 0.05); ``sweep_vs_bare`` compares the sweep's time per run with ``episode_s``;
- ``speedup_2``: the 2-worker local pool's throughput against 1 worker (target >= 1.8 on a
  2-core machine; it includes the pool's start-up and each worker's first, slower run);
- ``ray_overhead``: a 2-actor Ray sweep's wall time against the 2-worker pool's, minus 1
  (target <= 0.15), with the cluster started beforehand (``ray_init_s`` reported apart).

``cpu_per_run_1``/``cpu_per_run_2`` (CPU seconds per run in-process / in a worker) and the load
average before and after are printed too: wall-clock ratios mean little on a machine that
other jobs keep busy, while equal CPU per run shows the workers pay no per-run penalty.

The size of a sweep directory per ``--steps`` mode and the read time of validation's
columns are measured by ``benchmarks/sweep_storage.py`` (on ``warehouse``).

Usage: ``python benchmarks/montecarlo.py [--runs N] [--no-ray]``.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np  # noqa: E402

import scenarios  # noqa: E402
from sim.montecarlo import results  # noqa: E402
from sim.montecarlo.engine import default_api, sweep  # noqa: E402

SCENARIO = "paper-docks"


def bare_episodes(scenario, runs: int) -> float:
    """Mean seconds of one episode called directly (after one untimed warm-up run)."""
    api = default_api()
    prepared = api.prepare(scenario, 0)
    world = api.make_world(scenario)
    try:
        def seed(i: int) -> np.random.SeedSequence:
            return np.random.SeedSequence(scenario.seed, spawn_key=(i,))

        api.run_episode(scenario, 0, seed(10_000), world, prepared)
        start = time.perf_counter()
        for i in range(runs):
            api.run_episode(scenario, 0, seed(i), world, prepared)
        return (time.perf_counter() - start) / runs
    finally:
        world.close()


def timed_sweep(scenario, out: Path, runs: int, workers: int,
                executor: str = "local") -> tuple[float, float, float]:
    """Time a sweep: wall seconds of its runs, sum of its episodes' wall times, mean CPU seconds.

    Planning is excluded; the start-up of workers is included.
    """
    summary = sweep(scenario, out, runs=runs, workers=workers, executor=executor, progress=False)
    if summary.crashed:
        raise RuntimeError(f"{summary.crashed} runs crashed in {out}")
    table = results.read_runs(out)
    episodes = float(np.sum(table.column("wall_time").to_numpy()))
    return summary.wall_time, episodes, float(np.mean(table.column("cpu_time").to_numpy()))


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=40, help="runs per measurement")
    parser.add_argument("--no-ray", action="store_true", help="skip the Ray measurement")
    args = parser.parse_args(argv)
    scenario = scenarios.load(SCENARIO)
    n = args.runs
    out: dict = {"scenario": SCENARIO, "runs": n, "cpus": os.cpu_count(), "load_before": os.getloadavg()[0]}
    with tempfile.TemporaryDirectory(prefix="pefsim-bench-mc-") as tmp:
        tmp = Path(tmp)
        episode_s = bare_episodes(scenario, n)
        wall_1, episodes_1, cpu_1 = timed_sweep(scenario, tmp / "w1", n, 1)
        wall_2, _, cpu_2 = timed_sweep(scenario, tmp / "w2", n, 2)
        out.update(episode_s=round(episode_s, 4), runs_per_minute_1=round(60 * n / wall_1, 2),
                   runs_per_minute_2=round(60 * n / wall_2, 2), speedup_2=round(wall_1 / wall_2, 3),
                   speedup_target=1.8, harness_overhead=round(wall_1 / episodes_1 - 1, 4),
                   harness_overhead_target=0.05, sweep_vs_bare=round(wall_1 / (n * episode_s), 3),
                   cpu_per_run_1=round(cpu_1, 3), cpu_per_run_2=round(cpu_2, 3))
        if not args.no_ray and importlib.util.find_spec("ray") is not None:
            from sim.montecarlo.executors import start_ray

            start = time.perf_counter()
            ray, _ = start_ray(2, None)
            out["ray_init_s"] = round(time.perf_counter() - start, 2)
            try:
                wall_ray, _, _ = timed_sweep(scenario, tmp / "ray", n, 2, executor="ray")
            finally:
                ray.shutdown()
            out.update(runs_per_minute_ray_2=round(60 * n / wall_ray, 2),
                       ray_overhead=round(wall_ray / wall_2 - 1, 4), ray_overhead_target=0.15)
        else:
            out["ray_overhead"] = None
    out["load_after"] = os.getloadavg()[0]
    for key, value in out.items():
        print(f"{key:>24}: {value}", file=sys.stderr)
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main()
