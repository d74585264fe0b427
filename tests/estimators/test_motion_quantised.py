"""The predict step with encoder residual harmonics: moments, layout, windows' count errors, the remainder."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from estimators import encoder_phase, motion
from estimators.ekf import Localizer
from estimators.encoder_phase import boundaries, new_state, phase_advance
from estimators.motion_quantised import (
    BLOCK,
    HARMONICS,
    block_prior,
    propagate_moments_quantised,
    remainder_correlation,
    remainder_share,
    residual_block,
)
from scenarios.errors import SimulationError
from scenarios.schema import RobotSpec, SensorSpec

ROBOT = RobotSpec()
TICK = 2 * math.pi * ROBOT.wheel_radius / ROBOT.encoder_ticks
QUANT_VAR = TICK**2 / 12
MARKERS = np.array([[0.0, 0.0], [10.0, 0.0]])
NO_SLIP = dataclasses.replace(ROBOT, odometry_noise=0.0)
DT = 1 / 240


def _saw(phase: np.ndarray) -> np.ndarray:
    """Centred residual of a wheel at ``phase`` [ticks], in ticks."""
    return phase - np.floor(phase) - 0.5


def _harmonics(phase: np.ndarray, m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return the sawtooth's phasor components ``a_m``, ``b_m`` at start phase ``phase`` [ticks], in ticks."""
    a = -np.sin(2 * np.pi * m * phase[..., None]) / (np.pi * m)
    b = -np.cos(2 * np.pi * m * phase[..., None]) / (np.pi * m)
    return a, b


def _phase_after(turns: tuple[float, float], predicted: bool, reads: int = 3) -> np.ndarray:
    """Return a phase state after ``reads`` reads of 4 steps turning the wheels ``turns`` ticks each."""
    state = new_state(ROBOT.encoder_ticks, ROBOT.wheel_radius, DT if predicted else None)
    per_rad = ROBOT.encoder_ticks / (2 * math.pi)
    state[encoder_phase.CMD_LEFT] = turns[0] / (4 * DT * per_rad)
    state[encoder_phase.CMD_RIGHT] = turns[1] / (4 * DT * per_rad)
    for _ in range(reads):
        state[encoder_phase.STEPS] = 4
        phase_advance(state, turns[0] * TICK, turns[1] * TICK)
    return state


def test_the_prior_splits_a_residual_into_harmonics_and_a_remainder():
    # Sampled over phases uniform in a tick: each phasor component has 6 / (pi m)^2 of the
    # residual's variance, and the sum of the carried ones misses the residual by the
    # remainder's share (7.1 % for 8 harmonics). 2e5 samples: variances to ~0.3 %.
    rng = np.random.default_rng(3)
    phase = rng.uniform(0, 1, 200_000)
    m = np.arange(1, HARMONICS + 1)
    a, b = _harmonics(phase, m)
    prior = block_prior()
    np.testing.assert_allclose(prior[:-1:2], 12 * a.var(axis=0), rtol=0.015)
    np.testing.assert_allclose(prior[1:-1:2], 12 * b.var(axis=0), rtol=0.015)
    rest = _saw(phase) - a.sum(axis=1)
    assert prior[-1] == remainder_share() == pytest.approx(12 * rest.var(), rel=0.02)
    # at any turn one component's worth per harmonic, and the remainder: the residual's variance
    assert prior[:-1:2].sum() + prior[-1] == pytest.approx(1.0, rel=1e-12)


@pytest.mark.parametrize("f, sigma", [(0.25, 0.0), (0.0, 0.003), (0.0, 0.01), (0.8, 0.05)])
def test_the_remainders_correlation_over_a_read_is_the_sampled_one(f, sigma):
    # The remainder at a read's two ends, from sampled phases and turns known to sigma. 2e5
    # samples: a correlation to ~0.003, so 0.015 is > 4 sigma. The negative control, where the
    # spread matters (a whole tick's turn, whose exact correlation is 1), is the exact turn's.
    rng = np.random.default_rng(int(1000 * f + 1e4 * sigma))
    phase = rng.uniform(0, 1, 200_000)
    turn = 44.0 + f + sigma * rng.standard_normal(phase.size)
    m = np.arange(1, HARMONICS + 1)
    a0, b0 = _harmonics(phase, m)
    r0 = _saw(phase) - a0.sum(axis=1)
    # the carried harmonics at the read's end: q(c) = sum a cos(2 pi m c) + b sin(2 pi m c), c = turn
    carried = (a0 * np.cos(2 * np.pi * m * turn[:, None]) + b0 * np.sin(2 * np.pi * m * turn[:, None])).sum(axis=1)
    r1 = _saw(phase + turn) - carried
    sampled = np.corrcoef(r0, r1)[0, 1]
    assert abs(remainder_correlation(44.0 + f, sigma) - sampled) < 0.015
    if sigma > 0.0 and f == 0.0:
        assert abs(remainder_correlation(44.0 + f, 0.0) - sampled) > 0.015
    assert remainder_correlation(44.0 + f, math.inf) == 0.0


