"""Costs of the PyBullet side: connect, build vs reset, stepping, control step, laser.

Run: ``python benchmarks/physics.py [--scenario warehouse]``. Each figure is the best of
several batches (robust to other load on the machine); ratios compare figures measured in
this same run. The last line is one JSON object.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time

import numpy as np

import scenarios
from sim.physics.config import PhysicsConfig
from sim.physics.laser import LaserSensor
from sim.physics.quiet import pb, silenced
from sim.physics.world import PhysicsWorld


def best_us(fn, number: int, repeat: int = 5) -> float:
    """Best mean time of ``fn()`` over ``repeat`` batches of ``number`` calls [µs]."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        best = min(best, (time.perf_counter() - t0) / number)
    return best * 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="warehouse")
    args = ap.parse_args()
    sc = scenarios.load(args.scenario)
    pose = sc.docks[0].pose if sc.docks else (1.0, 1.0, 0.0)

    def connect_disconnect():
        with silenced():
            cid = pb.connect(pb.DIRECT)
        pb.disconnect(physicsClientId=cid)

    res: dict[str, float] = {"connect_us": best_us(connect_disconnect, 10)}
    res["build_world_us"] = best_us(lambda: PhysicsWorld(sc).close(), 5)

    fast = dataclasses.replace(PhysicsConfig(), solver_iterations=20)
    with PhysicsWorld(sc, pose=pose) as w, PhysicsWorld(sc, fast, pose=pose) as ref:
        res["reset_us"] = best_us(lambda: w.reset(pose), 200)
        for world, key in ((w, "step_us"), (ref, "step_20_iterations_us")):
            world.robot.set_wheel_speeds(3.0, 3.5)
            cid = world.client
            res[key] = best_us(lambda cid=cid: pb.stepSimulation(physicsClientId=cid), 2000)
            world.reset(pose)

        def control_step():
            w.robot.set_wheel_speeds(3.0, 3.5)
            w.step(1)
            w.robot.wheel_angles()
            w.true_pose()

        res["step_motor_reads_us"] = best_us(control_step, 2000)
        w.reset(pose)
        laser = LaserSensor(w, sc.sensor_actual, sc.marker_positions())
        visible = laser.visible_all()
        res["visible_all_us"] = best_us(laser.visible_all, 500)
        rng = np.random.default_rng(0)
        if visible.any():
            i = int(np.flatnonzero(visible)[0])
            res["measure_us"] = best_us(lambda: laser.measure(i, rng), 500)

    res["markers"] = len(sc.markers)
    res["obstacles"] = len(sc.obstacles)
    res["build_over_reset"] = res["build_world_us"] / res["reset_us"]
    # What the accurate solver costs against the 20 iterations once used (see sim/physics/config.py).
    res["step_over_20_iterations"] = res["step_us"] / res["step_20_iterations_us"]
    res["control_step_over_bare_step"] = res["step_motor_reads_us"] / res["step_us"]
    for k, v in res.items():
        print(f"{k:30s} {v:12.2f}")
    print(json.dumps({"benchmark": "physics", "scenario": sc.name,
                      **{k: round(v, 3) for k, v in res.items()}}))


if __name__ == "__main__":
    main()
