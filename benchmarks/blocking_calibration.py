"""Predicted against observed robot blocking on a fleet's episodes, planned alone or with traffic.

Run: ``python benchmarks/blocking_calibration.py [--scenario warehouse-fleet] [--runs 20] [--alone]``;
the last line is JSON. The fleet is planned once (``--alone``: each robot's schedule as if it drove
alone, so that it counts on reflectors the others hide and blocks happen; default: the
traffic-aware schedule), then driven ``--runs`` times (seeds spawned from the scenario's, as a
sweep's); each fix's prediction (``p_block_robot``) and what happened (a scheduled line of sight
hidden by a robot) go through the ``blocking`` check of ``pefsim validate``
(:mod:`validation.blocking`) at alpha = 0.01, and per robot the runs that lost the guarantee
(the plan check's single-failure test). Nothing is written.

``--model`` drives no episode: it plans the fleet and prints the power the sampled prediction itself
states for the ``blocking`` check at ``--runs`` runs (:func:`validation.blocking.model_powers`: one
run's count of hidden decided fixes, its mean and variance over the declared spread's draws), at
the check's share ``--alpha`` of the family false-alarm probability (default 0.01 / 7, the seven
statistical checks that apply to a fleet sweep with every step stored), simulated from the
model's own law of a run's count, and what the normal law would say.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

HERE = Path(__file__).resolve().parent

import numpy as np  # noqa: E402


def model(name: str, runs: int, alpha: float) -> None:
    """Print the power the sampled prediction states for the ``blocking`` check at ``runs`` runs."""
    from planner.fleet.plan import plan_fleet
    from planner.fleet.sampled import DRAWS, UNDECIDED, predict_sampled
    from scenarios import load
    from validation.blocking import critical, model_powers, powers

    sc = load(name)
    fleet = plan_fleet(sc)
    pred = predict_sampled(sc, fleet.robots)
    # the fixes the check tests: decided ones (a sweep's p_block_robot is NaN on the others)
    p = np.concatenate([pf[u <= UNDECIDED] for pf, u in zip(pred.p_fix, pred.undecided, strict=True)])
    z_crit = critical(alpha, p)
    var = runs * pred.count_var * (1.0 + runs / DRAWS)
    normal = powers(runs * pred.count_mean, var, z_crit)
    double, half = model_powers(pred.hits, runs, z_crit, np.random.default_rng(sc.seed))
    reach = runs * pred.count_mean / math.sqrt(var)
    print(f"{sc.name}: one run's hidden decided fixes {pred.count_mean:.3f} expected, variance {pred.count_var:.3f} "
          f"({DRAWS} draws); at {runs} runs E / sqrt(V) = {reach:.2f}, |z| <= {z_crit:.3f} at alpha {alpha:.3g}; "
          f"power against a prediction twice the truth {double:.3f}, half the truth {half:.3f} (simulated; "
          f"the normal law's {normal[0]:.3f} and {normal[1]:.3f}); traffic note: {fleet.note}")
    print(json.dumps({"scenario": sc.name, "runs": runs, "alpha": alpha, "count_mean": pred.count_mean,
                      "count_var": pred.count_var, "draws": DRAWS, "z_crit": z_crit, "reach": reach,
                      "power_double": double, "power_half": half, "normal_double": normal[0],
                      "normal_half": normal[1]}))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="warehouse-fleet")
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--alone", action="store_true")
    ap.add_argument("--model", action="store_true")
    ap.add_argument("--alpha", type=float, default=0.01 / 7)
    args = ap.parse_args()
    if args.model:
        model(args.scenario, args.runs, args.alpha)
        return

    from scenarios import load
    from sim.episode.fleet import prepare_fleet, run_fleet_episode
    from sim.physics.world import PhysicsWorld
    from validation.blocking import blocking
    from validation.data import FixTable, RunTable, SweepData

    sc = load(args.scenario)
    prep = prepare_fleet(sc, traffic=not args.alone)
    n_rob = len(sc.robots)
    unit, p_col, obs = [], [], []
    lost = np.zeros(n_rob, int)
    hidden = np.zeros(n_rob, int)
    world = PhysicsWorld(sc, fleet=True)
    try:
        for run in range(args.runs):
            res = run_fleet_episode(sc, np.random.SeedSequence(sc.seed, spawn_key=(run,)), world=world, prepared=prep)
            for j, r in enumerate(res.robots):
                notes = r.result.fixes.notes or []
                unit.append(np.full(len(notes), run * n_rob + j))
                p_col.append(np.array([n.p_block_robot for n in notes], float))
                obs.append(np.array([len(n.hidden) > 0 for n in notes], bool))
                lost[j] += int(r.result.summary.get("lost_guarantee", 0) > 0)
                hidden[j] += int(r.result.summary.get("robot_blocked", 0))
            print(f"run {run}: blocked fixes {int(sum(o.sum() for o in obs[-n_rob:]))}, "
                  f"expected {sum(p.sum() for p in p_col[-n_rob:]):.2f}", flush=True)
    finally:
        world.close()
    n = int(sum(len(u) for u in unit))
    z = np.zeros(n)
    fixes = FixTable(run=np.concatenate(unit), fix=np.zeros(n, np.int64), true_xy=np.zeros((n, 2)),
                     snapshot_xy=np.zeros((n, 2)), snapshot_cov=np.zeros((n, 2, 2)), snapshot_error=z,
                     predicted_tau=np.ones(n), contained=np.ones(n, bool), fault_diameter=z, nis=z,
                     n_accepted=np.zeros(n, np.int64), markers=np.zeros((n, 2), np.int64),
                     p_block_robot=np.concatenate(p_col), robot_blocked=np.concatenate(obs))
    units = np.arange(args.runs * n_rob)
    data = SweepData(scenario=sc, runs=RunTable(run=units, ok=np.ones(len(units), bool),
                                                succeeded=np.ones(len(units), bool), mean_nees=np.zeros(len(units))),
                     fixes=fixes)
    res = blocking(data, 0.01, np.random.default_rng(0))
    print(f"blocking check: {res.status.value}: {res.statistic} ({res.acceptance})")
    print(res.detail)
    names = [r.name for r in sc.robots]
    print(f"runs that lost the guarantee per robot: {dict(zip(names, lost.tolist(), strict=True))}; "
          f"scheduled lines of sight hidden by robots: {dict(zip(names, hidden.tolist(), strict=True))}")
    print(json.dumps({"scenario": sc.name, "alone": args.alone, "runs": args.runs, "check": res.to_dict(),
                      "lost_guarantee_runs": lost.tolist(), "robot_blocked": hidden.tolist()}))


if __name__ == "__main__":
    main()