@pytest.mark.parametrize("biased, predicted", [(True, True), (False, True), (True, False)])
def test_moments_match_sampling_the_model(biased, predicted):
    # The model written out sample by sample: old state from a correlated prior; each wheel's
    # residual at a boundary of commanded turn c is sum_m a_m cos(2 pi m c) + b_m sin(2 pi m c)
    # + r. Predicted: the phasors kept, r' = rho r + fresh; not predicted: phasors and r redrawn
    # from their prior. The wheels roll (1 -/+ e)(d - q(c_old) + q(c_new) + slip).
    rng = np.random.default_rng(5)
    turns = (3.3, 7.9)
    # 150 reads: a history of 600 steps, so the remainder's spread is known and rho is not 0
    phase = _phase_after(turns, predicted, reads=150)
    nb = 2 * BLOCK
    prior = QUANT_VAR * np.tile(block_prior(), 2)
    root = rng.normal(0, 0.15, (4 + nb, 4 + nb))
    P0 = np.diag(np.r_[1e-6, 2e-6, 1e-6, 4e-6, prior])
    scale = np.sqrt(np.diag(P0))
    C = np.eye(4 + nb) + 0.5 * (root @ root.T) / (4 + nb)           # a correlation-like SPD matrix
    C /= np.sqrt(np.outer(np.diag(C), np.diag(C)))
    P0 = C * np.outer(scale, scale)
    x0 = np.r_[1.0, 2.0, 0.3, 0.002, rng.normal(0, 1e-5, nb)]
    if not biased:
        keep = [0, 1, 2] + list(range(4, 4 + nb))
        x0, P0 = x0[keep], P0[np.ix_(keep, keep)]
    b0 = x0.size - nb
    d_left, d_right, var_left, var_right = 0.02, 0.025, 1e-8, 2e-8
    x, P = x0.copy(), P0.copy()
    propagate_moments_quantised(x, P, d_left, d_right, ROBOT.wheel_base, var_left, var_right, QUANT_VAR, 0.0, 0.0,
                                phase)
    n = 400_000
    s = rng.multivariate_normal(x0, P0, n)
    e = s[:, 3] if biased else np.zeros(n)
    t, new_blocks = [], []
    m = np.arange(1, HARMONICS + 1)
    for w, d, var in ((0, d_left, var_left), (1, d_right, var_right)):
        c, steps, seg = np.empty(2), np.empty(2), np.empty(2)
        per_step = boundaries(phase, w, c, steps, seg)
        h = [np.column_stack([np.cos(2 * np.pi * m * ci), np.sin(2 * np.pi * m * ci)]).ravel() for ci in c]
        block = s[:, b0 + w * BLOCK:b0 + (w + 1) * BLOCK]
        q_old = block[:, :-1] @ h[1] + block[:, -1]
        if predicted:
            rho = remainder_correlation(c[0] - c[1], per_step * (steps[0] - steps[1]))
            assert 0.01 < abs(rho) < 0.99, rho
            z = block[:, :-1]
        else:
            rho = 0.0
            z = rng.standard_normal((n, BLOCK - 1)) * np.sqrt(prior[:BLOCK - 1])
        r = rho * block[:, -1] + rng.standard_normal(n) * math.sqrt((1 - rho**2) * remainder_share() * QUANT_VAR)
        q_new = z @ h[0] + r
        u = d - q_old + q_new + rng.standard_normal(n) * math.sqrt(var)
        t.append((1 - e) * u if w == 0 else (1 + e) * u)
        new_blocks.append(np.column_stack([z, r]))
    zz = np.column_stack([motion.propagate(s[:, :3], t[0], t[1], ROBOT.wheel_base), *([e] if biased else []),
                          *new_blocks])
    # Sampling error of a variance with 4e5 samples: ~0.2 % (normal) -> 1 % is > 4 sigma.
    np.testing.assert_allclose(np.diag(np.cov(zz.T)), np.diag(P), rtol=0.01)
    sd = np.sqrt(np.diag(P))
    np.testing.assert_allclose(np.cov(zz.T) / np.outer(sd, sd), P / np.outer(sd, sd), atol=0.01)
    np.testing.assert_allclose(zz.mean(axis=0), x, atol=3e-5)
    assert np.array_equal(P, P.T)


