"""CPU time of a fleet episode against one robot driving the same tasks one after another.

Run: ``python benchmarks/fleet.py [--scenario warehouse-fleet] [--repeat 1]``. The fleet is
driven once per repeat (:func:`sim.episode.fleet.run_fleet_episode`: every robot in one world,
under zone control, robot bodies hiding reflectors); the baseline drives each robot's tasks as
single-robot episodes (:func:`sim.episode.drive.run_episode`, one per task, in the same
process and the same run) and adds their CPU times. Planning is outside both clocks. The
target is a ratio of at most 3.5. Each figure is the best of ``--repeat`` (robust to other load).
The last line is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

import scenarios  # noqa: E402
from sim.episode.drive import prepare, run_episode  # noqa: E402
from sim.episode.fleet import prepare_fleet, run_fleet_episode  # noqa: E402
from sim.physics.world import PhysicsWorld  # noqa: E402


def cpu(fn) -> float:
    """CPU time of ``fn()`` in this process [s]."""
    t0 = time.process_time()
    fn()
    return time.process_time() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="warehouse-fleet")
    ap.add_argument("--repeat", type=int, default=1)
    args = ap.parse_args()
    sc = scenarios.load(args.scenario)
    seed = np.random.SeedSequence(sc.seed, spawn_key=(0,))
    fleet = prepare_fleet(sc)
    tasks = [i for r in sc.robots for i in r.tasks]
    single = {i: prepare(sc, i, pef=fleet.pef) for i in sorted(set(tasks))}

    with PhysicsWorld(sc, fleet=True) as fw, PhysicsWorld(sc) as sw:
        # one warm-up of each, so that neither side pays for numba's cache loads
        run_fleet_episode(sc, seed=seed, world=fw, prepared=fleet, time_limit=2.0)
        run_episode(sc, tasks[0], seed=seed, world=sw, prepared=single[tasks[0]], time_limit=2.0)
        fleet_cpu = min(cpu(lambda: run_fleet_episode(sc, seed=seed, world=fw, prepared=fleet))
                        for _ in range(args.repeat))
        per_task = {i: min(cpu(lambda i=i: run_episode(sc, i, seed=seed, world=sw, prepared=single[i]))
                           for _ in range(args.repeat)) for i in single}
    alone = sum(per_task[i] for i in tasks)
    ratio = fleet_cpu / alone
    print(f"{sc.name}: {len(sc.robots)} robots, tasks {tasks}")
    print(f"  fleet episode:                    {fleet_cpu:8.2f} s CPU")
    print(f"  one robot, the tasks in sequence: {alone:8.2f} s CPU  "
          f"({', '.join(f'task {i} {t:.2f} s' for i, t in per_task.items())})")
    print(f"  ratio {ratio:.2f} (target <= 3.5)")
    print(json.dumps({"scenario": sc.name, "robots": len(sc.robots), "fleet_cpu_s": fleet_cpu,
                      "sequential_cpu_s": alone, "per_task_cpu_s": per_task, "ratio": ratio}))


if __name__ == "__main__":
    main()
