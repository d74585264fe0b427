"""The predict step with encoder residual states: moments against sampling, layout, bounded count error."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from estimators import motion
from estimators.ekf import Localizer
from estimators.motion_quantised import propagate_moments_quantised, read_correlation
from scenarios.errors import SimulationError
from scenarios.schema import RobotSpec, SensorSpec

ROBOT = RobotSpec()
TICK = 2 * math.pi * ROBOT.wheel_radius / ROBOT.encoder_ticks
QUANT_VAR = TICK**2 / 12
MARKERS = np.array([[0.0, 0.0], [10.0, 0.0]])
NO_SLIP = dataclasses.replace(ROBOT, odometry_noise=0.0)


@pytest.mark.parametrize("biased, turns, sigma", [(True, (3.3, 7.9), 0.01), (False, (3.3, 7.9), 0.01),
                                                 (True, (3.3, 7.9), math.inf)])
def test_moments_match_sampling_the_model(biased, turns, sigma):
    # The model written out sample by sample: old state from its prior; each wheel's new residual
    # c q_old plus a fresh part of variance (1 - c^2) tick^2 / 12, c the sawtooth's correlation
    # over the read's fractional turn (0 when the turn is not predicted); slip gaussian. The
    # wheels roll (1 -/+ e)(d - q_old + q_new + slip).
    rng = np.random.default_rng(5)
    x0 = np.r_[1.0, 2.0, 0.3, 0.002, rng.normal(0, 1e-5, 2)]
    P0 = np.diag([1e-6, 2e-6, 1e-6, 4e-6, QUANT_VAR, QUANT_VAR])
    P0[0, 4] = P0[4, 0] = 0.3 * math.sqrt(1e-6 * QUANT_VAR)
    P0[2, 5] = P0[5, 2] = -0.2 * math.sqrt(1e-6 * QUANT_VAR)
    P0[3, 2] = P0[2, 3] = 0.1 * math.sqrt(4e-6 * 1e-6)
    if not biased:
        keep = [0, 1, 2, 4, 5]
        x0, P0 = x0[keep], P0[np.ix_(keep, keep)]
    d_left, d_right, var_left, var_right = 0.02, 0.025, 1e-8, 2e-8
    x, P = x0.copy(), P0.copy()
    propagate_moments_quantised(x, P, d_left, d_right, ROBOT.wheel_base, var_left, var_right, QUANT_VAR, 0.0, 0.0,
                                turns[0], turns[1], sigma, sigma)
    n = 400_000
    s = rng.multivariate_normal(x0, P0, n)
    e = s[:, 3] if biased else np.zeros(n)
    t, q_new = [], []
    for w, d, var in ((0, d_left, var_left), (1, d_right, var_right)):
        f = turns[w] % 1.0
        c = 1 - 6 * f * (1 - f) if sigma < math.inf else 0.0
        q = c * s[:, -2 + w] + rng.standard_normal(n) * math.sqrt((1 - c * c) * QUANT_VAR)
        u = d - s[:, -2 + w] + q + rng.standard_normal(n) * math.sqrt(var)
        t.append((1 - e) * u if w == 0 else (1 + e) * u)
        q_new.append(q)
    z = np.column_stack([motion.propagate(s[:, :3], t[0], t[1], ROBOT.wheel_base), *([e] if biased else []), *q_new])
    # Sampling error of a variance with 4e5 samples: ~0.2 % (normal) -> 1 % is > 4 sigma.
    np.testing.assert_allclose(np.diag(np.cov(z.T)), np.diag(P), rtol=0.01)
    corr = np.cov(z.T) / np.sqrt(np.outer(np.diag(P), np.diag(P)))
    np.testing.assert_allclose(corr, P / np.sqrt(np.outer(np.diag(P), np.diag(P))), atol=0.01)
    np.testing.assert_allclose(z.mean(axis=0), x, atol=3e-5)
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
    np.testing.assert_array_equal(unknown.full_x[3:], 0.0)
    np.testing.assert_allclose(np.diag(unknown.full_P)[3:], QUANT_VAR, rtol=1e-12)   # tick^2 / 12 each
    with pytest.raises(SimulationError, match="residual0"):
        Localizer(ROBOT, SensorSpec(), MARKERS, [1.0, 2.0, 0.0], np.eye(3) * 1e-6, residual0=[0.0, 0.0])


def _count_error_var(reads: int, residual_state: bool) -> float:
    """Return the model's variance of a wheel's count error over ``reads`` reads on the spot [tick^2].

    The filter (no slip) turns on the spot from a known pose; the heading's variance is then
    ``(var_l + var_r) / b^2`` of the two wheels' count errors over the window.
    """
    loc = Localizer(NO_SLIP, SensorSpec(), MARKERS, [1.0, 2.0, 0.0], np.eye(3) * 1e-12,
                    encoder_residual_state=residual_state)
    for _ in range(reads):
        loc.predict(-44.3 * TICK, 44.3 * TICK, 0.0, 4)
    return (loc.P[2, 2] - 1e-12) * ROBOT.wheel_base**2 / 2 / TICK**2


@pytest.mark.parametrize("reads", [1, 50])
def test_the_count_error_over_a_window_stays_that_of_two_residuals(reads):
    # Sampled: a wheel from a phase uniform over a tick, reads that turn it whole ticks plus a
    # fraction drawn anew for each window (the filter does not know where in a tick the wheel
    # stops): over any number of reads the count error telescopes to the difference of the
    # residuals at the window's ends, variance tick^2 / 6 (= the mean of f (1 - f) over the
    # fraction f). The white model (no residual states) adds tick^2 / 12 per read, unbounded:
    # the negative control, 50 / 12 tick^2 at 50 reads.
    rng = np.random.default_rng(reads)
    n_windows = 200_000
    theta0 = rng.uniform(0, 1, n_windows)
    turn = rng.uniform(44.0, 45.0, (n_windows, reads)).sum(axis=1)
    empirical = np.var(turn - (np.floor(theta0 + turn) - np.floor(theta0)))
    # 1/6 to ~0.5 % at 2e5 samples: 0.005 tick^2 is > 5 sigma
    assert abs(_count_error_var(reads, True) - empirical) < 0.005
    assert abs(empirical - 1 / 6) < 0.005
    if reads > 1:
        assert abs(_count_error_var(reads, False) - empirical) > 0.005


@pytest.mark.parametrize("f", [0.004, 0.25, 0.5, 0.83])
def test_a_reads_count_error_has_the_variance_of_its_fractional_turn(f):
    # Sampled: a wheel from a phase uniform over a tick, a read that turns it 44 + f ticks: the
    # residual's correlation across the read is 1 - 6 f (1 - f) and the count error's variance
    # f (1 - f). The model's, with the turn predicted, is that; independent residuals (the turn
    # not predicted) give 1/6 whatever f: the negative control, off at f = 0.004 and 0.5.
    rng = np.random.default_rng(int(f * 1000))
    theta0 = rng.uniform(0, 1, 200_000)
    q0, q1 = theta0 % 1.0 - 0.5, (theta0 + 44.0 + f) % 1.0 - 0.5
    # correlation and variance to ~0.005 at 2e5 samples: 0.01 is > 4 sigma
    assert abs(read_correlation(44.0 + f, 0.01) - np.corrcoef(q0, q1)[0, 1]) < 0.01
    empirical = np.var(q0 - q1)
    assert abs(_read_count_error_var(44.0 + f, 4) - empirical) < 0.01
    if f in (0.004, 0.5):
        assert abs(_read_count_error_var(44.0 + f, None) - empirical) > 0.01


def _read_count_error_var(turn: float, steps: int | None) -> float:
    """Return the model's variance of one read's count error on the spot [tick^2] (``steps`` None: turn not predicted).

    The filter (no slip) turns on the spot at a steady command for 150 reads of 4 steps, so the
    phase history is there, then the pose is made known and it predicts one more read: the
    heading's variance is ``(var_l + var_r) / b^2`` of the two wheels' count errors.
    """
    dt = 1 / 240
    loc = Localizer(NO_SLIP, SensorSpec(), MARKERS, [1.0, 2.0, 0.0], np.eye(3) * 1e-8, encoder_residual_state=True,
                    step_time=dt)
    rate = turn / (4 * dt) / (ROBOT.encoder_ticks / (2 * math.pi))   # rad/s
    loc.set_command(-rate, rate)
    for _ in range(150):
        loc.predict(-turn * TICK, turn * TICK, 0.0, 4)
    x, P = loc.state_arrays()
    P[:3, :] = 0.0
    P[:, :3] = 0.0
    loc.predict(-turn * TICK, turn * TICK, 0.0, steps)
    return loc.P[2, 2] * ROBOT.wheel_base**2 / 2 / TICK**2
