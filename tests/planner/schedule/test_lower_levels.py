"""The promises' lower bound (:func:`planner.schedule.promise.lower_levels`) and the proof it gives.

1. The bound is below every candidate fix's promise at every speed level, on the sampled paths
   of two built-in plans (a proven inequality: every entry checked, no tolerance but the bound's
   own 1e-9), and not trivially small (most entries within a factor 10 of the promise).
   Negative control: the promises at the cruising speed taken as the bound of every level (a
   bound of the fastest fix only: slower fixes promise less) are caught above a slower one.
2. The ladder at the planned speed, which proves failures from the bound, gives the same
   schedule as without the proof, where a rung's failure was proven (paper-docks: the 10 mm
   rung, the hall-like case of a small rung that cannot plan at speed).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import scenarios
from planner.pef.map import PEF
from planner.plan import plan_task
from planner.schedule import promise
from planner.schedule.pathtime import sample_track
from planner.schedule.schedule import _candidate_subsets, _stretch_tau


def candidates(name: str):
    """Return task 0's chosen route of ``name`` sampled as a schedule does: scenario, subsets, tr, path, tau_s."""
    sc = scenarios.load(name)
    plan = plan_task(sc, 0)
    path, v = plan.path, plan.speed
    pef = PEF(sc)
    k, mt = 2, sc.sensor.measurement_time
    gap = max(1.0 / sc.sensor.fix_rate_hz, k * mt)
    spacing = min(sc.planning.resolution, 0.25 * max(v.max(), 1e-9) * gap)
    tr = sample_track(path, v, spacing, k * mt, gap, measurements=k)
    subsets = _candidate_subsets(pef, tr.xy, k)
    n = len(tr.s)
    tau = np.asarray(pef.tau_subset(np.vstack([tr.xy, tr.xy_c]), np.asarray(subsets)), dtype=float)
    return sc, subsets, tr, path, _stretch_tau(tau[:, :n], tau[:, n:], tr.c_idx)


def below_every_level(bound: np.ndarray, lv: promise.Levels) -> bool:
    return all(bool(np.all(bound <= lv[i].tau)) for i in range(len(lv)))


@pytest.mark.parametrize("name", ["warehouse", "paper-docks"])
def test_the_bound_is_below_every_promise_at_every_speed(name):
    sc, subsets, tr, path, tau_s = candidates(name)
    lv = promise.levels(sc, subsets, tr, path, tau_s, 2, sc.planning.eps_max)
    lb = promise.lower_levels(sc, subsets, tr, path, tau_s)
    assert len(lv) > 1  # slower levels too
    assert below_every_level(lb, lv)
    assert np.array_equal(np.isfinite(lb), np.isfinite(tau_s))  # inf exactly where not visible
    best = np.min([lv[i].tau for i in range(len(lv))], axis=0)
    both = np.isfinite(best)
    assert both.sum() > 1000
    assert np.mean(lb[both] * 10.0 >= best[both]) > 0.5  # a bound that says something


def test_negative_control_the_cruising_promises_are_not_below_the_slower_ones():
    sc, subsets, tr, path, tau_s = candidates("warehouse")
    lv = promise.levels(sc, subsets, tr, path, tau_s, 2, sc.planning.eps_max)
    assert not below_every_level(lv[0].tau, lv), "the cruising promises stayed below every level: cannot fail"


def test_the_ladder_at_speed_proves_a_failure_and_plans_the_same(monkeypatch):
    """paper-docks: the 10 mm rung fails at speed; proven from the bound, then the same plan as without."""
    sc = scenarios.load("paper-docks")
    proven, computed = [], []
    levels, lower = promise.levels, promise.lower_levels

    def counting_levels(scenario, *args, **kwargs):
        computed.append(scenario.planning.eps_max)
        return levels(scenario, *args, **kwargs)

    def counting_lower(scenario, *args, **kwargs):
        proven.append(scenario.planning.eps_max)
        return lower(scenario, *args, **kwargs)

    monkeypatch.setattr(promise, "levels", counting_levels)
    monkeypatch.setattr(promise, "lower_levels", counting_lower)
    with_proof = plan_task(sc, 0).schedule
    assert 0.01 in proven and 0.01 not in computed  # the 10 mm rung's promises never computed
    monkeypatch.setattr(promise, "lower_levels", lambda scenario, subsets, tr, path, tau_s: np.zeros(tau_s.shape))
    without = plan_task(sc, 0).schedule
    assert with_proof.fixes == without.fixes
    assert with_proof.worst == without.worst and with_proof.slowdown_time == without.slowdown_time
    assert math.isfinite(with_proof.worst)
