"""The filter's process noise against the simulated odometry, over many short windows.

The episode's odometry (:class:`sim.physics.odometry.WheelOdometry`: quantised encoders, the
nominal radius, the floor's random slip) reads wheels that roll a known rotation with the actual
radii ``r (1 -/+ e)``. Each window starts the episode's filter
(:func:`sim.episode.driver.episode_localizer`: wheel error and encoder residual states,
:mod:`estimators.motion_quantised`) at the true pose and wheel error with a negligible
covariance and lets it dead-reckon ``WINDOW`` control steps; its pose NEES at the end compares
the covariance the process model predicts with the odometry error it actually makes. Nothing is
measured, so this isolates Q: a filter that is a few per cent pessimistic or optimistic in Q
is a few per cent off in NEES here, where 200 episodes were needed to see it in NIS.

The physics' own slip is left out: along the wheels it is ~2e-5 of the travel (about 1 mm over
40 m, against the declared 1 % random slip); sideways in turns it is not negligible and not
modelled (``estimators/motion.py``).

Statistic and threshold: windows are independent (own start angles, pose, speeds and slip
draws), so under the model the mean of ``N_WINDOWS`` NEES values has mean 3; the acceptance
region is the two-sided chi2(3N)/N interval at false-alarm probability ``ALPHA``. The errors are
sums of uniform (quantisation) and gaussian (slip) terms, whose excess kurtosis is <= 0, so the
NEES varies less than chi2(3) and the interval is conservative: the false-alarm probability is
at most ALPHA. Power: a Q inflated by 5 % gives a mean NEES of 3/1.05 = 2.857, more than four of
its standard deviations (<= 0.019) below the lower bound (2.934).
"""

from __future__ import annotations

import dataclasses
import math

import numba
import numpy as np
import pytest

import scenarios
from estimators import consistency
from estimators.motion import arc_step
from estimators.motion_quantised import residual_block
from estimators.predict import predict_step
from sim.episode.driver import CONTROL_STEPS, episode_localizer
from sim.physics.config import PhysicsConfig
from sim.physics.odometry import (
    NEXT_NORMAL,
    TICKS_LEFT,
    TICKS_PER_REV,
    TICKS_RIGHT,
    WheelOdometry,
    centred_residual,
    odometry_step,
)

# 2048 ticks, 0.2 % wheel error, 1 % slip, declared = actual. The windows roll the kinematic arc
# (no sideways slip), so the filter declares none: this isolates Q from the turn-slip mean term.
_WAREHOUSE = scenarios.load("warehouse")
SCENARIO = dataclasses.replace(_WAREHOUSE, robot=dataclasses.replace(_WAREHOUSE.robot, turn_slip=0.0))
ROBOT, ACTUAL = SCENARIO.robot, SCENARIO.robot_actual
DT = CONTROL_STEPS * PhysicsConfig().time_step   # control step of an episode [s]
WINDOW = 24                         # steps between fixes: 0.4 s
N_WINDOWS = 15000
ALPHA = 0.001
TINY_VAR = 1e-16                    # start covariance: the start is known (P0 must be SPD)

FILTERS = {  # name -> changes to the episode's filter
    "model": {},
    "white-quantisation": {"encoder_residual_state": False},   # the old model
    "q+5%": {"q_scale": 1.05},
}


@numba.njit(cache=True)
def _dead_reckon(odo_state, odo_params, normals, angles0, rates, x0, P0, ekf_params, phase, radii, wheel_base,
                 xs, Ps, truths):
    """Dead-reckon every window with the episode's compiled odometry and predict kernels.

    ``rates`` (N, WINDOW, 2): nominal-radius wheel travel commanded per step [m]; window ``w``
    starts at ``x0[w]`` (pose, e, residuals) with covariance ``P0`` and writes the final state,
    covariance and true pose into ``xs[w]``, ``Ps[w]``, ``truths[w]``.
    """
    for w in range(rates.shape[0]):
        angle_l, angle_r = angles0[w, 0], angles0[w, 1]
        odo_state[TICKS_LEFT] = math.floor(angle_l * odo_params[TICKS_PER_REV] / (2.0 * math.pi))
        odo_state[TICKS_RIGHT] = math.floor(angle_r * odo_params[TICKS_PER_REV] / (2.0 * math.pi))
        x = x0[w].copy()
        P = P0.copy()
        tx, ty, tth = x[0], x[1], x[2]
        for k in range(rates.shape[1]):
            tl, tr = rates[w, k, 0], rates[w, k, 1]
            angle_l += tl / radii[0]          # the rotation that rolls this travel
            angle_r += tr / radii[1]
            tx, ty, tth = arc_step((tx, ty, tth), tl, tr, wheel_base)
            d_left, d_right, _ = odometry_step(odo_state, odo_params, normals, angle_l, angle_r)
            predict_step(x, P, d_left, d_right, ekf_params, phase)
        xs[w] = x
        Ps[w] = P
        truths[w, 0], truths[w, 1], truths[w, 2] = tx, ty, tth


