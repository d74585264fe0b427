"""The encoder phase: the commanded turn's prediction, and the count errors it makes coherent."""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimators import encoder_phase
from estimators.encoder_phase import count_error_var, new_state, phase_advance
from estimators.fault.carried import count_cov
from scenarios.schema import RobotSpec

ROBOT = RobotSpec()
TICK = 2 * math.pi * ROBOT.wheel_radius / ROBOT.encoder_ticks


@pytest.mark.parametrize("f, sigma", [(0.05, 0.0), (0.5, 0.0), (0.3, 0.02), (0.05, 0.1), (0.5, 0.1), (0.7, 1.0)])
def test_count_error_variance_is_that_of_sampled_windows(f, sigma):
    # A phase uniform over a tick, a window turning 7 + f ticks give or take sigma: the count
    # error's variance. 2e6 samples: its standard error is below 3e-4 (f (1 - f) <= 1/4, the
    # error's fourth moment <= 1/16), so 1.5e-3 is > 5 of them.
    rng = np.random.default_rng(int(100 * f + 1000 * sigma))
    theta = rng.uniform(0, 1, 2_000_000)
    turn = 7 + f + sigma * rng.standard_normal(theta.size)
    error = turn - (np.floor(theta + turn) - np.floor(theta))
    assert float(count_error_var(7 + f, sigma)) == pytest.approx(error.var(), abs=1.5e-3)
    if sigma < 0.05 and abs(f * (1 - f) - 1 / 6) > 0.05:
        # negative control: independent residuals (1/6) are far off where the turn is known
        assert abs(1 / 6 - error.var()) > 1.5e-3


def test_count_error_variance_limits():
    np.testing.assert_allclose(count_error_var([0.0, 0.25, 0.5, 3.75], 0.0), [0, 0.1875, 0.25, 0.1875])
    np.testing.assert_allclose(count_error_var([0.1, 0.6], math.inf), 1 / 6)
    np.testing.assert_allclose(count_error_var([0.1, 0.6], 2.0), 1 / 6, atol=1e-3)


def test_shift_count_covariance_matches_a_simulated_fix():
    # Three reads of a fix at steps 0, 3 and 7 (the end), a wheel turning 2.37 ticks per step:
    # the count errors of the shifts (0 -> end, 3 -> end) over random start phases, per wheel
    # (the right wheel turning backwards at 1.9 ticks per step). 1e6 samples: covariances to
    # ~3e-4 tick^2 (4 standard errors: 1.2e-3).
    rng = np.random.default_rng(11)
    steps = np.array([0.0, 3.0, 7.0])
    rates = np.array([2.37, -1.9])
    turns = steps[:, None] * rates[None, :]                    # commanded = true turn here
    theta = rng.uniform(0, 1, (1_000_000, 2))
    pos = theta[:, None, :] + turns[None, :, :]                 # (n, reads, wheel) [ticks]
    counts = np.floor(pos)
    shift_err = (turns[-1] - turns[:-1])[None] - (counts[:, -1:, :] - counts[:, :-1, :])   # (n, 2 shifts, wheel)
    got = count_cov(ROBOT, turns, steps, [0.0, 0.0]) / TICK**2
    for w in range(2):
        want = np.cov(shift_err[:, :, w].T)
        np.testing.assert_allclose(got[:, :, w], want, atol=1.2e-3)
    # negative control: independent residuals (1/6 on the diagonal, 1/12 off it)
    independent = np.array([[1 / 6, 1 / 12], [1 / 12, 1 / 6]])
    assert np.abs(independent - np.cov(shift_err[:, :, 0].T)).max() > 1.2e-3


def test_window_covariance_adds_the_turns_random_walk():
    # The same fix, each wheel's true turn wandering from the predicted one as a random walk of
    # 0.02 tick^2 per step (loose_var, the running sum the filter keeps): sampled covariances
    # to 1.2e-3 as above. Negative control: the wander left out.
    rng = np.random.default_rng(12)
    steps = np.array([0.0, 3.0, 7.0])
    rates = np.array([2.37, -1.9])
    turns = steps[:, None] * rates[None, :]
    n = 1_000_000
    step_std = np.sqrt(0.02 * np.diff(steps, prepend=0.0))[None, :, None]
    walk = np.cumsum(step_std * rng.standard_normal((n, 3, 2)), axis=1)
    pos = rng.uniform(0, 1, (n, 1, 2)) + turns[None] + walk
    counts = np.floor(pos)
    # the count error: the true turn (with its wander) less the counted one
    shift_err = (pos[:, -1:, :] - pos[:, :-1, :]) - (counts[:, -1:, :] - counts[:, :-1, :])
    loose = 0.02 * np.repeat(steps[:, None], 2, axis=1)
    got = count_cov(ROBOT, turns, steps, [0.0, 0.0], loose) / TICK**2
    without = count_cov(ROBOT, turns, steps, [0.0, 0.0]) / TICK**2
    for w in range(2):
        want = np.cov(shift_err[:, :, w].T)
        np.testing.assert_allclose(got[:, :, w], want, atol=1.2e-3)
        assert np.abs(without[:, :, w] - want).max() > 1.2e-3


