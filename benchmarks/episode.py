"""Episode cost against the physics alone, the real-time factor, reset vs build, and recording.

The baseline replays the episode's own wheel commands open loop, so it steps the same rolling
robot for the same number of physics steps; the ratio is what planning-free control, odometry,
the EKF, the laser and the fixes add on top.

Every figure is a ratio against a baseline measured in this run, in this process, so the
numbers compare across machines. The headline ``episode_over_bare`` is the median, over
interleaved pairs, of one episode's time over the baseline run just before it: on a shared host
whose speed drifts by tens of per cent within a minute, the two runs of a pair see the same
machine, while the best episode and the best baseline may come from different moments
(``episode_over_bare_best`` reports that ratio too); ``episode_over_bare_cpu`` is the median
pair ratio on the thread's CPU clock, which a loaded host does not inflate by the time other
processes held the core. Run: ``python benchmarks/episode.py [SCENARIO] [--repeat N]``.
The last line is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import tempfile
import time

import scenarios  # noqa: E402
from sim.episode.drive import prepare, run_episode  # noqa: E402
from sim.physics.world import PhysicsWorld  # noqa: E402


def best_of(n: int, fn, clock=time.perf_counter) -> float:
    """Smallest time of ``n`` calls of ``fn`` on ``clock`` [s] (the least disturbed by other load)."""
    best = float("inf")
    for _ in range(n):
        t0 = clock()
        fn()
        best = min(best, clock() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario", nargs="?", default="paper-docks")
    ap.add_argument("--repeat", type=int, default=11)
    args = ap.parse_args()

    s = scenarios.load(args.scenario)
    t0 = time.perf_counter()
    prepared = prepare(s, 0)
    t_prepare = time.perf_counter() - t0
    world = PhysicsWorld(s)
    # Warm-up run (numba, caches) that also records every wheel command at its physics step, so
    # that the baseline drives the same motion: a robot at rest steps ~40 % cheaper than a
    # rolling one, and comparing against it would charge physics to the harness.
    commands: list[tuple[int, float, float]] = []
    motor = world.robot.set_wheel_speeds

    def recording_motor(left: float, right: float) -> None:
        commands.append((world.steps, left, right))
        motor(left, right)

    world.robot.set_wheel_speeds = recording_motor
    result = run_episode(s, 0, seed=1, prepared=prepared, world=world)
    world.robot.set_wheel_speeds = motor
    n_steps = world.steps
    start_pose = result.steps.true_pose[0]
    sim_time = result.summary["duration"]
    until = [c[0] for c in commands[1:]] + [n_steps]

    def bare():
        # the same wheel commands at the same physics steps, open loop: physics alone
        world.reset(start_pose)
        world.step(commands[0][0] if commands else n_steps)
        for (step, left, right), nxt in zip(commands, until, strict=True):
            motor(left, right)
            world.step(nxt - step)

    def episode():
        run_episode(s, 0, seed=1, prepared=prepared, world=world)

    rrd = os.path.join(tempfile.mkdtemp(), "episode.rrd")
    pef_map = prepared.pef.grid()

    def episode_rrd():
        from interop.recording import write_episode_rrd

        r = run_episode(s, 0, seed=1, prepared=prepared, world=world)
        write_episode_rrd(rrd, s, r, pef_map=pef_map)

    # Interleaved: each episode run is paired with the baseline run just before it, so a
    # machine that slows down for a while (other processes, a shared host) slows both. The
    # headline ratio is the median of the pairs' ratios (module docstring), next to best over best.
    t_bare, t_episode, t_rrd, pair_ratios, rrd_ratios = math.inf, math.inf, math.inf, [], []
    cpu_ratios = []
    for _ in range(args.repeat):
        b, e, r = best_of(1, bare), best_of(1, episode), best_of(1, episode_rrd)
        t_bare, t_episode, t_rrd = min(t_bare, b), min(t_episode, e), min(t_rrd, r)
        pair_ratios.append(e / b)
        rrd_ratios.append(r / e)
        # the same pair on this thread's CPU clock: on a shared host the wall clock also counts
        # the time other processes held the core (pybullet DIRECT steps in this thread)
        cpu_ratios.append(best_of(1, episode, time.thread_time) / best_of(1, bare, time.thread_time))
    t_reset = best_of(20, lambda: world.reset(s.docks[0].pose))

    def build():
        PhysicsWorld(s).close()
    t_build = best_of(5, build)
    world.close()

    out = {
        "scenario": args.scenario,
        "physics_steps": n_steps,
        "sim_time_s": round(sim_time, 3),
        "prepare_s": round(t_prepare, 3),
        "bare_steps_s": round(t_bare, 4),
        "episode_s": round(t_episode, 4),
        "episode_over_bare": round(statistics.median(pair_ratios), 3),
        "episode_over_bare_best": round(t_episode / t_bare, 3),
        "episode_over_bare_cpu": round(statistics.median(cpu_ratios), 3),
        "episode_over_bare_target": 1.25,
        "real_time_factor": round(sim_time / t_episode, 1),
        "episode_rrd_s": round(t_rrd, 4),
        "rrd_over_episode": round(statistics.median(rrd_ratios), 3),
        "rrd_over_episode_best": round(t_rrd / t_episode, 3),
        "rrd_over_episode_target": 1.3,
        "reset_ms": round(1e3 * t_reset, 4),
        "build_ms": round(1e3 * t_build, 3),
        "build_over_reset": round(t_build / t_reset, 1),
        "fixes": result.summary["fixes"],
        "repeats": args.repeat,
        "load_average": round(os.getloadavg()[0], 2),
    }
    w = max(len(k) for k in out)
    for k, v in out.items():
        print(f"{k:<{w}}  {v}")
    print(json.dumps(out))


if __name__ == "__main__":
    main()