def _window_nees(seed: int, n_windows: int = N_WINDOWS) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(np.random.SeedSequence(seed))
    r, b, e = ACTUAL.wheel_radius, ACTUAL.wheel_base, ACTUAL.wheel_radius_error
    radii = np.array([r * (1.0 - e), r * (1.0 + e)])
    # Episodes drive between 0.05 and 1 m/s, turn up to 1 rad/s and accelerate at 0.5 m/s^2.
    angles0 = rng.uniform(0.0, 2.0 * math.pi, (n_windows, 2))
    poses = np.column_stack([rng.uniform(0.0, 20.0, (n_windows, 2)), rng.uniform(-math.pi, math.pi, n_windows)])
    v0, a = rng.uniform(0.05, 1.0, n_windows), rng.uniform(-0.5, 0.5, n_windows)
    omega0, alpha = rng.uniform(-1.0, 1.0, n_windows), rng.uniform(-2.0, 2.0, n_windows)
    t = (np.arange(WINDOW) + 0.5) * DT
    v = np.maximum(v0[:, None] + a[:, None] * t, 0.02)
    omega = omega0[:, None] + alpha[:, None] * t
    rates = np.ascontiguousarray(np.stack([v - 0.5 * b * omega, v + 0.5 * b * omega], axis=-1) * DT)
    # each wheel's known start residual as the filter holds it
    residual0 = np.array([[centred_residual(float(g), ROBOT) for g in row] for row in angles0])
    slip_normals = rng.standard_normal(2 * n_windows * WINDOW + 2)
    out = {}
    for name, kw in FILTERS.items():
        # The episode's filter gives the predict parameters and the start covariance's layout.
        # the windows' start residuals are known (residual0 below): zero variance in their block
        known = {} if kw.get("encoder_residual_state") is False else {
            "residual0": [centred_residual(float(g), ROBOT) for g in angles0[0]]}
        loc = episode_localizer(SCENARIO, np.r_[poses[0], e], np.diag([TINY_VAR] * 4), **known, **kw)
        quantised = loc.encoder_residual_state
        odo = WheelOdometry(ROBOT, np.zeros(2), np.zeros(3), slip_std=ACTUAL.odometry_noise,
                            rng=np.random.default_rng(0))
        odo.normals = slip_normals      # every filter sees the same slip draws
        odo.state[NEXT_NORMAL] = 0.0
        # each wheel's block: the start residual's harmonics and remainder
        tick = 2.0 * math.pi * ROBOT.wheel_radius / ROBOT.encoder_ticks
        blocks = np.array([np.r_[residual_block(q[0], tick), residual_block(q[1], tick)] for q in residual0])
        x0 = np.column_stack([poses, np.full(n_windows, e)] + ([blocks] if quantised else []))
        xs, Ps = np.empty_like(x0), np.empty((n_windows, *loc.full_P.shape))
        truths = np.empty((n_windows, 3))
        # no read spans: the residuals independent from read to read (the phases go unpredicted)
        _dead_reckon(odo.state, odo.params, odo.normals, angles0, rates, np.ascontiguousarray(x0), loc.full_P,
                     loc.predict_params, loc.phase, radii, b, xs, Ps, truths)
        err = xs[:, :3] - truths
        err[:, 2] = (err[:, 2] + math.pi) % (2.0 * math.pi) - math.pi
        out[name] = consistency.nees(err, Ps[:, :3, :3])
    return out


@pytest.fixture(scope="module")
def window_nees() -> dict[str, np.ndarray]:
    return _window_nees(20240711)


def test_process_noise_matches_the_simulated_odometry(window_nees):
    res = consistency.nees_test(window_nees["model"], 3, ALPHA)
    assert res.passed, f"mean window NEES {res.statistic:.4f} outside {res.interval} (3 = Q matches)"


@pytest.mark.parametrize("name", ["white-quantisation", "q+5%"])
def test_negative_control_pessimistic_q_is_rejected(window_nees, name):
    res = consistency.nees_test(window_nees[name], 3, ALPHA)
    assert res.verdict is consistency.Verdict.BELOW, \
        f"{name}: mean window NEES {res.statistic:.4f} {res.interval}: a pessimistic Q went unnoticed"
