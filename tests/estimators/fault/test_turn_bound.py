"""The odometry's heading-change bound for bearings carried to the fix time.

With the random slip off, :func:`turn_bound` is a hard bound: quantisation (less than a tick
per wheel) and a wheel-radius error within the declared one can never exceed it, so no
exceedance is allowed. Negative control: wheels whose radius error is three times the
declared one do exceed it. With a bounded slip (a bounded-noise world's floor) it is a hard bound
too, on the simulated odometry itself; the same floor with normal slip exceeds it.
"""

from __future__ import annotations

import dataclasses

import numpy as np

import scenarios
from estimators.fault.carried import encoder_tick, turn_bound
from sim.physics.odometry import WheelOdometry


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


def _odometry_shifts(robot, bounded, n, seed):
    """Turn errors and bounds of n shifts read by the simulated odometry.

    Each shift rolls the wheels at constant speeds (a constant-curvature arc, forwards, backwards
    or turning in place), with actual radii ``r (1 +- e)`` at the declared error, read 1-8 times
    at random instants; returns the dead-reckoned turn's error and :func:`turn_bound` with the
    odometry's wheel paths, each shape (n,).
    """
    rng = np.random.default_rng(seed)
    r, b, e = robot.wheel_radius, robot.wheel_base, robot.wheel_radius_error
    errors, bounds = np.zeros(n), np.zeros(n)
    for i in range(n):
        speed = rng.uniform(-1.0, 1.0) * rng.choice([0.0, 1.0])
        yaw = rng.uniform(-1.0, 1.0)
        sign = rng.choice([-1.0, 1.0])
        rates = np.array([(speed - 0.5 * b * yaw) / (r * (1 - sign * e)),
                          (speed + 0.5 * b * yaw) / (r * (1 + sign * e))])
        a0 = rng.uniform(0.0, 2.0 * np.pi, 2)
        odo = WheelOdometry(robot, a0, np.zeros(3), slip_std=robot.odometry_noise,
                            rng=np.random.default_rng(rng.integers(2**63)), bounded=bounded)
        times = np.sort(rng.uniform(0.0, 0.06, rng.integers(1, 9)))
        times[-1] = 0.06
        paths0 = odo.wheel_paths
        for t in times:
            odo.update(a0 + rates * t)
        x, y, turned = odo.pose
        paths = np.subtract(odo.wheel_paths, paths0)
        true = 0.06 * ((1 + sign * e) * r * rates[1] - (1 - sign * e) * r * rates[0]) / b
        errors[i] = turned - true
        bounds[i] = turn_bound(robot, [np.hypot(x, y)], [turned], wheel_paths=[paths], bounded=True)[0]
    return errors, bounds


def test_turn_bound_holds_for_a_bounded_slip():
    # slip well above the quantisation's share (it is what the bound's slip part must hold)
    robot = dataclasses.replace(scenarios.load("warehouse").robot, odometry_noise=0.03, encoder_ticks=20000)
    errors, bounds = _odometry_shifts(robot, True, 4000, 2337)
    assert np.all(np.abs(errors) <= bounds)
    assert np.max(np.abs(errors) / bounds) > 0.5   # the bound is not loose beyond use
    # negative control: the same floor with normal slip of the same std breaks it (9 of the 4000)
    errors, bounds = _odometry_shifts(robot, False, 4000, 2337)
    assert np.sum(np.abs(errors) > bounds) > 0
