"""The blocking prediction from a declared timing spread's draws, on a two-robot fleet built by hand.

Robot A drives along y = 0 from x = -10 m to x = 10 m at 1 m/s and measures one fix at x = 0 to
a reflector straight north of it; robot B stands on its dock on that ray, 3 m north of A's path,
and leaves east ``U J`` seconds after the start (U uniform). With the follower's ramp from rest at
a = 0.5 m/s^2 A reaches x = 0 at 10 + v / (2 a) = 11 s, and B's body leaves the ray when its centre
is its radius r = 0.4 m east of it, sqrt(2 r / a) = 1.265 s after it leaves: the ray is hidden with
probability P(U J + 1.265 > 11) = 1 - 9.735 / J.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from planner.fleet.sampled import DOCK_BOUND, predict_sampled

RADIUS = 0.4
ACCEL = 0.5


def _robot(name, path, start_time, jitter, fixes=(), spread=0.0):
    path = np.asarray(path, float)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(path, axis=0).T))])
    speed = np.ones(len(path))
    speed[-1] = 0.0
    plan = SimpleNamespace(schedule=SimpleNamespace(fixes=tuple(fixes)))
    # wheels without radius error: no steady offset, a straight path has no tracking error
    robot = SimpleNamespace(radius=RADIUS, height=0.5, max_speed=1.0, wheel_radius_error=0.0, wheel_base=0.5)
    return SimpleNamespace(name=name, path=path, s=s, speed=speed, offsets=np.array([0.0]), plans=[plan],
                           start_time=start_time, robot=robot,
                           declared=SimpleNamespace(start_jitter=jitter, speed_spread=spread, dwell=0.0))


def _fleet(jitter: float, marker_x: float = 0.0, b_start: float = 0.0):
    """Build A, measuring at (0, 0) towards a reflector at (marker_x, 6), and B, docked at (0, 3), driving east."""
    fix = SimpleNamespace(s=10.0, position=(0.0, 0.0), markers=(0,), estimate=0.01)
    a = _robot("A", np.column_stack([np.linspace(-10.0, 10.0, 201), np.zeros(201)]), 0.0, 0.0, [fix])
    b = _robot("B", np.column_stack([np.linspace(0.0, 10.0, 101), np.full(101, 3.0)]), b_start, jitter)
    scenario = SimpleNamespace(seed=3, marker_positions=lambda: np.array([[marker_x, 6.0]]),
                               sensor=SimpleNamespace(measurement_time=0.02, markers_per_fix=1),
                               marker_heights=lambda: np.array([0.3]))
    return scenario, [a, b]


def _exact(jitter: float) -> float:
    return max(0.0, 1.0 - (10.0 + 1.0 - math.sqrt(2.0 * RADIUS / ACCEL)) / jitter)


def test_a_robot_leaving_its_dock_late_hides_the_ray_as_often_as_the_uniform_release_says():
    """The sampled prediction equals the closed form 1 - 9.735 / J (J = 20 s: 0.513).

    Tolerance: the mean of N = 128 independent draws of an indicator errs by less than
    3 sqrt(p (1 - p) / N) = 0.133 (false alarm 0.3 %, the seed fixed); the body's place spread of
    8.7 cm smooths the edge by 0.14 s either way, 0.007 of J at most; the drive's ticks of 0.05 s put
    A's and B's times off by less than 2 ticks, 0.1 s, 0.005 of J. Negative control: the closed form
    of a jitter 1.5 x as long (0.675) is farther.
    """
    jitter, draws = 20.0, 128
    scenario, fleet = _fleet(jitter)
    got = predict_sampled(scenario, fleet, draws=draws)
    p = float(got.p_fix[0][0])
    tol = 3.0 * math.sqrt(_exact(jitter) * (1.0 - _exact(jitter)) / draws) + 0.007 + 0.005
    assert abs(p - _exact(jitter)) < tol, (p, _exact(jitter))
    assert abs(p - _exact(1.5 * jitter)) > tol       # the negative control
    assert got.undecided[0][0] == 0.0                # the ray passes through B's centre: decided
    assert got.p_fix[1].size == 0                    # B measures nothing


@pytest.mark.parametrize(("clear", "undecided"), [(0.39, True), (0.37, False), (0.20, False)])
def test_a_ray_grazing_a_standing_robot_within_the_tracking_bounds_is_undecided(clear, undecided):
    """B stands on its dock the whole time; the ray passes ``clear`` m from its centre.

    Undecided when the body's edge lies within the two robots' bounds of it: A's estimate bound of
    1 cm (a straight path and wheels without radius error: no tracking error) plus B's start pose
    bound of 3 mm, 1.3 cm: a ray 1 cm inside the body is, 3 cm and 20 cm inside are not (and are
    hidden in every draw).
    """
    # the ray from (0, 0) to (x, 6) passes 3 x / sqrt(x^2 + 36) from B's centre (0, 3)
    scenario, fleet = _fleet(0.0, marker_x=6.0 * clear / math.sqrt(9.0 - clear * clear), b_start=15.0)
    got = predict_sampled(scenario, fleet, draws=4)
    assert bool(got.undecided[0][0] == 1.0) is undecided
    assert got.undecided[0][0] in (0.0, 1.0)
    if not undecided:
        assert got.p_fix[0][0] > 1.0 - 1e-6
    assert 0.01 + DOCK_BOUND > RADIUS - 0.39 and 0.01 + DOCK_BOUND < RADIUS - 0.37   # the bounds the cases straddle


def test_the_schedules_risk_is_the_predictions_blocking_on_the_same_draws():
    """sampled_risk (the measurement schedule's risk) gives the fix the prediction's probability.

    Both drive the same first 128 draws of the spread (:func:`planner.fleet.sampled.sampled_drives`
    and ``predict_sampled(draws=128)``) and score B's body on the same ray: with one marker the two
    products are the same operations, so they agree to rounding (1e-12), and both to the closed form
    1 - 9.735 / J within the tolerance of the test above (false alarm 0.3 %). Negative control: the
    closed form of a jitter 1.5 x as long is farther than that tolerance.
    """
    from planner.fleet.sampled import sampled_drives, sampled_risk

    jitter, draws = 20.0, 128
    scenario, fleet = _fleet(jitter)
    risk = sampled_risk(scenario, fleet, sampled_drives(scenario, fleet, draws=draws), 0, np.array([10.0]),
                        np.array([[0.0, 0.0]]), 0.01)
    assert risk.shape == (1, 1)
    p = float(predict_sampled(scenario, fleet, draws=draws).p_fix[0][0])
    assert abs(float(risk[0, 0]) - p) < 1e-12, (risk, p)
    tol = 3.0 * math.sqrt(_exact(jitter) * (1.0 - _exact(jitter)) / draws) + 0.007 + 0.005
    assert abs(float(risk[0, 0]) - _exact(jitter)) < tol
    assert abs(float(risk[0, 0]) - _exact(1.5 * jitter)) > tol       # the negative control
