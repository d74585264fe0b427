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


def test_the_phase_predictor_times_the_command_and_bounds_it_by_the_history():
    state = new_state(ROBOT.encoder_ticks, ROBOT.wheel_radius, 1 / 240)
    rate = 3.0                                                   # rad/s, both wheels
    per_step = rate / 240 * ROBOT.encoder_ticks / (2 * math.pi)  # ticks
    state[encoder_phase.CMD_LEFT] = state[encoder_phase.CMD_RIGHT] = rate
    out = []
    for k in range(300):                                         # 300 reads of 4 steps: 1200 steps
        state[encoder_phase.STEPS] = 4
        counted = math.floor((k + 1) * 4 * per_step) - math.floor(k * 4 * per_step)
        out.append(phase_advance(state, counted * TICK, counted * TICK))
    turn_l, turn_r, sig_l, sig_r = out[-1]
    assert turn_l == pytest.approx(4 * per_step) and turn_r == pytest.approx(4 * per_step)
    # a WINDOW of history (to a checkpoint), the counted turn within a tick of the commanded one,
    # no slip: sqrt(D^2 + 1/4) / span per step with |D| < 1
    window, checkpoint = encoder_phase.WINDOW, encoder_phase.CHECKPOINT
    assert 4 * 0.5 / (window + checkpoint) <= sig_l <= 4 * math.sqrt(1.25) / window
    assert math.isinf(out[25][2])                                # 104 steps of history: unknown
    # no span: no prediction; the history is left alone, and the read starts a new segment of
    # boundaries (the residuals before it are not related to the ones after by a known turn)
    before = state.copy()
    assert math.isinf(phase_advance(state, 0.01, 0.01)[2])
    np.testing.assert_array_equal(state[encoder_phase.HEAD0:encoder_phase.RECENT0],
                                  before[encoder_phase.HEAD0:encoder_phase.RECENT0])
    np.testing.assert_array_equal(state[:encoder_phase.PER_L], before[:encoder_phase.PER_L])
    assert state[encoder_phase.SEGMENT] == before[encoder_phase.SEGMENT] + 1


def test_the_boundaries_are_the_last_reads_newest_first():
    state = new_state(ROBOT.encoder_ticks, ROBOT.wheel_radius, 1 / 240)
    state[encoder_phase.CMD_LEFT], state[encoder_phase.CMD_RIGHT] = 2.0, -1.0
    k_rad = ROBOT.encoder_ticks / (2 * math.pi) / 240              # ticks per (rad/s) per step
    spans = [4, 1, 3, 4, 2, 4, 4, 4, 4, 3, 1]
    for m in spans:
        state[encoder_phase.STEPS] = m
        phase_advance(state, 0.0, 0.0)
    n = encoder_phase.BOUNDARIES
    turns, steps, segments = np.empty(n), np.empty(n), np.empty(n)
    per = encoder_phase.boundaries(state, 1, turns, steps, segments)
    assert math.isinf(per)                                          # 30 steps of history: unknown
    ends = np.cumsum(spans)[::-1][:n]
    np.testing.assert_array_equal(steps, ends)
    np.testing.assert_allclose(turns, -1.0 * k_rad * ends, rtol=1e-12)
    # every read's span was known: its turn is predicted, whatever the history says of sigma
    # (the drive holds the wheels to the command's integral, sim.physics.robot)
    assert len(set(segments)) == 1
    state[encoder_phase.STEPS] = 0                                  # a read at the same step
    phase_advance(state, 0.0, 0.0)
    encoder_phase.boundaries(state, 1, turns, steps, segments)
    assert segments[0] == segments[1] and steps[0] == steps[1] and turns[0] == turns[1]
    assert state[encoder_phase.STEPS] == encoder_phase.UNKNOWN_SPAN   # until the next read's is set
    phase_advance(state, 0.0, 0.0)                                  # a read without a span
    encoder_phase.boundaries(state, 1, turns, steps, segments)
    assert segments[0] == segments[1] + 1
