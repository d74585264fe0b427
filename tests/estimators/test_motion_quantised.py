"""The predict step with encoder residual states: moments against sampling, layout, bounded standstill."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from estimators import motion
from estimators.ekf import Localizer
from estimators.encoder_phase import sigma_per_step
from estimators.motion_quantised import HARMONICS, PER_WHEEL, WHITE_SHARE, harmonic_share, propagate_moments_quantised
from scenarios.errors import SimulationError
from scenarios.schema import RobotSpec, SensorSpec

ROBOT = RobotSpec()
TICK = 2 * math.pi * ROBOT.wheel_radius / ROBOT.encoder_ticks
QUANT_VAR = TICK**2 / 12
MARKERS = np.array([[0.0, 0.0], [10.0, 0.0]])
NO_SLIP = dataclasses.replace(ROBOT, odometry_noise=0.0)


@pytest.mark.parametrize("turn, sigma", [(3.3, 0.05), (7.75, math.inf)])
def test_moments_match_sampling_the_model(turn, sigma):
    # The model written out sample by sample: old state from its prior; each wheel's phasors
    # turned by 2 pi m turn and shrunk by rho_m, plus a fresh part; the white rest renewed; slip
    # gaussian. The wheels roll (1 -/+ e)(d - q_old + q_new + slip), q = sum_m p_s,m + w.
    M = HARMONICS
    block = [harmonic_share(m) * QUANT_VAR for m in range(1, M + 1) for _ in range(2)] + [WHITE_SHARE * QUANT_VAR]
    rng = np.random.default_rng(5)
    x0 = np.r_[1.0, 2.0, 0.3, 0.002, rng.normal(0, 1e-5, 2 * PER_WHEEL)]
    P0 = np.diag([1e-6, 2e-6, 1e-6, 4e-6] + block + block)
    P0[0, 5] = P0[5, 0] = 0.3 * math.sqrt(1e-6 * P0[5, 5])
    P0[2, 4 + 2 * PER_WHEEL - 1] = P0[4 + 2 * PER_WHEEL - 1, 2] = -0.2 * math.sqrt(1e-6 * P0[-1, -1])
    d_left, d_right, var_left, var_right = 0.02, 0.025, 1e-8, 2e-8
    x, P = x0.copy(), P0.copy()
    propagate_moments_quantised(x, P, d_left, d_right, ROBOT.wheel_base, var_left, var_right, QUANT_VAR, 0.0, 0.0,
                                turn, turn, sigma, sigma)
    n = 400_000
    s = rng.multivariate_normal(x0, P0, n)
    cols, t = [], []
    for w, d, var in ((0, d_left, var_left), (1, d_right, var_right)):
        b = 4 + PER_WHEEL * w
        q_old, q_new = s[:, b + 2 * M].copy(), 0.0
        for m in range(1, M + 1):
            rho = math.exp(-2 * (math.pi * m * sigma) ** 2) if sigma < math.inf else 0.0
            c, sn = math.cos(2 * math.pi * m * turn), math.sin(2 * math.pi * m * turn)
            o = b + 2 * (m - 1)
            fresh = math.sqrt((1 - rho**2) * harmonic_share(m) * QUANT_VAR)
            pc = rho * (c * s[:, o] - sn * s[:, o + 1]) + rng.standard_normal(n) * fresh
            ps = rho * (sn * s[:, o] + c * s[:, o + 1]) + rng.standard_normal(n) * fresh
            q_old += s[:, o + 1]
            q_new = q_new + ps
            cols += [pc, ps]
        wn = rng.standard_normal(n) * math.sqrt(WHITE_SHARE * QUANT_VAR)
        cols.append(wn)
        u = d - q_old + q_new + wn + rng.standard_normal(n) * math.sqrt(var)
        t.append((1 - s[:, 3]) * u if w == 0 else (1 + s[:, 3]) * u)
    z = np.column_stack([motion.propagate(s[:, :3], t[0], t[1], ROBOT.wheel_base), s[:, 3], *cols])
    # Sampling error of a variance with 4e5 samples: ~0.2 % (normal) -> 1 % is > 4 sigma.
    np.testing.assert_allclose(np.diag(np.cov(z.T)), np.diag(P), rtol=0.01)
    corr = np.cov(z.T) / np.sqrt(np.outer(np.diag(P), np.diag(P)))
    np.testing.assert_allclose(corr, P / np.sqrt(np.outer(np.diag(P), np.diag(P))), atol=0.01)
    np.testing.assert_allclose(z.mean(axis=0), x, atol=3e-5)
    assert np.array_equal(P, P.T)


def test_localizer_layout_and_known_start_residuals():
    loc = Localizer(ROBOT, SensorSpec(), MARKERS, [1.0, 2.0, 0.0], np.eye(3) * 1e-6, estimate_wheel_bias=True,
                    encoder_residual_state=True, residual0=[1e-5, -2e-5])
    assert loc.full_x.shape == (4 + 2 * PER_WHEEL,) and loc.full_P.shape == (4 + 2 * PER_WHEEL,) * 2
    for w, q in enumerate([1e-5, -2e-5]):
        block = loc.full_x[4 + PER_WHEEL * w:4 + PER_WHEEL * (w + 1)]
        assert block[1:-1:2].sum() + block[-1] == pytest.approx(q, abs=1e-20)      # the residual
        phase = q / TICK + 0.5                                            # the wheel's phase
        for m in range(1, HARMONICS + 1):
            pc, ps = block[2 * m - 2], block[2 * m - 1]
            assert math.hypot(pc, ps) == pytest.approx(TICK / (math.pi * m), rel=1e-12)
            assert math.atan2(-ps, -pc) == pytest.approx(math.remainder(2 * math.pi * m * phase, 2 * math.pi),
                                                         abs=1e-9)
    np.testing.assert_array_equal(loc.full_P[4:, :], 0.0)          # known exactly
    assert loc.x.shape == (3,) and loc.P.shape == (3, 3)
    unknown = Localizer(ROBOT, SensorSpec(), MARKERS, [1.0, 2.0, 0.0], np.eye(3) * 1e-6,
                        encoder_residual_state=True)
    assert unknown.full_x.shape == (3 + 2 * PER_WHEEL,)
    var = np.diag(unknown.full_P)[3:3 + PER_WHEEL]
    np.testing.assert_allclose(var[1:-1:2].sum() + var[-1], QUANT_VAR, rtol=1e-12)   # a residual's: tick^2 / 12
    np.testing.assert_allclose(var[0:-1:2], var[1:-1:2], rtol=1e-12)
    with pytest.raises(SimulationError, match="residual0"):
        Localizer(ROBOT, SensorSpec(), MARKERS, [1.0, 2.0, 0.0], np.eye(3) * 1e-6, residual0=[0.0, 0.0])


def _window_variance(f: float, sigma_inf: bool) -> tuple[float, float]:
    """Return the model's variance of a wheel's count error over a read that turns it 44 + f ticks [tick^2].

    The filter (no slip) first dead-reckons 150 such reads of 4 steps, turning on the spot, so the
    phase predictor has its history and the residual states their stationary spread; then the
    pose is made known (its rows and columns zeroed) and it predicts one more read: the
    heading's variance is then ``(var_l + var_r) / b^2`` of the two wheels' count errors. Also
    returns the phase predictor's sigma for that read [ticks].
    """
    dt = 1 / 240
    loc = Localizer(NO_SLIP, SensorSpec(), MARKERS, [1.0, 2.0, 0.0], np.eye(3) * 1e-8, encoder_residual_state=True,
                    step_time=dt)
    per_read = 44.0 + f                                # ticks per 4-step read, both wheels
    rate = per_read / (4 * dt) / (ROBOT.encoder_ticks / (2 * math.pi))   # rad/s
    loc.set_command(-rate, rate)                       # on the spot: the pose's x, y stay put
    for _ in range(150):
        loc.predict(-per_read * TICK, per_read * TICK, 0.0, 4)
    x, P = loc.state_arrays()
    P[:3, :] = 0.0
    P[:, :3] = 0.0
    sigma = 4 * sigma_per_step(loc.phase)[0]
    loc.predict(-per_read * TICK, per_read * TICK, 0.0, None if sigma_inf else 4)
    return loc.P[2, 2] * ROBOT.wheel_base**2 / 2 / TICK**2, sigma


@pytest.mark.parametrize("f", [0.05, 0.25, 0.5, 0.8])
def test_a_windows_count_error_variance_is_that_of_its_fractional_turn(f):
    # The simulated encoder at a steady rate, from a phase uniform over a tick: over a window that
    # turns the wheel n + f ticks the count error is f or f - 1 (variance f (1 - f)), the same in
    # every run. The model's harmonics follow it to within twice the white share of tick^2 / 12
    # (the harmonics beyond HARMONICS are white); its phase predictor's uncertainty sigma costs
    # at most sum_m 2 (1 - rho_m) / (2 pi^2 m^2) more. Independent residuals (no span: the model
    # before the phase) are off by up to 0.167: the negative control.
    rng = np.random.default_rng(int(f * 100))
    n_windows = 200_000
    theta0 = rng.uniform(0, 1, n_windows)
    turn = 44.0 + f
    count = np.floor(theta0 + turn) - np.floor(theta0)
    empirical = np.var(turn - count)
    model, sigma = _window_variance(f, sigma_inf=False)
    decoherence = sum(2 * (1 - math.exp(-2 * (math.pi * m * sigma) ** 2)) / (2 * math.pi**2 * m**2)
                      for m in range(1, HARMONICS + 1))
    # f (1 - f) to ~0.5 % at 2e5 samples: the bound leaves 0.002 for it
    bound = 2 * WHITE_SHARE / 12 + decoherence + 0.002
    assert abs(model - empirical) <= bound
    if f in (0.05, 0.5):
        assert abs(_window_variance(f, sigma_inf=True)[0] - empirical) > bound
