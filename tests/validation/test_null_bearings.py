"""The null model and the snapshot covariance of fixes that measure bearings.

A fix with bearings estimates the heading with the position (:mod:`estimators.snapshot`), so
its error does not depend on any other heading estimate. These tests draw fixes the way an
episode makes them (uniform or gaussian errors, the heading handed to the fix off by a filter's
error) and hold the snapshot errors to what :mod:`validation.null` and the snapshot's
covariance say. Each has a negative control: the model of a fix that takes the heading as
exact (what both described before), which the same statistic rejects.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

from estimators.measurements import bearing, draw_bearing_errors, draw_range_errors, ranges
from estimators.snapshot import snapshot_fix
from scenarios.schema import NoiseModel, SensorSpec
from validation import null

XI = math.radians(0.05)
MARKERS = np.array([[0.0, 0.0], [6.0, 0.5]])
TRUTH = np.array([2.5, 3.5])
HEADING, HEADING_STD = 0.3, 0.003   # the filter's heading error handed to the fix [rad]
N_FIXES = 800
ALPHA = 1e-3
"""False-alarm probability of each statistical assertion below."""


def _sensor(noise: NoiseModel) -> SensorSpec:
    return SensorSpec(relative_error=2e-4, absolute_error=0.002, bearing_error=XI, noise=noise)


def _heading_known_map(sensor: SensorSpec) -> np.ndarray:
    """Return the null map (2, 2k) of a fix that takes the heading as exact: rows ``u`` and ``t``."""
    d = TRUTH - MARKERS
    r = np.hypot(d[:, 0], d[:, 1])
    u = d / r[:, None]
    g = np.vstack([u, np.column_stack([-u[:, 1], u[:, 0]])])
    b = np.r_[sensor.range_bound(r), r * sensor.bearing_error]
    gw = g / b[:, None] ** 2
    return np.linalg.solve(g.T @ gw, gw.T) * b


def _fixes(noise: NoiseModel, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Errors (N, 2) [m] and covariances (N, 2, 2) [m^2] of snapshot fixes with bearings."""
    sensor = _sensor(noise)
    rng = np.random.default_rng(seed)
    r = ranges(TRUTH, MARKERS)
    rho = sensor.range_bound(r)
    true_b = bearing(np.r_[TRUTH, HEADING], MARKERS)
    err, cov = np.empty((N_FIXES, 2)), np.empty((N_FIXES, 2, 2))
    for j in range(N_FIXES):
        z = r + draw_range_errors(rng, rho, noise)
        b = true_b + draw_bearing_errors(rng, XI, 2, noise)
        heading = HEADING + rng.normal(0.0, HEADING_STD)
        fix = snapshot_fix(MARKERS, z, rho, TRUTH + rng.normal(0, 0.01, 2), noise, bearings=b,
                           bearing_error=XI, heading=heading)
        err[j], cov[j] = fix.position - TRUTH, fix.covariance
    return err, cov


def test_snapshot_with_bearings_does_not_depend_on_the_heading_it_is_given():
    sensor = _sensor(NoiseModel.UNIFORM)
    r = ranges(TRUTH, MARKERS)
    z = r + np.array([0.001, -0.0015])
    b = bearing(np.r_[TRUTH, HEADING], MARKERS) + np.array([2e-4, -5e-4])
    fixes = [snapshot_fix(MARKERS, z, sensor.range_bound(r), TRUTH, NoiseModel.UNIFORM, bearings=b,
                          bearing_error=XI, heading=HEADING + dh) for dh in (0.0, 0.01, -0.02)]
    for f in fixes[1:]:
        np.testing.assert_allclose(f.position, fixes[0].position, atol=1e-9)
        np.testing.assert_allclose(f.covariance, fixes[0].covariance, rtol=1e-6)
        assert abs(f.heading - fixes[0].heading) < 1e-9


def test_null_model_describes_snapshot_errors_with_bearings():
    """Two-sample KS at ALPHA: the snapshot errors against the null's draws at the same fix.

    Negative control: the null of a fix that takes the heading as exact (the map before) is
    rejected by the same test.
    """
    sensor = _sensor(NoiseModel.UNIFORM)
    err, _ = _fixes(NoiseModel.UNIFORM, seed=31)
    observed = np.hypot(err[:, 0], err[:, 1])
    amap = null.error_maps(MARKERS[None], TRUTH[None], sensor)
    assert amap.shape == (1, 2, 4)
    rng = np.random.default_rng(32)
    simulated = null.simulate_ratios(amap, np.ones(1), rng, draws=20_000)[0]
    assert stats.ks_2samp(observed, simulated).pvalue > ALPHA
    old = null.simulate_ratios(_heading_known_map(sensor)[None], np.ones(1), rng, draws=20_000)[0]
    assert stats.ks_2samp(observed, old).pvalue < ALPHA


def test_null_model_without_bearings_is_unchanged():
    sensor = SensorSpec(relative_error=2e-4, absolute_error=0.002)
    amap = null.error_maps(MARKERS[None], TRUTH[None], sensor)[0]
    d = TRUTH - MARKERS
    u = d / np.hypot(d[:, 0], d[:, 1])[:, None]
    np.testing.assert_allclose(amap, np.linalg.solve(u, np.diag(sensor.range_bound(np.hypot(*d.T)))), rtol=1e-12)


def test_snapshot_covariance_with_bearings_covers_its_errors():
    """Mean squared Mahalanobis distance of gaussian fixes in the two-sided chi2(2N)/N interval at ALPHA.

    Negative control: the covariance of the heading-known fix, ``(H^T W H)^-1`` of ranges and
    world bearings with the bearing std widened by the heading's std (what the episode used),
    judged on the same errors.
    """
    sensor = _sensor(NoiseModel.GAUSSIAN)
    err, cov = _fixes(NoiseModel.GAUSSIAN, seed=41)
    m2 = np.einsum("fi,fi->f", err, np.linalg.solve(cov, err[..., None])[..., 0])
    lo, hi = stats.chi2.ppf([ALPHA / 2, 1 - ALPHA / 2], 2 * N_FIXES) / N_FIXES
    assert lo <= m2.mean() <= hi, (m2.mean(), lo, hi)
    d = TRUTH - MARKERS
    r = np.hypot(d[:, 0], d[:, 1])
    jac = np.vstack([d / r[:, None], np.column_stack([-d[:, 1], d[:, 0]]) / (r * r)[:, None]])
    std = np.r_[sensor.range_bound(r) / 3.0, np.full(2, XI / 3.0 + HEADING_STD)]
    old_cov = np.linalg.inv((jac / std[:, None] ** 2).T @ jac)
    m2_old = np.einsum("fi,fi->f", err, np.linalg.solve(old_cov, err.T).T)
    assert not lo <= m2_old.mean() <= hi, m2_old.mean()
