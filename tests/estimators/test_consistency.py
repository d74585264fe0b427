"""Consistency statistics: chi2 and Clopper-Pearson intervals, NEES/NIS, their tests."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from estimators import consistency
from estimators.consistency import Verdict
from scenarios.errors import SimulationError


def _random_covs(rng, n, d):
    a = rng.normal(size=(n, d, d))
    return a @ np.swapaxes(a, 1, 2) + 0.1 * np.eye(d)


def test_nees_matches_filterpy():
    from filterpy.stats import NEES

    rng = np.random.default_rng(1)
    covs = _random_covs(rng, 30, 3)
    truth = rng.normal(size=(30, 3))
    est = truth + rng.normal(size=(30, 3))
    np.testing.assert_allclose(consistency.nees(est - truth, covs), NEES(truth, est, covs), rtol=1e-10)


def test_nis_scalar_and_matrix_forms_agree():
    rng = np.random.default_rng(2)
    y, s = rng.normal(size=40), rng.uniform(0.5, 2.0, size=40)
    np.testing.assert_allclose(consistency.nis(y, s), y**2 / s)
    np.testing.assert_allclose(consistency.nis(y[:, None], s[:, None, None]), y**2 / s)


def test_pose_errors_wrap_heading():
    e = consistency.pose_errors([[1.0, 2.0, math.pi - 0.1]], [[0.5, 2.5, -math.pi + 0.1]])
    np.testing.assert_allclose(e, [[0.5, -0.5, -0.2]], atol=1e-12)


@pytest.mark.parametrize("dof, n, alpha", [(1, 1, 0.05), (3, 20, 0.01), (1, 20000, 0.005), (2, 7, 0.3)])
def test_chi2_interval_tails_carry_alpha_over_two(dof, n, alpha):
    # Independent route to the same distribution: n*avg ~ chi2(n*dof) = Gamma(n*dof/2, scale 2).
    lo, hi = consistency.chi2_interval(dof, n, alpha)
    assert stats.gamma.cdf(lo * n, a=n * dof / 2, scale=2.0) == pytest.approx(alpha / 2, rel=1e-8)
    assert stats.gamma.sf(hi * n, a=n * dof / 2, scale=2.0) == pytest.approx(alpha / 2, rel=1e-8)
    assert lo < dof < hi


def test_chi2_interval_false_alarm_rate_by_simulation():
    # 20000 averages of 20 chi2(3) draws (as squared normals), alpha = 5 %. The rejection count
    # is binomial(20000, 0.05); the Clopper-Pearson interval at 0.1 % must contain 0.05.
    rng = np.random.default_rng(7)
    n, dof, alpha, reps = 20, 3, 0.05, 20000
    averages = (rng.standard_normal((reps, n, dof)) ** 2).sum(axis=2).mean(axis=1)
    lo, hi = consistency.chi2_interval(dof, n, alpha)
    rejected = int(np.count_nonzero((averages < lo) | (averages > hi)))
    assert consistency.fraction_test(rejected, reps, alpha, 0.001).passed
    # Negative control: the interval for the wrong dof (2) rejects far more often than 5 %.
    lo2, hi2 = consistency.chi2_interval(2, n, alpha)
    wrong = int(np.count_nonzero((averages < lo2) | (averages > hi2)))
    assert consistency.fraction_test(wrong, reps, alpha, 0.001).verdict is Verdict.ABOVE


def test_clopper_pearson_closed_forms_and_definition():
    alpha = 0.05
    # k = 0 and k = n have closed forms.
    assert consistency.clopper_pearson(0, 10, alpha) == pytest.approx((0.0, 1 - (alpha / 2) ** 0.1))
    assert consistency.clopper_pearson(10, 10, alpha) == pytest.approx(((alpha / 2) ** 0.1, 1.0))
    # Inside: at the bounds the binomial tails equal alpha/2 (the interval's definition).
    k, n = 37, 120
    lo, hi = consistency.clopper_pearson(k, n, alpha)
    assert stats.binom.sf(k - 1, n, lo) == pytest.approx(alpha / 2, rel=1e-8)
    assert stats.binom.cdf(k, n, hi) == pytest.approx(alpha / 2, rel=1e-8)


def test_fraction_test_verdicts():
    assert consistency.fraction_test(950, 1000, 0.95, 0.01).verdict is Verdict.INSIDE
    assert consistency.fraction_test(990, 1000, 0.95, 0.01).verdict is Verdict.ABOVE
    assert consistency.fraction_test(900, 1000, 0.95, 0.01).verdict is Verdict.BELOW


def _consistent_nees(rng, runs, steps, d, scale=1.0, rho=0.0):
    """NEES of Gaussian errors of a 'filter' that states their covariance exactly.

    The truth's errors are ``scale`` times larger, and AR(1)-correlated in time with
    coefficient ``rho`` (stationary, marginally exact).
    """
    covs = _random_covs(rng, runs, d)
    chol = np.linalg.cholesky(covs)
    white = rng.standard_normal((runs, steps, d))
    z = np.empty_like(white)
    z[:, 0] = white[:, 0]
    for k in range(1, steps):
        z[:, k] = rho * z[:, k - 1] + math.sqrt(1 - rho * rho) * white[:, k]
    errors = scale * np.einsum("rij,rkj->rki", chol, z)
    return consistency.nees(errors, covs[:, None])


def test_nees_test_accepts_consistent_and_rejects_wrong_scale():
    # Three checks at alpha = 1e-3 each (family false alarm <= 0.3 %). Scale 1.5 multiplies the
    # mean NEES by 2.25 (mean 6.75 vs interval hi ~4.8 for 20 runs of chi2(3)); 0.6 by 0.36.
    rng = np.random.default_rng(5)
    alpha = 1e-3
    for scale, verdict in [(1.0, Verdict.INSIDE), (1.5, Verdict.ABOVE), (0.6, Verdict.BELOW)]:
        res = consistency.nees_test(_consistent_nees(rng, 20, 100, 3, scale=scale), 3, alpha)
        assert res.verdict is verdict, f"scale {scale}: NEES {res.statistic:.3f} {res.interval}"


def test_nees_test_is_conservative_for_time_correlated_errors():
    # Errors that are consistent at every time but strongly correlated in time (AR(1), 0.95).
    # Over 400 repetitions nees_test (counting runs only) must not reject more often than its
    # alpha = 5 %: the Clopper-Pearson interval at 0.1 % of its rejection rate must reach down
    # to 0.05. Negative control: treating every time sample as independent (what is right for
    # NIS) rejects far more often than 5 %.
    rng = np.random.default_rng(9)
    alpha, reps = 0.05, 400
    runs_only = independent = 0
    for _ in range(reps):
        v = _consistent_nees(rng, 10, 100, 3, rho=0.95)
        runs_only += not consistency.nees_test(v, 3, alpha).passed
        independent += not consistency.average_test(v, 3, alpha).passed
    assert consistency.clopper_pearson(runs_only, reps, 0.001)[0] <= alpha
    assert consistency.fraction_test(independent, reps, alpha, 0.001).verdict is Verdict.ABOVE


def test_nis_test_counts_every_sample():
    rng = np.random.default_rng(4)
    v = rng.standard_normal(5000) ** 2
    res = consistency.nis_test(v, 1, 0.01)
    assert res.n == 5000 and res.passed
    assert res.interval == pytest.approx(consistency.chi2_interval(1, 5000, 0.01))
    # Negative control: 20 % too large innovations (NIS x 1.44) are far outside.
    assert consistency.nis_test(1.44 * v, 1, 0.01).verdict is Verdict.ABOVE


def test_bad_arguments_raise():
    with pytest.raises(SimulationError, match="alpha"):
        consistency.chi2_interval(3, 10, 1.5)
    with pytest.raises(SimulationError, match="k="):
        consistency.clopper_pearson(11, 10, 0.05)
    with pytest.raises(SimulationError, match="no finite values"):
        consistency.average_test([np.nan], 1, 0.05)
