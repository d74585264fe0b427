"""Validation checks on synthetic sweeps whose truth is known, each with a negative control.

The sweeps here are written with :mod:`sim.montecarlo.results` (the real on-disk format) from fixes made by
the real snapshot fix (:func:`estimators.snapshot.snapshot_fix`: exact least squares and exact
fault area, independent of the linearised null model in :mod:`validation.null`) at the
paper's two-marker geometry, with errors drawn from the declared model (must pass) or from a
deliberately wrong one (must fail the named check). No physics: these run in seconds.

Statistical verdicts use fixed seeds; each check's false-alarm probability is the per-check
alpha of the report (family 0.01 split over the statistical checks), so a model-drawn sweep
fails a given check with probability at most 0.002 per seed.
"""

from __future__ import annotations

import dataclasses
import inspect
import json
import math

import numpy as np
import pytest
from scipy import optimize, stats

import scenarios
from planner.pef.map import PEF
from scenarios.errors import OutputError, SimulationError
from sim.montecarlo import results
from sim.montecarlo.negative_control import NEGATIVE_CONTROL_JSON
from sim.montecarlo.results import RunRecord, SweepLayout
from sim.montecarlo.rows import FIX_SCHEMA, RUN_SCHEMA, fix_columns, run_row
from tests.validation.synthetic_fixes import FIXES_PER_RUN, fix_log
from validation import null
from validation import suite as validation
from validation.data import EPISODE_GATE_PROBABILITY
from validation.promise import promise
from validation.suite import CheckStatus

RUNS, NEES_STEPS = 5, 50
PASS, FAIL, NA = CheckStatus.PASS, CheckStatus.FAIL, CheckStatus.NOT_APPLICABLE


def _scenario(noise: str = "uniform"):
    base = scenarios.load("paper-two-markers")
    text = base.text.replace('noise = "uniform"', f'noise = "{noise}"')
    return scenarios.loads(text, source=f"{noise}.toml")


def write_sweep(root, scenario, seed: int, error_scale: float = 1.0, nees_scale: float = 1.0,
                nis_scale: float = 1.0, failed_runs: int = 0):
    """Write a synthetic sweep and read it back.

    NEES is a run's time average of chi2(3) samples, NIS the sum of two chi2(1) per fix (times
    the scales: 1 is a consistent filter); ``failed_runs`` runs exceeded eps_max.
    """
    rng = np.random.default_rng(seed)
    layout = SweepLayout(root)
    layout.make_dirs()
    results.write_atomic(layout.scenario_toml, scenario.text.encode())
    for run in range(RUNS):
        log = fix_log(scenario, rng, error_scale)
        log.nis[:] = nis_scale * rng.chisquare(1, (FIXES_PER_RUN, 2)).sum(axis=1)
        summary = {"reached": True, "violations": int(run < failed_runs), "fixes": FIXES_PER_RUN,
                   "mean_nees": nees_scale * rng.chisquare(3, NEES_STEPS).mean()}
        row = run_row(run, f"s{run}", 0, summary, 0.1)
        results.write_record(layout, RunRecord(run, row, None, fix_columns(run, log)))
    return validation.load_sweep(root)


@pytest.fixture(scope="module")
def uniform_model(tmp_path_factory):
    return validation.validate(write_sweep(tmp_path_factory.mktemp("u") / "mc", _scenario(), seed=1))


def _status(report) -> dict[str, CheckStatus]:
    return {c.name: c.status for c in report.checks}


def test_model_sweep_passes_every_applicable_check(uniform_model):
    assert _status(uniform_model) == {"runs": PASS, "containment": PASS, "promise": PASS, "bound": PASS,
                                      "tightness": PASS,
                                      "coverage": NA,
                                      "nees": PASS, "nis": PASS, "nees_nrun": NA, "nis_nrun": PASS,
                                      "plan": PASS, "blocking": NA}
    assert uniform_model.passed and uniform_model.failed == []
    assert uniform_model.fixes == RUNS * FIXES_PER_RUN


def test_bonferroni_split_over_the_statistical_checks_that_apply(uniform_model):
    # tightness, nees, nis, nis_nrun, plan apply (no per-step table: nees_nrun does not);
    # containment, promise and bound cannot fail under the model.
    assert uniform_model.statistical == 5
    assert uniform_model.alpha_per_check == pytest.approx(0.01 / 5)
    alphas = {c.name: c.alpha for c in uniform_model.checks}
    assert alphas == {"runs": 0.0, "containment": 0.0, "promise": 0.0, "bound": 0.0, "tightness": 0.002,
                      "coverage": None,
                      "nees": 0.002, "nis": 0.002, "nees_nrun": None, "nis_nrun": 0.002, "plan": 0.002,
                      "blocking": None}
    json.dumps(uniform_model.to_dict(), allow_nan=False)  # JSON-ready, no NaN