def _steady_reads(state, per_step: float, offset: float, reads: int) -> list:
    """Advance ``state`` over ``reads`` reads of 4 steps of a wheel turning ``per_step - offset`` ticks per step."""
    out = []
    for k in range(reads):
        state[encoder_phase.STEPS] = 4
        true = (per_step - offset) * 4
        counted = math.floor((k + 1) * true) - math.floor(k * true)
        out.append(phase_advance(state, counted * TICK, counted * TICK))
    return out


def test_the_phase_predictor_learns_the_motors_steady_offset_from_the_history():
    # Both wheels commanded at 3 rad/s turn 1.6e-3 tick per step short of it (the velocity
    # loop's offset under load, random-23-029). After a WINDOW of history (to a checkpoint) the
    # counted minus the commanded turn is the offset's within a tick (the residuals at its
    # ends), so the read's predicted turn is the true one to 4 / WINDOW; its std, no slip and no
    # command change since, is 4 sqrt(1/4) / span.
    window, checkpoint = encoder_phase.WINDOW, encoder_phase.CHECKPOINT
    rate, offset = 3.0, 1.6e-3
    per_step = rate / 240 * ROBOT.encoder_ticks / (2 * math.pi)   # ticks
    state = new_state(ROBOT.encoder_ticks, ROBOT.wheel_radius, 1 / 240)
    state[encoder_phase.CMD_LEFT] = state[encoder_phase.CMD_RIGHT] = rate
    out = _steady_reads(state, per_step, offset, 300)                # 1200 steps
    turn_l, turn_r, sig_l, sig_r = out[-1]
    true = 4 * (per_step - offset)
    assert abs(turn_l - true) <= 4 / window and abs(turn_r - true) <= 4 / window
    assert abs(4 * per_step - true) > 4 / window                     # negative control: the command alone
    assert 4 * 0.5 / (window + checkpoint) <= sig_l <= 4 * 0.5 / window
    assert math.isinf(out[25][2])                                    # 104 steps of history: unknown
    # no span: no prediction, and the history is left alone
    before = state.copy()
    assert math.isinf(phase_advance(state, 0.01, 0.01)[2])
    np.testing.assert_array_equal(state, before)


def test_an_offset_the_slip_swamps_is_not_taken():
    # The same wheels, but readings that slip 5 % per read: over the history the slip's
    # std (sqrt(slip^2 sum d^2), ~12 ticks) dwarfs the offset's 1.5 ticks, so D / span would be
    # mostly slip, persistent from read to read. The predictor keeps the commanded turn and
    # counts |D| in the spread: sqrt(D^2 + noise) / span per step.
    window = encoder_phase.WINDOW
    rate, offset = 3.0, 1.6e-3
    per_step = rate / 240 * ROBOT.encoder_ticks / (2 * math.pi)
    state = new_state(ROBOT.encoder_ticks, ROBOT.wheel_radius, 1 / 240, slip_std=0.05)
    state[encoder_phase.CMD_LEFT] = state[encoder_phase.CMD_RIGHT] = rate
    turn_l, _, sig_l, _ = _steady_reads(state, per_step, offset, 300)[-1]
    assert turn_l == pytest.approx(4 * per_step)
    assert sig_l > 4 * 10.0 / (window + encoder_phase.CHECKPOINT)   # the slip's ~12 ticks, at least 10
    # negative control: without the slip the offset is taken (the test above)
    clean = new_state(ROBOT.encoder_ticks, ROBOT.wheel_radius, 1 / 240)
    clean[encoder_phase.CMD_LEFT] = clean[encoder_phase.CMD_RIGHT] = rate
    assert abs(_steady_reads(clean, per_step, offset, 300)[-1][0] - 4 * per_step) > 4 / window


def test_a_command_change_and_the_rate_wander_widen_the_reads_sigma():
    # A read right after the command steps from 3 to 3.5 rad/s: the loop keeps between none and
    # all of one step of the change, mean square a third of it; the wander adds
    # rate_diffusion * (commanded turn per step)^2 per step. Both add to the running sums the
    # snapshot's windows read.
    a = ROBOT.encoder_ticks / (2 * math.pi) / 240                   # ticks per step per rad/s
    kappa = 1e-6
    state = new_state(ROBOT.encoder_ticks, ROBOT.wheel_radius, 1 / 240, rate_diffusion=kappa)
    state[encoder_phase.CMD_LEFT] = state[encoder_phase.CMD_RIGHT] = 3.0
    _steady_reads(state, 3.0 * a, 0.0, 300)
    per = encoder_phase.tracking(state)[2]
    loose0 = state[encoder_phase.LOOSE_L]
    state[encoder_phase.CMD_LEFT] = 3.5
    state[encoder_phase.STEPS] = 4
    _, _, sig_l, sig_r = phase_advance(state, 0.0, 0.0)
    want_l = (4 * per) ** 2 + (0.5 * a) ** 2 / 3 + kappa * (3.5 * a) ** 2 * 4
    want_r = (4 * per) ** 2 + kappa * (3.0 * a) ** 2 * 4
    assert sig_l**2 == pytest.approx(want_l) and sig_r**2 == pytest.approx(want_r)
    assert state[encoder_phase.LOOSE_L] - loose0 == pytest.approx(want_l - (4 * per) ** 2)
