"""The physics' turn slip per odometry read depends on the physics steps the read spans.

On a steady arc of the warehouse robot (open floor), reads spanning m = 1..4 physics steps are
taken in turn; each read's chord lag is the angle between the arc's mid-heading (the kinematic
turn of the wheels' joint angles, actual radii) and the true chord, over the read's turn.
:func:`sim.physics.turn_lag.read_turn_slip` claims lag(m) - lag(4) = 0.5 (1/m - 1/4): the
integrator's part; the solver's part is the same for every span and cancels in the difference.
Tolerance 0.01: the solver's part measured 0.119-0.134 - 0.125 over four arcs of both built-in
robots (``estimators.motion``), a spread of 0.015, and it is common to the spans here.
Negative control: the declared constant (the model before, lag(m) = lag(4)) misses by 0.04-0.375.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

import scenarios
from sim.physics.turn_lag import read_turn_slip
from sim.physics.world import PhysicsWorld
from tests.conftest import flat_text

PATTERN = (1, 3, 2, 2, 4)     # physics steps per read: a fix splits control periods like this
TOL = 0.01


def _lags() -> dict[int, float]:
    actual = scenarios.load("warehouse").robot_actual
    sc = dataclasses.replace(scenarios.loads(flat_text(30.0)), robot_actual=actual)
    v, omega = 0.8, 0.6
    with PhysicsWorld(sc, pose=(15.0, 8.0, 0.0)) as w:
        g = w.robot.geometry
        b = actual.wheel_base
        w.robot.set_wheel_speeds((v - 0.5 * b * omega) / g.left_radius, (v + 0.5 * b * omega) / g.right_radius)
        w.step(480)                                   # 2 s: the arc is steady
        lags: dict[int, list[float]] = {m: [] for m in set(PATTERN)}
        pose, angles = w.true_pose(), w.robot.wheel_angles()
        for _ in range(60):
            for m in PATTERN:
                w.step(m)
                pose2, angles2 = w.true_pose(), w.robot.wheel_angles()
                dl, dr = (angles2 - angles) * (g.left_radius, g.right_radius)
                dth = (dr - dl) / b
                chord = math.atan2(pose2[1] - pose[1], pose2[0] - pose[0])
                mid = pose[2] + 0.5 * dth
                lags[m].append(((mid - chord + math.pi) % (2 * math.pi) - math.pi) / dth)
                pose, angles = pose2, angles2
    return {m: float(np.mean(x)) for m, x in lags.items()}


def test_a_reads_turn_lag_follows_the_physics_steps_it_spans():
    lag = _lags()
    assert abs(lag[4] - 0.13) < 0.015          # the declared constant, on the control period's reads
    for m in (1, 2, 3):
        claimed = read_turn_slip(0.13, m, 4) - 0.13
        assert abs((lag[m] - lag[4]) - claimed) < TOL, (m, lag)
        # negative control: the constant model (no dependence on the span)
        assert abs(lag[m] - lag[4]) > TOL