def test_bound_uses_half_the_diagonal_for_two_markers(uniform_model):
    # Two ranges: the LS point is the intersection, inside the parallelogram centred on the
    # truth, so the model's worst error is exactly half the long diagonal.
    b = uniform_model.check("bound").values
    assert b["model_worst_ratio"] == pytest.approx(0.5, rel=1e-9)
    assert 0.3 < b["max_ratio"] <= 0.5 + 0.01  # + the nonlinearity of the exact solution


def test_three_times_the_noise_fails_containment_and_bound(tmp_path):
    report = validation.validate(write_sweep(tmp_path / "mc", _scenario(), seed=2, error_scale=3.0))
    s = _status(report)
    assert s["containment"] is FAIL and s["bound"] is FAIL
    assert report.check("containment").values["misses"] > 0
    # three times the noise makes realised fault areas no larger (the bounds are the declared
    # ones): the promise is about the size of the area, containment about where the truth is
    assert s["promise"] is PASS
    assert report.check("bound").values["exceedances"] > 0


def test_a_third_of_the_noise_fails_tightness(tmp_path):
    report = validation.validate(write_sweep(tmp_path / "mc", _scenario(), seed=3, error_scale=1 / 3))
    s = _status(report)
    assert s["tightness"] is FAIL and s["bound"] is PASS and s["containment"] is PASS
    t = report.check("tightness").values
    assert t["max_ratio"] < t["threshold"]


def test_gaussian_coverage_passes_and_an_understated_covariance_fails(tmp_path):
    sc = _scenario("gaussian")
    good = validation.validate(write_sweep(tmp_path / "good", sc, seed=4))
    assert _status(good) == {"runs": PASS, "containment": NA, "promise": NA, "bound": NA, "tightness": NA,
                             "coverage": PASS,
                             "nees": PASS, "nis": PASS, "nees_nrun": NA, "nis_nrun": PASS, "plan": PASS, "blocking": NA}
    bad = validation.validate(write_sweep(tmp_path / "bad", sc, seed=5, error_scale=2.0))
    assert bad.check("coverage").status is FAIL
    # Independent count: errors twice the model's leave ~1 - exp(-chi2_95 / 8) inside.
    assert bad.check("coverage").values["inside"] / bad.fixes < 0.8


def test_overconfident_filter_fails_nees_and_nis(tmp_path):
    # 5 runs: the conservative NEES interval (runs as the unit) reaches 7.4, so 3x is needed.
    data = write_sweep(tmp_path / "mc", _scenario(), seed=6, nees_scale=3.0, nis_scale=1.5)
    report = validation.validate(data)
    assert report.check("nees").status is FAIL and report.check("nis").status is FAIL
    assert "overconfident" in report.check("nees").detail


def test_nees_and_nis_against_scipy(uniform_model, tmp_path):
    n = uniform_model.check("nis").values["updates"]
    assert n == RUNS * FIXES_PER_RUN * 2
    lo, hi = uniform_model.check("nis").values["interval"]
    a = uniform_model.alpha_per_check
    assert (lo, hi) == pytest.approx((stats.chi2.ppf(a / 2, n) / n, stats.chi2.isf(a / 2, n) / n))
    lo, hi = uniform_model.check("nees").values["interval"]
    dof = 3 * RUNS
    assert (lo, hi) == pytest.approx((stats.chi2.ppf(a / 2, dof) / RUNS, stats.chi2.isf(a / 2, dof) / RUNS))


def test_plan_fails_when_too_few_runs_stay_under_eps_max(tmp_path):
    report = validation.validate(write_sweep(tmp_path / "mc", _scenario(), seed=7, failed_runs=4))
    plan = report.check("plan")
    # 1 of 5: the Clopper-Pearson upper bound p solves P(X <= 1 | 5, p) = alpha / 2 (0.87 < 0.95).
    assert plan.status is FAIL and plan.values["successes"] == 1
    upper = optimize.brentq(lambda p: stats.binom.cdf(1, 5, p) - report.alpha_per_check / 2, 0.01, 0.999999, xtol=1e-12)
    assert plan.values["ci"][1] == pytest.approx(upper)


def test_a_fix_on_an_unplanned_subset_breaks_the_promise_and_an_old_sweep_is_not_judged_on_it(tmp_path):
    # a substitute for a marker the laser did not see (no line of sight blocked) did not keep the
    # plan, however small its realised area; a sweep written before the column reads it as null
    data = write_sweep(tmp_path / "mc", _scenario(), seed=1)
    assert data.fixes.unplanned is not None and not data.fixes.unplanned.any()
    marked = np.zeros(len(data.fixes), dtype=bool)
    marked[3] = True
    judged = dataclasses.replace(data, fixes=dataclasses.replace(data.fixes, unplanned=marked))
    res = promise(judged, 0.01, np.random.default_rng(0))
    assert res.status is CheckStatus.FAIL and res.values["unplanned"] == 1 and res.values["broken"] == 1
    old = dataclasses.replace(data, fixes=dataclasses.replace(data.fixes, unplanned=None))
    res = promise(old, 0.01, np.random.default_rng(0))
    assert res.status is CheckStatus.PASS and res.values["unplanned"] is None and "not recorded" in res.detail


