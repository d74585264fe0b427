"""The compiled control step does exactly what the separate objects' Python methods do."""

from __future__ import annotations

import math

import numpy as np
import pytest

import scenarios
from estimators.ekf import Localizer
from sim.episode.control_tick import LOG_COLUMNS, LOG_COV, LOG_EST, LOG_S, LOG_T, LOG_TRUE, ControlTick
from sim.episode.follower import PurePursuit
from sim.physics.odometry import WheelOdometry


def _parts(sc, path, kw):
    pose0 = np.array([0.0, 0.0, 0.0])
    loc = Localizer(sc.robot, sc.sensor, sc.marker_positions(), pose0, np.diag([1e-6, 1e-6, 1e-6]),
                    estimate_wheel_bias=True, **kw)
    odo = WheelOdometry(sc.robot, np.zeros(2), pose0, slip_std=0.01, rng=np.random.default_rng(3))
    fol = PurePursuit(path=path, speed=np.full(len(path), 0.8), max_speed=1.0, max_yaw_rate=1.0)
    return loc, odo, fol


@pytest.mark.parametrize("kw", [{}, {"encoder_residual_state": True, "residual0": [1e-5, -2e-5]}],
                         ids=["bias", "bias+encoder-residuals (the episode's)"])
def test_compiled_step_matches_the_objects_methods(kw):
    sc = scenarios.load("paper-two-markers")
    path = np.column_stack([np.linspace(0.0, 4.0, 81), 0.3 * np.sin(np.linspace(0.0, 3.0, 81))])
    loc_a, odo_a, fol_a = _parts(sc, path, kw)
    loc_b, odo_b, fol_b = _parts(sc, path, kw)
    n = 700  # > 512 steps: the slip normals' block is refilled on the way
    log = np.empty((n, LOG_COLUMNS))
    tick = ControlTick(odo_b, loc_b, fol_b, log, 1 / 60)
    rng = np.random.default_rng(11)
    tick_per_rad = sc.robot.encoder_ticks / (2 * math.pi)
    angles = np.zeros(2)
    s_prev = 0.0
    for i in range(n):
        angles = angles + rng.uniform(5, 12, 2) / tick_per_rad   # a few ticks per wheel and step
        true_pose = rng.normal(size=3)
        steer = i % 7 != 3                  # some steps hold the robot
        # the objects' methods, one after another
        d_left, d_right = odo_a.update(angles)
        loc_a.predict(d_left, d_right)
        if steer:
            cmd = fol_a.command(loc_a.x, 1 / 60)
            expected = (cmd.v, cmd.omega, cmd.done, cmd.s)
        else:
            expected = (0.0, 0.0, False, s_prev)
        got = tick((float(angles[0]), float(angles[1])), tuple(true_pose.tolist()), 0.5 * i, i, s_prev, steer)
        assert got == expected
        row = log[i]
        assert row[LOG_T] == 0.5 * i
        np.testing.assert_array_equal(row[LOG_TRUE], true_pose)
        np.testing.assert_array_equal(row[LOG_EST], loc_a.x)          # after this step's predict
        np.testing.assert_array_equal(row[LOG_COV].reshape(3, 3), loc_a.P)
        assert row[LOG_S] == expected[3]
        s_prev = expected[3]
    np.testing.assert_array_equal(odo_a.pose, odo_b.pose)
    np.testing.assert_array_equal(loc_a.full_P, loc_b.full_P)
    np.testing.assert_array_equal(fol_a.state, fol_b.state)


def test_the_log_holds_the_estimate_after_the_predict():
    # Negative control of the comparison above: the estimate before the step's predict differs
    # from the logged one, so a log written too early would be caught.
    sc = scenarios.load("paper-two-markers")
    path = np.column_stack([np.linspace(0.0, 4.0, 81), np.zeros(81)])
    loc, odo, fol = _parts(sc, path, {})
    log = np.empty((1, LOG_COLUMNS))
    before = loc.x
    ControlTick(odo, loc, fol, log, 1 / 60)((0.5, 0.6), (0.0, 0.0, 0.0), 0.0, 0, 0.0, True)
    assert not np.array_equal(log[0, LOG_EST], before)
    np.testing.assert_array_equal(log[0, LOG_EST], loc.x)
