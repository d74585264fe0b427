"""The sampled blocking model's drives against a fleet sweep's episodes, run by run.

Run: ``python benchmarks/fleet_timelines.py SWEEP_DIR [--runs 40]``; the last line is JSON. The
sweep must be of a fleet with a declared timing spread, recorded with ``--steps all``. For each
run the model (:func:`planner.fleet.drive.drive_timings`, the fleet driven kinematically through
its zone gate) is driven with that run's own draws of the spread (:func:`planner.fleet.timing.draw`
on the run's stream, as the simulation draws them), and compared with the episode:

* ``fix_dt``: each scheduled fix's time in the model minus the simulation's (the fix the robot
  took nearest the planned place) [s], pooled over robots, runs and fixes not on a final dock;
* ``pos``: at every logged step, the distance between the model's robot and the simulated one [m];
* ``waits``: each zone wait longer than 1 s in the episode (the robot's speed below 3 mm/s between
  its first and last move) against the model's wait that overlaps it: where (distance [m]) and how
  long (model minus simulation [s]); waits in one but not the other are counted (``unmatched``);
* ``counts``: per run, the fixes the plan decided (``p_block_robot`` not NaN) that a robot hid in
  the episode, against the model's expected count with that run's own draws
  (:func:`planner.fleet.sampled.predict_sampled` given them): their totals, and how much of the
  runs' spread about the plan's expected count (the same in every run) the run's own draws explain.

The plan is made anew from the sweep's ``scenario.toml`` (as ``validate --from`` does). Nothing is
written.
"""

from __future__ import annotations

import argparse
import json
import types
from pathlib import Path

import numpy as np


def _table(path, columns) -> types.SimpleNamespace:
    import pyarrow.parquet as pq

    tab = pq.read_table(path, columns=columns)
    return types.SimpleNamespace(**{c: tab.column(c).to_numpy(zero_copy_only=False) for c in columns})


