"""CPU time per robot-second of a fleet episode against one robot driving the same tasks one after another.

Run: ``python benchmarks/fleet.py [--scenario hall-fleet] [--repeat 1]``. The fleet is
driven once per repeat (:func:`sim.episode.fleet.run_fleet_episode`: every robot in one world,
under zone control, robot bodies hiding reflectors); the baseline drives each robot's tasks as
single-robot episodes (:func:`sim.episode.drive.run_episode`, one per task, in the same
process and the same run). Planning is outside both clocks. Both sides are divided by the
simulated time their robots drove (a robot-second: one robot simulated for one second; a fleet
robot counts from the start to its last logged step, waits included, a lone episode its
duration), so that waits and the fleet's length do not hide what a robot costs. Targets: CPU
per robot-second of the fleet at most 1.5 x the lone robot's; the total ratio (the fleet's CPU
over the sequential episodes' CPU) at most 3.5. Each figure is the best of ``--repeat`` (robust
to other load). The last line is one JSON object.
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


def robot_seconds(result) -> float:
    """Return the simulated time the robots of ``result`` (a fleet's or a lone episode's) drove [s].

    The sum of their step logs' spans.
    """
    runs = [r.result for r in result.robots] if hasattr(result, "robots") else [result]
    return float(sum(r.steps.t[-1] - r.steps.t[0] for r in runs if len(r.steps.t)))


def best(fn, repeat: int) -> tuple[float, object]:
    """Return the smallest CPU time of ``repeat`` calls of ``fn`` [s] and the result of that call."""
    out = []
    for _ in range(repeat):
        t0 = time.process_time()
        res = fn()
        out.append((time.process_time() - t0, res))
    return min(out, key=lambda x: x[0])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="hall-fleet")
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
        fleet_cpu, fleet_res = best(lambda: run_fleet_episode(sc, seed=seed, world=fw, prepared=fleet), args.repeat)
        per_task = {i: best(lambda i=i: run_episode(sc, i, seed=seed, world=sw, prepared=single[i]), args.repeat)
                    for i in single}
    alone = sum(per_task[i][0] for i in tasks)
    fleet_rs = robot_seconds(fleet_res)
    alone_rs = sum(robot_seconds(per_task[i][1]) for i in tasks)
    ratio = fleet_cpu / alone
    per_rs = (fleet_cpu / fleet_rs) / (alone / alone_rs)
    print(f"{sc.name}: {len(sc.robots)} robots, tasks {tasks}")
    print(f"  fleet episode:                    {fleet_cpu:8.2f} s CPU, {fleet_rs:8.1f} robot-s, "
          f"{1000 * fleet_cpu / fleet_rs:6.2f} ms CPU per robot-s")
    print(f"  one robot, the tasks in sequence: {alone:8.2f} s CPU, {alone_rs:8.1f} robot-s, "
          f"{1000 * alone / alone_rs:6.2f} ms CPU per robot-s  "
          f"({', '.join(f'task {i} {c:.2f} s' for i, (c, _) in per_task.items())})")
    print(f"  CPU per robot-second: fleet / lone {per_rs:.2f} (target <= 1.5); total ratio {ratio:.2f} "
          f"(target <= 3.5)")
    print(json.dumps({"scenario": sc.name, "robots": len(sc.robots), "fleet_cpu_s": fleet_cpu,
                      "sequential_cpu_s": alone, "per_task_cpu_s": {i: c for i, (c, _) in per_task.items()},
                      "fleet_robot_s": fleet_rs, "sequential_robot_s": alone_rs,
                      "per_robot_second_ratio": per_rs, "ratio": ratio}))


if __name__ == "__main__":
    main()
