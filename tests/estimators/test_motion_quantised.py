"""The predict step with encoder residual states: moments against sampling, layout, bounded standstill."""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimators import motion
from estimators.ekf import Localizer
from estimators.motion_quantised import propagate_moments_quantised
from scenarios.errors import SimulationError
from scenarios.schema import RobotSpec, SensorSpec

ROBOT = RobotSpec()
TICK = 2 * math.pi * ROBOT.wheel_radius / ROBOT.encoder_ticks
QUANT_VAR = TICK**2 / 12
MARKERS = np.array([[0.0, 0.0], [10.0, 0.0]])


def test_moments_match_sampling_the_model():
    # The model written out sample by sample: old state from its prior, new residuals uniform
    # over a tick, slip gaussian; the travel the wheels roll is (1 -/+ e)(d - q_old + q_new + slip).
    x0 = np.array([1.0, 2.0, 0.3, 0.002, 1e-4, -1e-4])
    P0 = np.diag([1e-6, 2e-6, 1e-6, 4e-6, QUANT_VAR, QUANT_VAR])
    P0[0, 4] = P0[4, 0] = 0.3 * math.sqrt(1e-6 * QUANT_VAR)
    d_left, d_right, var_left, var_right = 0.02, 0.025, 1e-8, 2e-8
    x, P = x0.copy(), P0.copy()
    propagate_moments_quantised(x, P, d_left, d_right, ROBOT.wheel_base, var_left, var_right, QUANT_VAR, 0.0)
    rng = np.random.default_rng(5)
    n = 400_000
    s = rng.multivariate_normal(x0, P0, n)
    q_new = rng.uniform(-TICK / 2, TICK / 2, (n, 2))
    slip = rng.standard_normal((n, 2)) * np.sqrt([var_left, var_right])
    tl = (1 - s[:, 3]) * (d_left - s[:, 4] + q_new[:, 0] + slip[:, 0])
    tr = (1 + s[:, 3]) * (d_right - s[:, 5] + q_new[:, 1] + slip[:, 1])
    z = np.column_stack([motion.propagate(s[:, :3], tl, tr, ROBOT.wheel_base), s[:, 3], q_new])
    # Sampling error of a variance with 4e5 samples: ~0.2 % (normal) -> 1 % is > 4 sigma.
    np.testing.assert_allclose(np.diag(np.cov(z.T)), np.diag(P), rtol=0.01)
    corr = np.cov(z.T) / np.sqrt(np.outer(np.diag(P), np.diag(P)))
    np.testing.assert_allclose(corr, P / np.sqrt(np.outer(np.diag(P), np.diag(P))), atol=0.01)
    np.testing.assert_allclose(z.mean(axis=0)[:4], x[:4], atol=3e-5)
    assert np.array_equal(P, P.T)


def test_localizer_layout_and_known_start_residuals():
    loc = Localizer(ROBOT, SensorSpec(), MARKERS, [1.0, 2.0, 0.0], np.eye(3) * 1e-6, estimate_wheel_bias=True,
                    encoder_residual_state=True, residual0=[1e-5, -2e-5])
    assert loc.full_x.shape == (6,) and loc.full_P.shape == (6, 6)
    np.testing.assert_array_equal(loc.full_x[4:], [1e-5, -2e-5])
    np.testing.assert_array_equal(loc.full_P[4:, :], 0.0)          # known exactly
    assert loc.x.shape == (3,) and loc.P.shape == (3, 3)
    unknown = Localizer(ROBOT, SensorSpec(), MARKERS, [1.0, 2.0, 0.0], np.eye(3) * 1e-6,
                        encoder_residual_state=True)
    assert unknown.full_x.shape == (5,)
    np.testing.assert_allclose(np.diag(unknown.full_P)[3:], QUANT_VAR, rtol=1e-12)
    with pytest.raises(SimulationError, match="residual0"):
        Localizer(ROBOT, SensorSpec(), MARKERS, [1.0, 2.0, 0.0], np.eye(3) * 1e-6, residual0=[0.0, 0.0])


def test_standstill_covariance_stays_bounded_unlike_the_white_model():
    # At standstill the count error cannot exceed a tick; the white model's grows like sqrt(steps).
    exact = Localizer(ROBOT, SensorSpec(), MARKERS, [1.0, 2.0, 0.0], np.eye(3) * 1e-8, encoder_residual_state=True)
    white = Localizer(ROBOT, SensorSpec(), MARKERS, [1.0, 2.0, 0.0], np.eye(3) * 1e-8)
    for _ in range(600):      # 10 s at 60 Hz
        exact.predict(0.0, 0.0)
        white.predict(0.0, 0.0)
    # exact: at most the start plus one residual per wheel (and the variance floor per step)
    bound = 1e-8 + 2 * (QUANT_VAR + 600 * motion.VARIANCE_FLOOR) / ROBOT.wheel_base**2 * 4
    assert exact.P[2, 2] <= bound
    assert white.P[2, 2] > 100 * exact.P[2, 2] / 2