def _stops(t: np.ndarray, moving: np.ndarray, standing: np.ndarray, min_len: float = 1.0
           ) -> list[tuple[float, float, int]]:
    """Stretches (start, end, first index) ``standing`` holds over ``min_len`` s, between the first and last move."""
    mv = np.flatnonzero(moving)
    out = []
    if len(mv) == 0:
        return out
    k = mv[0]
    while k < mv[-1]:
        if standing[k]:
            e = k
            while e < len(t) and standing[e]:
                e += 1
            if t[e - 1] - t[k] > min_len:
                out.append((float(t[k]), float(t[e - 1]), k))
            k = e
        else:
            k += 1
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sweep")
    ap.add_argument("--runs", type=int, default=40)
    args = ap.parse_args()

    import scenarios
    from planner.fleet import drive, sampled
    from planner.fleet import timing as fleet_timing
    from sim.episode.fleet import prepare_fleet

    sweep = Path(args.sweep)
    sc = scenarios.load(sweep / "scenario.toml")
    robots = prepare_fleet(sc).plan.robots
    fix_dt, pos, place, longer, unmatched, matched = [], [], [], [], 0, 0
    observed, own, plan_e = [], [], []
    decided = [~r.blocking.undecided if r.blocking.undecided is not None else np.ones(len(r.blocking.p_fix), bool)
               for r in robots]
    for run in range(args.runs):
        ss = np.random.SeedSequence(sc.seed, spawn_key=(run,))
        starts, factors, dwells = [], [], []
        for q, (r, fr) in enumerate(zip(robots, sc.robots, strict=True)):
            d = fleet_timing.draw(fr, fleet_timing.stream(ss, q), legs=len(r.plans))
            starts.append(fr.start_time + d.release_delay)
            factors.append(d.speed_factor)
            dwells.append(np.asarray(d.dwell, float))
        model = drive.drive_timings(sc, robots, [(starts, factors, dwells)])[0]
        steps = _table(sweep / "steps" / f"run-{run:06d}.parquet", ["t", "true_x", "true_y", "robot"])
        fixes = _table(sweep / "fixes" / f"run-{run:06d}.parquet",
                       ["t", "true_x", "true_y", "robot", "p_block_robot", "blocked_by_robot_count"])
        with_p = np.isfinite(fixes.p_block_robot.astype(float))
        observed.append(int(np.sum(with_p & (fixes.blocked_by_robot_count > 0))))
        plan_e.append(float(np.sum(fixes.p_block_robot[with_p])))
        mine = sampled.predict_sampled(sc, robots, timing=[(starts, factors, dwells)])
        own.append(float(sum(p[m].sum() for p, m in zip(mine.p_fix, decided, strict=True))))
        for i, r in enumerate(robots):
            tm, sm, stm = model[i]
            m = steps.robot == r.name
            t, x, y = steps.t[m], steps.true_x[m], steps.true_y[m]
            s_at = np.interp(t, tm, sm)
            pos.append(np.hypot(np.interp(s_at, r.s, r.path[:, 0]) - x, np.interp(s_at, r.s, r.path[:, 1]) - y))
            # scheduled fixes: the model's time at the fix's arc length against the nearest fix taken
            f = fixes.robot == r.name
            f_xy = np.column_stack([fixes.true_x[f], fixes.true_y[f]])
            end = float(r.s[-1]) - 0.5
            for plan, off in zip(r.plans, r.offsets, strict=True):
                for fx in plan.schedule.fixes:
                    s_f = off + fx.s
                    if s_f >= end or s_f <= 0.0 or not len(f_xy):
                        continue
                    k = int(np.argmin(np.hypot(*(f_xy - np.asarray(fx.position)).T)))
                    fix_dt.append(float(np.interp(s_f, sm, tm)) - float(fixes.t[f][k]))
            # zone waits: the episode's stops against the model's
            v = np.r_[0.0, np.hypot(np.diff(x), np.diff(y)) / np.maximum(np.diff(t), 1e-9)]
            sim_stops = _stops(t, v > 0.01, v < 0.003)
            zw = stm & (tm > starts[i] + 0.2) & (sm < float(r.s[-1]) - 0.1)
            mod_stops = _stops(tm, sm > 1e-3, zw)
            for a, b, k in sim_stops:
                hit = [(c, e, q) for c, e, q in mod_stops if c < b and e > a]
                if not hit:
                    unmatched += 1
                    continue
                c, e, q = hit[0]
                matched += 1
                place.append(float(np.hypot(np.interp(sm[q], r.s, r.path[:, 0]) - x[k],
                                            np.interp(sm[q], r.s, r.path[:, 1]) - y[k])))
                longer.append((e - c) - (b - a))
            unmatched += sum(1 for c, e, _ in mod_stops if not any(a < e and b > c for a, b, _ in sim_stops))
    pos = np.concatenate(pos)
    q = [50, 90, 95, 99]
    observed, own, plan_e = np.asarray(observed, float), np.asarray(own), np.asarray(plan_e)
    counts = {"observed": int(observed.sum()), "own_draws": round(float(own.sum()), 1),
              "plan": round(float(plan_e.sum()), 1),
              "residual_var_own": round(float(np.var(observed - own)), 2),
              "residual_var_plan": round(float(np.var(observed - plan_e)), 2)}
    out = {"runs": args.runs,
           "fix_dt_percentiles": dict(zip(map(str, [1, 5, 50, 95, 99]),
                                          np.round(np.percentile(fix_dt, [1, 5, 50, 95, 99]), 3).tolist(),
                                          strict=True)),
           "fix_dt_mean": round(float(np.mean(fix_dt)), 3), "fixes": len(fix_dt),
           "pos_percentiles": dict(zip(map(str, q), np.round(np.percentile(pos, q), 3).tolist(), strict=True)),
           "waits_matched": matched, "waits_unmatched": unmatched,
           "wait_place_max": round(max(place), 3) if place else None,
           "wait_longer_in_model": {"mean": round(float(np.mean(longer)), 3) if longer else None,
                                    "min": round(min(longer), 3) if longer else None,
                                    "max": round(max(longer), 3) if longer else None},
           "counts": counts}
    print(f"{args.runs} runs: scheduled fixes {len(fix_dt)}, model minus simulation time: median "
          f"{out['fix_dt_percentiles']['50']:+.2f} s, 5-95 % {out['fix_dt_percentiles']['5']:+.2f} .. "
          f"{out['fix_dt_percentiles']['95']:+.2f} s; robots apart (m) p50/p90/p95/p99 {out['pos_percentiles']}; "
          f"waits {matched} matched (places within {out['wait_place_max']} m, model longer by "
          f"{out['wait_longer_in_model']}), {unmatched} unmatched; hidden decided fixes {counts['observed']}, "
          f"the model with each run's own draws {counts['own_draws']}, the plan {counts['plan']}; variance of "
          f"observed minus expected per run {counts['residual_var_own']} (own draws) against "
          f"{counts['residual_var_plan']} (the plan's)")
    print(json.dumps(out))


if __name__ == "__main__":
    main()
