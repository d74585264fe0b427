"""The predict step with encoder residual blocks: moments, layout, windows' count errors, the predictor."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from estimators import motion
from estimators.ekf import Localizer
from estimators.encoder_phase import LAGS, count_error_var
from estimators.motion_quantised import predictor_from, propagate_moments_quantised, read_correlation
from scenarios.errors import SimulationError
from scenarios.schema import RobotSpec, SensorSpec

ROBOT = RobotSpec()
TICK = 2 * math.pi * ROBOT.wheel_radius / ROBOT.encoder_ticks
QUANT_VAR = TICK**2 / 12
MARKERS = np.array([[0.0, 0.0], [10.0, 0.0]])
NO_SLIP = dataclasses.replace(ROBOT, odometry_noise=0.0)


def _block_predictor(turn: float, per_step: float, steps: int = 4) -> tuple[np.ndarray, float]:
    """Return the predictor of a wheel that turned ``turn`` ticks in each of its last reads of ``steps`` steps."""
    k = np.arange(LAGS + 1)
    coef = np.empty(LAGS)
    fresh = predictor_from(-turn * k, -steps * k.astype(float), np.zeros(LAGS + 1), per_step, coef)
    return coef, fresh


@pytest.mark.parametrize("biased, turns, per_step", [(True, (3.3, 7.9), 0.002), (False, (3.3, 7.9), 0.002),
                                                    (True, (3.3, 7.9), math.inf)])
def test_moments_match_sampling_the_model(biased, turns, per_step):
    # The model written out sample by sample: old state from its prior; each wheel's new residual
    # a . (its block) plus a fresh part of the predictor's error variance (all fresh when the turn
    # is not predicted); slip gaussian. The wheels roll (1 -/+ e)(d - q_0 + q_new + slip); the
    # blocks shift by one.
    rng = np.random.default_rng(5)
    nb = 2 * LAGS
    pred = [_block_predictor(t, per_step) for t in turns]
    # a prior with the blocks as the model makes them: the sawtooth covariance over the boundaries
    blocks = np.zeros((nb, nb))
    for w, t in enumerate(turns):
        k = np.arange(LAGS)
        lag = np.abs(k[:, None] - k[None, :])
        corr = np.vectorize(read_correlation)(t * lag, 0.002 * 4 * lag)
        blocks[w * LAGS:(w + 1) * LAGS, w * LAGS:(w + 1) * LAGS] = QUANT_VAR * corr
    P0 = np.zeros((4 + nb, 4 + nb))
    P0[:4, :4] = np.diag([1e-6, 2e-6, 1e-6, 4e-6])
    P0[3, 2] = P0[2, 3] = 0.1 * math.sqrt(4e-6 * 1e-6)
    P0[4:, 4:] = blocks
    P0[0, 4] = P0[4, 0] = 0.3 * math.sqrt(1e-6 * QUANT_VAR)
    P0[2, 4 + LAGS] = P0[4 + LAGS, 2] = -0.2 * math.sqrt(1e-6 * QUANT_VAR)
    P0 += 1e-9 * QUANT_VAR * np.eye(4 + nb)
    x0 = np.r_[1.0, 2.0, 0.3, 0.002, rng.normal(0, 1e-5, nb)]
    if not biased:
        keep = [0, 1, 2] + list(range(4, 4 + nb))
        x0, P0 = x0[keep], P0[np.ix_(keep, keep)]
    b0 = x0.size - nb
    d_left, d_right, var_left, var_right = 0.02, 0.025, 1e-8, 2e-8
    x, P = x0.copy(), P0.copy()
    propagate_moments_quantised(x, P, d_left, d_right, ROBOT.wheel_base, var_left, var_right, QUANT_VAR, 0.0, 0.0,
                                pred[0][0], pred[1][0], pred[0][1], pred[1][1])
    n = 400_000
    s = rng.multivariate_normal(x0, P0, n)
    e = s[:, 3] if biased else np.zeros(n)
    t, new_blocks = [], []
    for w, d, var in ((0, d_left, var_left), (1, d_right, var_right)):
        block = s[:, b0 + w * LAGS:b0 + (w + 1) * LAGS]
        coef, fresh = pred[w]
        q = block @ coef + rng.standard_normal(n) * math.sqrt(fresh * QUANT_VAR)
        u = d - block[:, 0] + q + rng.standard_normal(n) * math.sqrt(var)
        t.append((1 - e) * u if w == 0 else (1 + e) * u)
        new_blocks.append(np.column_stack([q, block[:, :-1]]))
    z = np.column_stack([motion.propagate(s[:, :3], t[0], t[1], ROBOT.wheel_base), *([e] if biased else []),
                         *new_blocks])
    # Sampling error of a variance with 4e5 samples: ~0.2 % (normal) -> 1 % is > 4 sigma.
    np.testing.assert_allclose(np.diag(np.cov(z.T)), np.diag(P), rtol=0.01)
    corr = np.cov(z.T) / np.sqrt(np.outer(np.diag(P), np.diag(P)))
    np.testing.assert_allclose(corr, P / np.sqrt(np.outer(np.diag(P), np.diag(P))), atol=0.01)
    np.testing.assert_allclose(z.mean(axis=0), x, atol=3e-5)
    assert np.array_equal(P, P.T)


def test_localizer_layout_and_known_start_residuals():
    loc = Localizer(ROBOT, SensorSpec(), MARKERS, [1.0, 2.0, 0.0], np.eye(3) * 1e-6, estimate_wheel_bias=True,
                    encoder_residual_state=True, residual0=[1e-5, -2e-5])
    n = 4 + 2 * LAGS
    assert loc.full_x.shape == (n,) and loc.full_P.shape == (n, n)
    np.testing.assert_array_equal(loc.full_x[4:], np.repeat([1e-5, -2e-5], LAGS))
    np.testing.assert_array_equal(loc.full_P[4:, :], 0.0)          # known exactly
    assert loc.x.shape == (3,) and loc.P.shape == (3, 3)
    unknown = Localizer(ROBOT, SensorSpec(), MARKERS, [1.0, 2.0, 0.0], np.eye(3) * 1e-6,
                        encoder_residual_state=True)
    assert unknown.full_x.shape == (3 + 2 * LAGS,)
    np.testing.assert_array_equal(unknown.full_x[3:], 0.0)
    # each block is one residual at the start, tick^2 / 12, the two wheels independent
    blocks = unknown.full_P[3:, 3:]
    np.testing.assert_allclose(blocks[:LAGS, :LAGS], QUANT_VAR, rtol=1e-12)
    np.testing.assert_array_equal(blocks[:LAGS, LAGS:], 0.0)
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
    assert abs(read_correlation(44.0 + f, 0.0) - np.corrcoef(q0, q1)[0, 1]) < 0.01
    empirical = np.var(q0 - q1)
    assert abs(_read_count_error_var(44.0 + f, 4) - empirical) < 0.01
    if f in (0.004, 0.5):
        assert abs(_read_count_error_var(44.0 + f, None) - empirical) > 0.01


def _read_count_error_var(turn: float, steps: int | None, reads: int = 1) -> float:
    """Return the model's variance of a wheel's count error over ``reads`` reads on the spot [tick^2].

    The filter (no slip) turns on the spot at a steady command for 150 reads of 4 steps, so the
    phase history is there, then the pose is made known and it predicts ``reads`` more reads of
    ``steps`` steps (None: the turn not predicted): the heading's variance is
    ``(var_l + var_r) / b^2`` of the two wheels' count errors over the window.
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
    for _ in range(reads):
        loc.predict(-turn * TICK, turn * TICK, 0.0, steps)
    return loc.P[2, 2] * ROBOT.wheel_base**2 / 2 / TICK**2


