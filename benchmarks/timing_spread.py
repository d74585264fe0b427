"""How late a simulated robot is against its planned time profile: the timing model of fleet blocking.

Run: ``python benchmarks/timing_spread.py [--scenario warehouse-fleet] [--seeds 5]``; the last line
is JSON. Each task of the scenario is driven alone (one robot, one episode per seed, the ordinary
episode); at every metre of its path the *lag* is the simulated time the robot's true position
first passes that arc length minus the planned time (:class:`planner.schedule.pathtime.Kinematics`
of the plan's speed profile, the profile :func:`planner.fleet.zones.predict_timeline` drives the
fleet with). Reported per task and pooled: the mean lag at departure (the standstill fix and the
follower's acceleration from rest, which the plan does not ramp), the mean lag's growth per
second driven, and the spread (standard deviation over seeds) against planned time, with a
least-squares fit ``var = base_var + rate * t``. These are the numbers of
:data:`planner.fleet.blocking.TIMING`. Nothing is written.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

HERE = Path(__file__).resolve().parent

import numpy as np  # noqa: E402


def arc_length_on(path: np.ndarray, s: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Arc length of the nearest point of polyline ``path`` (N, 2) to each of ``xy`` (T, 2) [m], monotone."""
    a, b = path[:-1], path[1:]
    d = b - a
    L2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-12)
    out = np.empty(len(xy))
    lo = 0
    for n, p in enumerate(xy):
        # search forward only a few metres from the last match: the path may come back near itself
        hi = min(len(a), lo + 200)
        u = np.clip(np.einsum("ij,ij->i", p - a[lo:hi], d[lo:hi]) / L2[lo:hi], 0.0, 1.0)
        q = a[lo:hi] + u[:, None] * d[lo:hi]
        k = int(np.argmin(np.hypot(*(q - p).T)))
        out[n] = s[lo + k] + u[k] * np.sqrt(L2[lo + k])
        lo = lo + k
    return np.maximum.accumulate(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="warehouse-fleet")
    ap.add_argument("--seeds", type=int, default=5)
    args = ap.parse_args()

    from dataclasses import replace

    from planner.schedule.pathtime import Kinematics
    from scenarios import load
    from sim.episode.drive import prepare, run_episode
    from sim.physics.world import PhysicsWorld

    sc = load(args.scenario)
    alone = replace(sc, robots=())
    rows = {}
    world = PhysicsWorld(alone)
    try:
        for task in range(len(alone.tasks)):
            prep = prepare(alone, task)
            plan = prep.plan
            kin = Kinematics(plan.s, plan.speed)
            grid = np.arange(1.0, plan.s[-1] - 1.0, 1.0)
            lags = []
            for seed in range(args.seeds):
                res = run_episode(alone, task, seed, world=world, prepared=prep)
                s_true = arc_length_on(plan.path, plan.s, res.steps.true_pose[:, :2])
                k = np.searchsorted(s_true, grid, side="left")
                ok = k < len(s_true)
                lag = np.full(grid.shape, np.nan)
                lag[ok] = res.steps.t[k[ok]] - kin.t_at(grid[ok])
                lags.append(lag)
            lags = np.array(lags)
            rows[task] = {"t_plan": kin.t_at(grid), "lags": lags}
    finally:
        world.close()

    out = {"scenario": sc.name, "seeds": args.seeds, "tasks": {}}
    t_all, mean_all, var_all = [], [], []
    for task, r in rows.items():
        t, lags = r["t_plan"], r["lags"]
        mean, std = np.nanmean(lags, axis=0), np.nanstd(lags, axis=0, ddof=1)
        slope, icpt = np.polyfit(t, mean, 1)
        out["tasks"][task] = {"lag_at_1m": float(mean[0]), "lag_end": float(mean[-1]),
                              "lag_rate": float(slope), "lag0": float(icpt),
                              "std_min": float(std.min()), "std_max": float(std.max()),
                              "std_end": float(std[-1]), "t_end": float(t[-1])}
        t_all.append(t)
        mean_all.append(mean)
        var_all.append(std ** 2)
        print(f"task {task}: lag {mean[0]:.3f} s at 1 m, {mean[-1]:.3f} s at {t[-1]:.1f} s planned; "
              f"spread over seeds {std.min():.4f}..{std.max():.4f} s")
    t, mean, var = (np.concatenate(x) for x in (t_all, mean_all, var_all))
    rate, base = np.polyfit(t, var, 1)
    slope, icpt = np.polyfit(t, mean, 1)
    out["pooled"] = {"lag0": float(icpt), "lag_rate": float(slope), "base_var": float(base),
                     "var_rate": float(rate), "residual_std_of_mean_s": float(np.std(mean - (icpt + slope * t)))}
    print(f"pooled: mean lag = {icpt:.3f} s + {slope:.4f} t; var = {base:.3e} s^2 + {rate:.3e} s^2/s * t; "
          f"the mean lag's residual about its line {out['pooled']['residual_std_of_mean_s']:.3f} s")
    print(json.dumps(out))


if __name__ == "__main__":
    main()