def test_localizer_layout_and_known_start_residuals():
    loc = Localizer(ROBOT, SensorSpec(), MARKERS, [1.0, 2.0, 0.0], np.eye(3) * 1e-6, estimate_wheel_bias=True,
                    encoder_residual_state=True, residual0=[1e-5, -2e-5])
    n = 4 + 2 * BLOCK
    assert loc.full_x.shape == (n,) and loc.full_P.shape == (n, n)
    left, right = loc.full_x[4:4 + BLOCK], loc.full_x[4 + BLOCK:]
    # at commanded turn 0 every cosine is 1, every sine 0: the block sums to its residual
    assert left[:-1:2].sum() + left[-1] == pytest.approx(1e-5, abs=1e-18)
    assert right[:-1:2].sum() + right[-1] == pytest.approx(-2e-5, abs=1e-18)
    np.testing.assert_allclose(left, residual_block(1e-5, TICK), rtol=1e-12)
    np.testing.assert_array_equal(loc.full_P[4:, :], 0.0)          # known exactly
    assert loc.x.shape == (3,) and loc.P.shape == (3, 3)
    unknown = Localizer(ROBOT, SensorSpec(), MARKERS, [1.0, 2.0, 0.0], np.eye(3) * 1e-6,
                        encoder_residual_state=True)
    assert unknown.full_x.shape == (3 + 2 * BLOCK,)
    np.testing.assert_array_equal(unknown.full_x[3:], 0.0)
    blocks = unknown.full_P[3:, 3:]
    np.testing.assert_allclose(np.diag(blocks), QUANT_VAR * np.tile(block_prior(), 2), rtol=1e-12)
    np.testing.assert_array_equal(blocks - np.diag(np.diag(blocks)), 0.0)
    with pytest.raises(SimulationError, match="residual0"):
        Localizer(ROBOT, SensorSpec(), MARKERS, [1.0, 2.0, 0.0], np.eye(3) * 1e-6, residual0=[0.0, 0.0])


def _window_count_error_var(turn: float, reads: int, predicted: bool = True) -> float:
    """Return the model's variance of a wheel's count error over ``reads`` reads on the spot [tick^2].

    The filter (no slip) turns on the spot at a steady command of ``turn`` ticks per 4-step read
    from an unknown phase, for 150 reads so the phase history is there; then the pose is made
    known and it predicts ``reads`` more reads (``predicted`` False: spans unknown): the
    heading's variance is ``(var_l + var_r) / b^2`` of the two wheels' count errors over the window.
    """
    loc = Localizer(NO_SLIP, SensorSpec(), MARKERS, [1.0, 2.0, 0.0], np.eye(3) * 1e-8, encoder_residual_state=True,
                    step_time=DT)
    rate = turn / (4 * DT) / (ROBOT.encoder_ticks / (2 * math.pi))   # rad/s
    loc.set_command(-rate, rate)
    for _ in range(150):
        loc.predict(-turn * TICK, turn * TICK, 0.0, 4)
    x, P = loc.state_arrays()
    P[:3, :] = 0.0
    P[:, :3] = 0.0
    for _ in range(reads):
        loc.predict(-turn * TICK, turn * TICK, 0.0, 4 if predicted else None)
    return loc.P[2, 2] * ROBOT.wheel_base**2 / 2 / TICK**2


@pytest.mark.parametrize("turn, reads", [(44.3, 1), (44.94, 8), (44.94, 50), (7.18, 200), (71.0, 40),
                                         (12.5, 300)])