@pytest.mark.parametrize("f, sigma", [(0.0, 0.01), (0.004, 0.003), (0.02, 0.05), (0.5, 0.05), (0.3, 0.3)])
def test_a_correlation_over_an_uncertain_turn_is_the_sampled_one(f, sigma):
    # The turn known to sigma: residuals at its two ends from sampled phases and turns. 2e5
    # samples: a correlation to ~0.003, so 0.012 is > 4 sigma. Where the spread is wider than
    # f the exact turn's correlation is the negative control (off by ~6 (E|f| - f0)).
    rng = np.random.default_rng(int(1000 * f + 100 * sigma))
    theta0 = rng.uniform(0, 1, 200_000)
    turn = 44.0 + f + sigma * rng.standard_normal(theta0.size)
    q0, q1 = theta0 % 1.0, (theta0 + turn) % 1.0
    sampled = np.corrcoef(q0, q1)[0, 1]
    assert abs(read_correlation(44.0 + f, sigma) - sampled) < 0.012
    assert read_correlation(44.0 + f, sigma) == pytest.approx(1 - 6 * float(count_error_var(44.0 + f, sigma)), abs=1e-9)
    if sigma > f:
        assert abs(read_correlation(44.0 + f, 0.0) - sampled) > 0.012


def test_the_predictor_from_one_boundary_is_the_correlation_and_from_none_is_fresh():
    coef = np.empty(1)
    fresh = predictor_from(np.array([44.3, 0.0]), np.array([4.0, 0.0]), np.zeros(2), 0.001, coef)
    c = read_correlation(44.3, 0.004)
    assert coef[0] == pytest.approx(c, rel=1e-6) and fresh == pytest.approx(1 - c * c, rel=1e-6)
    coef = np.empty(LAGS)
    k = np.arange(LAGS + 1, dtype=float)
    # boundaries of another segment, or a turn not predicted: a new residual
    assert predictor_from(44.3 * k, 4 * k, np.r_[1.0, np.zeros(LAGS)], 0.001, coef) == 1.0
    np.testing.assert_array_equal(coef, 0.0)
    assert predictor_from(44.3 * k, 4 * k, np.zeros(LAGS + 1), math.inf, coef) == 1.0
    # a wheel that stood still, its tracking known: the residual is the one it had
    assert predictor_from(np.zeros(LAGS + 1), 4 * k, np.zeros(LAGS + 1), 1e-9, coef) < 1e-6
    assert coef.sum() == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize("reads", [2, 4, 6, LAGS])
def test_a_slowly_walking_phase_has_the_count_errors_of_its_windows(reads):
    # random-23-000's left wheel: 44.94 ticks a read, so its phase walks back 0.06 a read and a
    # window of 8 reads turns it 7.52: count-error variance near 1/4, not the 1/6 of unrelated
    # ends. Sampled over phases uniform in a tick: f (1 - f) of the window's fractional turn to
    # ~0.001 at 2e5 samples; the model's to its drift sigma (~0.03 ticks over 8 reads: < 0.006).
    # The negative control is the model before this one, each read related to the last only
    # (an AR(1): the window's correlation the product of the reads').
    turn = 44.94
    rng = np.random.default_rng(reads)
    theta0 = rng.uniform(0, 1, 200_000)
    window = turn * reads
    sampled = np.var(window - (np.floor(theta0 + window) - np.floor(theta0)))
    assert abs(_read_count_error_var(turn, 4, reads) - sampled) < 0.01
    ar1 = 2 * (1 - read_correlation(turn, 0.0) ** reads) / 12
    if reads >= 4:
        assert abs(ar1 - sampled) > 0.01
