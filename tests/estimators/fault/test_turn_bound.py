"""The odometry's heading-change bound for bearings carried to the fix time.

With the random slip off, :func:`turn_bound` is a hard bound: quantisation (less than a tick
per wheel) and a wheel-radius error within the declared one can never exceed it, so no
exceedance is allowed. Negative control: wheels whose radius error is three times the
declared one do exceed it.
"""

from __future__ import annotations

import dataclasses

import numpy as np

import scenarios
from estimators.fault.carried import encoder_tick, turn_bound


def _worst_errors(robot, rng, n, e_scale):
    """Chords, reported turns, and heading-change errors of n constant-curvature shifts."""
    tick, b = encoder_tick(robot), robot.wheel_base
    path = rng.uniform(0.0, 0.5, n)
    turned = rng.uniform(-1.0, 1.0, n) * rng.choice([0.0, 0.05, 1.0], n)
    d_r, d_l = path + 0.5 * b * turned, path - 0.5 * b * turned      # reported wheel travels
    e = e_scale * robot.wheel_radius_error * rng.choice([-1.0, 1.0], n)
    q_r, q_l = rng.uniform(-tick, tick, (2, n))                      # quantisation, < 1 tick
    # reported = nominal-radius travel + q; true = (1 +- e) nominal-radius travel
    nominal_r, nominal_l = d_r - q_r, d_l - q_l
    err = ((d_r - (1.0 + e) * nominal_r) - (d_l - (1.0 - e) * nominal_l)) / b
    h = 0.5 * np.abs(turned)
    chord = path * np.where(h > 0.0, np.sin(h) / np.where(h > 0.0, h, 1.0), 1.0)
    return chord, turned, err


def test_turn_bound_holds_without_slip():
    robot = dataclasses.replace(scenarios.load("warehouse").robot, odometry_noise=0.0)
    rng = np.random.default_rng(2330)
    chord, turned, err = _worst_errors(robot, rng, 20000, 1.0)
    bound = turn_bound(robot, chord, turned)
    assert np.all(np.abs(err) <= bound * (1.0 + 1e-9))
    # negative control: a wheel-radius error three times the declared one breaks it
    chord, turned, err = _worst_errors(robot, rng, 20000, 3.0)
    assert np.sum(np.abs(err) > turn_bound(robot, chord, turned)) > 100


def test_turn_bound_grows_with_travel_turn_and_slip():
    robot = scenarios.load("warehouse").robot
    base = turn_bound(robot, [0.0], [0.0])[0]
    assert base > 0.0
    assert turn_bound(robot, [0.2], [0.0])[0] > base
    assert turn_bound(robot, [0.2], [0.5])[0] > turn_bound(robot, [0.2], [0.0])[0]
    # more odometry reads over the same shift: the slip's sum is less spread
    assert turn_bound(robot, [0.2], [0.0], reads=[12])[0] < turn_bound(robot, [0.2], [0.0], reads=[1])[0]