def test_a_windows_count_error_is_that_of_its_fractional_turn_at_any_length(turn, reads):
    # A wheel from a phase uniform over a tick, turning a steady turn per read: the count error
    # over a window telescopes to the residuals' difference at its ends, variance f (1 - f) of
    # the window's fractional turn, however long the window (random-23-000: 44.94 ticks a read,
    # 8 reads turn 7.52, 1/4 where unrelated ends give 1/6; random-23-016: 7.18). Sampled to
    # ~0.001 at 2e5 samples. The model carries the harmonics exactly; the remainder (its share
    # r0 of the variance) is an AR(1) over a read, so the model's window variance may exceed the
    # truth by up to 2 r0 / 12 (0.012): that, plus 5 sampling sigmas, is the tolerance. The
    # negative controls: the turn not predicted (1/6 for any window) and a model that carries the
    # whole residual as an AR(1) over a read (the one before the chain: its correlation
    # 1 - 6 f (1 - f) per read, multiplied over the window).
    rng = np.random.default_rng(reads)
    theta0 = rng.uniform(0, 1, 200_000)
    window = turn * reads
    sampled = np.var(window - (np.floor(theta0 + window) - np.floor(theta0)))
    tol = 2 * remainder_share() / 12 + 0.002
    model = _window_count_error_var(turn, reads)
    assert -0.002 < model - sampled < tol, (model, sampled)
    unpredicted = _window_count_error_var(turn, reads, predicted=False)
    f = turn - math.floor(turn)
    ar1 = 2 * (1 - (1 - 6 * f * (1 - f)) ** reads) / 12
    fw = window - math.floor(window)
    if abs(fw * (1 - fw) - 1 / 6) > tol + 0.002:
        assert abs(unpredicted - sampled) > tol, (unpredicted, sampled)
    if reads > 1 and abs(ar1 - fw * (1 - fw)) > tol + 0.002:
        assert abs(ar1 - sampled) > tol, (ar1, sampled)


def test_a_known_phase_stays_known_over_a_long_drive():
    # Encoders zeroed at a known residual and a steady command: the residual's harmonics are
    # constants in the commanded frame, so after 2,000 reads the filter still knows them exactly
    # (the remainder aside), and its estimate of the residual at the end is the sawtooth's.
    turn, reads = 7.18, 2000
    q0 = 0.3 * TICK
    loc = Localizer(NO_SLIP, SensorSpec(), MARKERS, [1.0, 2.0, 0.0], np.eye(3) * 1e-8, encoder_residual_state=True,
                    residual0=[q0, -q0], step_time=DT)
    rate = turn / (4 * DT) / (ROBOT.encoder_ticks / (2 * math.pi))
    loc.set_command(rate, rate)
    for _ in range(reads):
        loc.predict(turn * TICK, turn * TICK, 0.0, 4)
    block = loc.full_x[3:3 + BLOCK]
    np.testing.assert_array_equal(np.diag(loc.full_P)[3:3 + BLOCK - 1], 0.0)
    c = turn * reads
    m = np.arange(1, HARMONICS + 1)
    h = np.column_stack([np.cos(2 * np.pi * m * c), np.sin(2 * np.pi * m * c)]).ravel()
    a, b = _harmonics(np.array([0.3 + 0.5]), m)
    carried = float((a[0] * np.cos(2 * np.pi * m * c) + b[0] * np.sin(2 * np.pi * m * c)).sum())
    assert block[:-1] @ h / TICK == pytest.approx(carried, abs=1e-9)


def test_a_read_of_span_zero_keeps_the_residual():
    # A second read at the same physics step (the robot stopped at its goal) turned the wheels
    # by 0: the block and its covariance stay as they were, remainder included. Negative
    # control: a read whose span is not known redraws the block from its prior.
    loc = Localizer(NO_SLIP, SensorSpec(), MARKERS, [1.0, 2.0, 0.0], np.eye(3) * 1e-8, encoder_residual_state=True,
                    step_time=DT)
    rate = 7.18 / (4 * DT) / (ROBOT.encoder_ticks / (2 * math.pi))
    loc.set_command(rate, rate)
    for _ in range(200):
        loc.predict(7.18 * TICK, 7.18 * TICK, 0.0, 4)
    x, P = loc.full_x[3:], loc.full_P[3:, 3:]
    loc.predict(0.0, 0.0, 0.0, 0)
    np.testing.assert_allclose(loc.full_x[3:], x, rtol=1e-12, atol=0.0)
    np.testing.assert_allclose(loc.full_P[3:, 3:], P, rtol=1e-9, atol=1e-30)
    loc.predict(0.0, 0.0, 0.0, None)
    np.testing.assert_array_equal(loc.full_x[3:], 0.0)
    np.testing.assert_allclose(np.diag(loc.full_P)[3:], QUANT_VAR * np.tile(block_prior(), 2), rtol=1e-12)