def test_empty_sweep_is_not_applicable_never_pass():
    sc = _scenario()
    data = validation.from_tables(sc, RUN_SCHEMA.empty_table(), FIX_SCHEMA.empty_table())
    report = validation.validate(data)
    assert all(c.status is NA for c in report.checks)
    assert report.statistical == 0 and report.alpha_per_check is None and report.passed


def test_gated_updates_enter_at_the_gate(uniform_model, tmp_path):
    data = write_sweep(tmp_path / "mc", _scenario(), seed=1)
    fx = data.fixes
    fx.n_accepted[:3] = 1  # three updates gated: their NIS is not in the sums
    r = validation.validate(data).check("nis").values
    gate = stats.chi2.ppf(EPISODE_GATE_PROBABILITY, 1)
    assert r["gated"] == 3
    assert r["mean_nis"] == pytest.approx((fx.nis.sum() + 3 * gate) / r["updates"])


def test_gate_probability_is_the_localizers_default():
    from estimators.ekf import Localizer

    assert inspect.signature(Localizer).parameters["gate_probability"].default == EPISODE_GATE_PROBABILITY


def test_bad_alpha_and_bad_directories(tmp_path, uniform_model):
    sc = _scenario()
    data = validation.from_tables(sc, RUN_SCHEMA.empty_table(), FIX_SCHEMA.empty_table())
    for bad in (0.0, 1.0, -0.1, math.nan):
        with pytest.raises(SimulationError, match="alpha"):
            validation.validate(data, alpha=bad)
    with pytest.raises(OutputError, match="not a pefsim mc directory"):
        validation.load_sweep(tmp_path)
    root = tmp_path / "mc"
    write_sweep(root, sc, seed=8)
    with pytest.raises(OutputError, match="was made from another scenario"):
        validation.load_sweep(root, scenarios.load("warehouse"))
    (root / NEGATIVE_CONTROL_JSON).write_text('{"q_scale": 0.01}')
    assert validation.load_sweep(root, sc).q_scale == 0.01
    empty = tmp_path / "empty"
    SweepLayout(empty).make_dirs()
    results.write_atomic(SweepLayout(empty).scenario_toml, sc.text.encode())
    with pytest.raises(OutputError, match="no finished run"):
        validation.load_sweep(empty)


# -- the null model -----------------------------------------------------------------------------

def test_error_maps_against_the_inverse_jacobian():
    sc = _scenario()
    rng = np.random.default_rng(10)
    truth = rng.uniform([0.5, 0.5], [4.5, 4.5], (20, 2))
    mk = sc.marker_positions()
    amap = null.error_maps(np.broadcast_to(mk, (20, 2, 2)), truth, sc.sensor)
    for p, a in zip(truth, amap, strict=True):
        u = (p - mk) / np.hypot(*(p - mk).T)[:, None]
        rho = sc.sensor.range_bound(np.hypot(*(p - mk).T))
        np.testing.assert_allclose(a, np.linalg.solve(u, np.diag(rho)), rtol=1e-9)
    # Worst case against the paper's long diagonal (eq. 12, via the planner): exactly 1/2.
    tau = PEF(sc).tau_subset(truth, np.array([0, 1]))
    np.testing.assert_allclose(null.worst_case_ratio(amap, tau), 0.5, rtol=1e-9)


def test_tightness_threshold_against_the_closed_form():
    # Ratios uniform on (0, 1): P(max of N < f) = f^N, so f = alpha^(1/N).
    rng = np.random.default_rng(11)
    for n, alpha in ((10, 0.01), (300, 0.0025)):
        f = null.tightness_threshold(rng.uniform(size=(n, 2000)), alpha)
        assert f == pytest.approx(alpha ** (1 / n), abs=0.01 * (1 - alpha ** (1 / n)) + 2e-3)


def test_tightness_false_alarm_rate_at_real_geometries():
    """Sweeps drawn from the null fail the tightness check at about rate alpha, not more.

    alpha = 0.1 so that 400 null sweeps resolve the rate; the acceptance bound is the binomial
    (400, 0.1) quantile at 1 - 1e-4, plus the 5 % Monte-Carlo slack of the threshold.
    """
    sc = _scenario()
    rng = np.random.default_rng(12)
    truth = np.linspace([1.0, 1.5], [4.0, 3.0], 50)
    amap = null.error_maps(np.broadcast_to(sc.marker_positions(), (50, 2, 2)), truth, sc.sensor)
    tau = PEF(sc).tau_subset(truth, np.array([0, 1]))
    f = null.tightness_threshold(null.simulate_ratios(amap, tau, rng), 0.1)
    observed_max = null.simulate_ratios(amap, tau, np.random.default_rng(13), draws=400).max(axis=0)
    fails = int(np.sum(observed_max < f))
    assert fails <= stats.binom.ppf(1 - 1e-4, 400, 0.105)
    # Negative control: the same threshold rejects sweeps whose errors are 20 % smaller.
    assert np.mean(0.8 * observed_max < f) > 0.9
