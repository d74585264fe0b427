"""The ``blocking`` check on synthetic fleet tables: calibrated predictions pass, 2x off either way fail.

Each synthetic run has the fixes of three robots; a robot crossing another's line of sight hides
it at a stretch of consecutive fixes whose probabilities rise and fall (a crossing), and within a
run the fixes of one crossing share one timing draw (a fix is blocked when a uniform draw of the
crossing falls below its probability: each fix's marginal probability is exact, and the fixes of
a crossing are as dependent as they come). The check's family false-alarm probability is
alpha = 0.01 (its Bonferroni share in ``pefsim validate``); seeds are fixed.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import binom, norm

import scenarios
from planner.fleet.sampled import DRAWS
from validation.blocking import blocking, blocking_why_not, critical, model_powers, powers
from validation.data import FixTable, RunTable, SweepData
from validation.suite import validate

ALPHA = 0.01
RUNS = 200
ROBOTS = 3
FIXES = 200       # per robot and run
CROSSINGS = 6     # per robot: stretches where another robot may hide a reflector


@pytest.fixture(scope="module")
def fleet_scenario():
    return scenarios.load("warehouse-fleet-spread")


def _profile(rng: np.random.Generator) -> np.ndarray:
    """Predicted probability per fix of one robot (FIXES,): zero but at CROSSINGS bumps."""
    p = np.zeros(FIXES)
    for c in rng.choice(np.arange(10, FIXES - 10), CROSSINGS, replace=False):
        width = int(rng.integers(2, 8))
        peak = rng.uniform(0.05, 1.0)
        idx = np.arange(c - width, c + width + 1)
        p[idx] = np.maximum(p[idx], peak * np.exp(-0.5 * ((idx - c) / (0.5 * width)) ** 2))
    return p


def _table(scenario, seed: int, scale: float = 1.0, runs: int = RUNS) -> SweepData:
    """Make a fleet sweep of ``runs`` runs whose true blocking probabilities are ``scale`` x the predicted."""
    rng = np.random.default_rng(seed)
    pred = [_profile(rng) / scale for _ in range(ROBOTS)]
    unit, p_col, obs = [], [], []
    for run in range(runs):
        for r in range(ROBOTS):
            true = np.clip(pred[r] * scale, 0.0, 1.0)
            # one uniform per crossing (a connected stretch of p > 0): the crossing's timing
            stretch = np.cumsum(np.diff(np.concatenate([[0.0], true]) > 0) & (true > 0))
            draw = rng.uniform(size=stretch.max() + 1)[stretch]
            unit.append(np.full(FIXES, run * ROBOTS + r))
            p_col.append(pred[r])
            obs.append(draw < true)
    n = runs * ROBOTS * FIXES
    z = np.zeros(n)
    fixes = FixTable(run=np.concatenate(unit), fix=np.tile(np.arange(FIXES), runs * ROBOTS),
                     true_xy=np.zeros((n, 2)), snapshot_xy=np.zeros((n, 2)), snapshot_cov=np.zeros((n, 2, 2)),
                     snapshot_error=z, predicted_tau=np.ones(n), contained=np.ones(n, bool), fault_diameter=z, nis=z,
                     n_accepted=np.zeros(n, np.int64), markers=np.zeros((n, 2), np.int64),
                     p_block_robot=np.concatenate(p_col), robot_blocked=np.concatenate(obs))
    units = np.arange(runs * ROBOTS)
    table = RunTable(run=units, ok=np.ones(len(units), bool), succeeded=np.ones(len(units), bool),
                     mean_nees=np.full(len(units), 3.0))
    return SweepData(scenario=scenario, runs=table, fixes=fixes)


def test_calibrated_predictions_pass(fleet_scenario):
    res = blocking(_table(fleet_scenario, 1), ALPHA, np.random.default_rng(0))
    assert res.status.value == "pass", res.detail
    assert len(res.values["per_bin"]) >= 3 and res.values["observed"] > 500
    # the power it shows: the same runs against predictions half and twice as large fail
    assert abs(res.values["z_half"]) > res.values["z_crit"] and abs(res.values["z_double"]) > res.values["z_crit"]


def test_predictions_three_times_too_small_fail(fleet_scenario):
    # negative control: the robots hide reflectors three times as often as predicted
    res = blocking(_table(fleet_scenario, 2, scale=3.0), ALPHA, np.random.default_rng(0))
    assert res.status.value == "FAIL", res.detail
    assert res.values["observed"] > 2.5 * res.values["expected"]


@pytest.mark.parametrize("scale", [0.5, 2.0])
def test_predictions_twice_too_high_or_too_low_fail(fleet_scenario, scale):
    # negative controls: the robots hide reflectors half (twice) as often as predicted, with a few
    # hundred blocked fixes over the sweep
    res = blocking(_table(fleet_scenario, 4, scale=scale), ALPHA, np.random.default_rng(0))
    assert res.status.value == "FAIL", res.detail
    assert (res.values["z"] > 0) == (scale > 1.0)


def test_a_fleet_that_keeps_time_like_a_clock_fails_a_spread_it_does_not_have(fleet_scenario):
    # identical runs (no timing drawn anew): fixes predicted 0.3 that never happen. The check that
    # counted each scheduled fix's rows as one dependent trial passed this; runs are the unit now
    p = np.r_[np.full(4, 0.3), np.zeros(200)]
    res = blocking(_deterministic(fleet_scenario, p, np.zeros(len(p), bool)), ALPHA, np.random.default_rng(0))
    assert res.status.value == "FAIL", res.detail
    assert res.values["expected"] == pytest.approx(0.3 * 4 * RUNS) and res.values["observed"] == 0


def test_false_alarms_stay_within_alpha(fleet_scenario):
    # 30 calibrated sweeps with dependent fixes: a check of false-alarm probability <= alpha fails
    # at most k of them, k the binomial(30, alpha) quantile at 1 - 0.001 (a false alarm of this
    # test of at most 0.001)
    tables = 30
    fails = sum(blocking(_table(fleet_scenario, 100 + i), ALPHA, np.random.default_rng(0)).status.value == "FAIL"
                for i in range(tables))
    assert fails <= binom.ppf(1 - 0.001, tables, ALPHA)


def test_applies_only_to_fleet_tables_and_joins_the_suite(fleet_scenario):
    data = _table(fleet_scenario, 3, runs=20)  # the whole suite judges it: a small sweep
    assert blocking_why_not(data) is None
    bare = SweepData(scenario=data.scenario, runs=data.runs,
                     fixes=FixTable(**{**data.fixes.__dict__, "p_block_robot": None, "robot_blocked": None}))
    assert "not a fleet sweep" in blocking_why_not(bare)
    # a fleet that declares no timing spread repeats one timing in every run: no trials to count
    clock = SweepData(scenario=scenarios.load("warehouse-fleet"), runs=data.runs, fixes=data.fixes)
    assert "declares a timing spread" in blocking_why_not(clock)
    report = validate(data, alpha=ALPHA)
    assert report.check("blocking").status.value == "pass"
    assert report.check("blocking").alpha == pytest.approx(ALPHA / report.statistical)


def _deterministic(scenario, p_pred: np.ndarray, blocked: np.ndarray) -> SweepData:
    """Every run the same: fixes predicted ``p_pred``, blocked as ``blocked`` (a run of robots on time)."""
    n = len(p_pred) * RUNS
    z = np.zeros(n)
    unit = np.repeat(np.arange(RUNS) * ROBOTS, len(p_pred))
    fixes = FixTable(run=unit, fix=np.tile(np.arange(len(p_pred)), RUNS), true_xy=np.zeros((n, 2)),
                     snapshot_xy=np.zeros((n, 2)), snapshot_cov=np.zeros((n, 2, 2)), snapshot_error=z,
                     predicted_tau=np.ones(n), contained=np.ones(n, bool), fault_diameter=z, nis=z,
                     n_accepted=np.zeros(n, np.int64), markers=np.zeros((n, 2), np.int64),
                     p_block_robot=np.tile(p_pred, RUNS), robot_blocked=np.tile(blocked, RUNS))
    units = np.arange(RUNS) * ROBOTS
    runs = RunTable(run=units, ok=np.ones(RUNS, bool), succeeded=np.ones(RUNS, bool), mean_nees=np.full(RUNS, 3.0))
    return SweepData(scenario=scenario, runs=runs, fixes=fixes)


def test_sure_predictions_pass_when_they_come_true_and_fail_when_reversed(fleet_scenario):
    # a deterministic fleet: 8 fixes hidden for sure, 500 never; predicted 1 - 1e-6 and 1e-6: the
    # runs' variance is 0, the prediction's own (independent fixes) keeps z small (0.1 expected
    # blocked among the 100000 clear rows: |z| about 0.3)
    truth = np.r_[np.ones(8, bool), np.zeros(500, bool)]
    p = np.where(truth, 1.0 - 1e-6, 1e-6)
    res = blocking(_deterministic(fleet_scenario, p, truth), ALPHA, np.random.default_rng(0))
    assert res.status.value == "pass", res.detail
    # the runs' variance is 0: V is the prediction's own, times the sampling error's 1 + R / draws
    assert res.values["variance"] == pytest.approx(res.values["variance_floor"] * (1.0 + RUNS / res.values["draws"]))
    # negative control: the hidden fixes are the ones predicted clear and the other way round
    swapped = np.r_[np.zeros(8, bool), np.ones(8, bool), np.zeros(492, bool)]
    res = blocking(_deterministic(fleet_scenario, p, swapped), ALPHA, np.random.default_rng(0))
    assert res.status.value == "FAIL", res.detail


def _stretches(scenario, seed: int, q: float, predicted: float, runs: int = RUNS, length: int = 5) -> SweepData:
    """Each run one robot stands in one line of sight or not (probability q): ``length`` fixes hidden together."""
    rng = np.random.default_rng(seed)
    hidden = np.repeat(rng.uniform(size=runs) < q, length)
    n = runs * length
    z = np.zeros(n)
    fixes = FixTable(run=np.repeat(np.arange(runs) * ROBOTS, length), fix=np.tile(np.arange(length), runs),
                     true_xy=np.zeros((n, 2)), snapshot_xy=np.zeros((n, 2)), snapshot_cov=np.zeros((n, 2, 2)),
                     snapshot_error=z, predicted_tau=np.ones(n), contained=np.ones(n, bool), fault_diameter=z, nis=z,
                     n_accepted=np.zeros(n, np.int64), markers=np.zeros((n, 2), np.int64),
                     p_block_robot=np.full(n, predicted), robot_blocked=hidden)
    units = np.arange(runs) * ROBOTS
    table = RunTable(run=units, ok=np.ones(runs, bool), succeeded=np.ones(runs, bool), mean_nees=np.full(runs, 3.0))
    return SweepData(scenario=scenario, runs=table, fixes=fixes)


def test_the_stated_power_is_how_often_a_prediction_half_the_truth_fails(fleet_scenario):
    """Stretches of 5 fixes hidden together in 17 % of the runs: the power against half is about 1/2.

    The check states, on each calibrated sweep, the power against a prediction half the truth
    (``power_half``); over 60 sweeps the mean stated power must match the share of the same
    sweeps with the prediction halved that fail, within 3 binomial sd (0.19 at 60) plus 0.1 for
    the normal approximation of the power at 200 runs. Negative control: the power of a test
    that took the ~170 blocked fixes for independent (V = E, ``Phi(sqrt(E) / 2 - z_c)`` = 1.0) is
    farther off than that.
    """
    q, sweeps = 0.17, 60
    stated, failed, naive = [], 0, []
    for i in range(sweeps):
        honest = blocking(_stretches(fleet_scenario, 700 + i, q, q), ALPHA, np.random.default_rng(0))
        stated.append(honest.values["power_half"])
        naive.append(norm.cdf(np.sqrt(honest.values["expected"]) / 2.0 - honest.values["z_crit"]))
        halved = blocking(_stretches(fleet_scenario, 700 + i, q, q / 2.0), ALPHA, np.random.default_rng(0))
        failed += halved.status.value == "FAIL"
    share = failed / sweeps
    tol = 3.0 * np.sqrt(0.25 / sweeps) + 0.1
    assert 0.15 < share < 0.85, share                     # a case where the power is not trivially 0 or 1
    assert abs(np.mean(stated) - share) < tol, (np.mean(stated), share)
    assert abs(np.mean(naive) - share) > tol              # the negative control


def _all_or_nothing(scenario, runs: int, scale: float, rng: np.random.Generator, p: float) -> SweepData:
    """Make a fleet sweep whose robots hide 5 fixes together at each of 6 crossings, with probability ``p``.

    Most runs hide nothing (a skewed count); every fix is predicted ``scale`` x ``p``.
    """
    width, crossings = 5, 6
    n_fix = width * crossings
    hidden = np.repeat(rng.random((runs, ROBOTS, crossings)) < p, width, axis=2).reshape(-1)
    n = runs * ROBOTS * n_fix
    z = np.zeros(n)
    fixes = FixTable(run=np.repeat(np.arange(runs * ROBOTS), n_fix), fix=np.tile(np.arange(n_fix), runs * ROBOTS),
                     true_xy=np.zeros((n, 2)), snapshot_xy=np.zeros((n, 2)), snapshot_cov=np.zeros((n, 2, 2)),
                     snapshot_error=z, predicted_tau=np.ones(n), contained=np.ones(n, bool), fault_diameter=z, nis=z,
                     n_accepted=np.zeros(n, np.int64), markers=np.zeros((n, 2), np.int64),
                     p_block_robot=np.full(n, scale * p), robot_blocked=hidden)
    units = np.arange(runs * ROBOTS)
    table = RunTable(run=units, ok=np.ones(len(units), bool), succeeded=np.ones(len(units), bool),
                     mean_nees=np.full(len(units), 3.0))
    return SweepData(scenario=scenario, runs=table, fixes=fixes)


def test_the_power_the_model_states_is_the_rate_the_check_fails_at(fleet_scenario):
    """The power ``model_powers`` states is the rate the check fails a prediction 2x off at.

    Against the check run on 1000 synthetic sweeps per control whose truth is the model's law: 40
    runs, 6 crossings a robot hiding 5 fixes together in 2 % of the runs (all predictions in one
    bin, so the check is the total's test).

    Tolerance: 3 binomial sd of the 1000 sweeps' rate plus 3 of the 5000 simulated (false alarm
    about 0.5 %). The law is drawn from 4096 draws of the crossings. Negative control: the normal
    law's power (:func:`powers`) overstates both, beyond the same tolerance (this skewed count is
    the case it misjudges).
    """
    runs, sweeps, sims, p = 40, 1000, 5000, 0.02
    rng = np.random.default_rng(5)
    failed = [np.mean([blocking(_all_or_nothing(fleet_scenario, runs, k, rng, p), ALPHA, rng).status.value == "FAIL"
                       for _ in range(sweeps)]) for k in (2.0, 0.5)]
    g = np.random.default_rng(6)
    hits = np.repeat(g.random((4096, ROBOTS * 6)) < p, 5, axis=1).astype(float)
    z_crit = critical(ALPHA, np.full(3, p))
    stated = model_powers(hits, runs, z_crit, g, sims=sims)
    mean, var = ROBOTS * 6 * 5 * p, ROBOTS * 6 * 25 * p * (1 - p)
    normal = powers(runs * mean, runs * var * (1 + runs / DRAWS), z_crit)
    for rate, sim, nor in zip(failed, stated, normal, strict=True):
        tol = 3 * np.sqrt(rate * (1 - rate) / sweeps) + 3 * np.sqrt(rate * (1 - rate) / sims)
        assert abs(sim - rate) <= tol, (failed, stated)
        assert nor - rate > tol, (failed, normal)
