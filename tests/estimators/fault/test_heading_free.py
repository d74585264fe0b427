"""The heading-free bearing constraint of the realised fault area (robot-frame bearings).

Under bounded noise the truth must lie in the fault area whatever the heading: a miss is
impossible, so the tests allow none (false-alarm probability 0). The negative control is the
heading-given construction it replaces: world wedges from a heading whose error is beyond
the 3-sigma margin they were widened by.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimators.fault.exact import DEFAULT_TOLERANCE_FRACTION, exact_fault_area
from estimators.fault.pieces import pair_circle
from estimators.measurements import ranges, world_bearing, wrap_angle

XI = math.radians(0.15)          # bearing bound of an L-shaped hall whose tightness check once failed
HEADING_STD = math.radians(0.2)  # a filter heading's std, for the negative control
TRIALS = 300


def _angle(p, mi, mj):
    """``a_i(p) - a_j(p)`` wrapped [rad]: the angle at p from marker j to marker i."""
    return wrap_angle(math.atan2(mi[1] - p[1], mi[0] - p[0]) - math.atan2(mj[1] - p[1], mj[0] - p[0]))


def _draw(rng, k):
    """Markers (k, 2), truth (2,), heading, rho (k,), noisy ranges (k,), robot-frame bearings (k,)."""
    while True:
        markers = rng.uniform(0.0, 20.0, (k, 2))
        truth = rng.uniform(0.0, 20.0, 2)
        r = ranges(truth, markers)
        if r.min() > 1.0 and np.min(np.hypot(*(markers[:, None] - markers[None]).transpose(2, 0, 1))
                                    + np.eye(k) * 1e3) > 1.0:
            break
    heading = rng.uniform(-math.pi, math.pi)
    rho = 0.002 + 6.7e-5 * r
    meas = r + rng.uniform(-1.0, 1.0, k) * rho
    robot = wrap_angle(world_bearing(truth, markers) - heading + rng.uniform(-1.0, 1.0, k) * XI)
    return markers, truth, heading, rho, meas, robot


@pytest.mark.parametrize("phi", [0.3, 1.2, 2.0, 3.0, -0.4, -1.6, -2.9])
def test_pair_circle_is_the_level_set_and_its_disk_the_larger_angles(phi):
    mi, mj = np.array([3.0, 1.0]), np.array([-1.0, 2.0])
    c, r = pair_circle(mi, mj, phi)
    for t in np.linspace(0.0, 2.0 * math.pi, 13)[:-1]:
        on = c + r * np.array([math.cos(t), math.sin(t)])
        if min(np.hypot(*(on - mi)), np.hypot(*(on - mj))) < 1e-6:
            continue
        f = _angle(on, mi, mj)
        # on the circle: phi on one arc, phi - pi on the other
        assert min(abs(wrap_angle(f - phi)), abs(wrap_angle(f - phi + math.pi))) < 1e-9
        inside = c + 0.9 * r * np.array([math.cos(t), math.sin(t)])
        in_d = 0.0 < (_angle(inside, mi, mj) - phi) % (2.0 * math.pi) < math.pi
        assert in_d == (math.sin(phi) > 0.0)


@pytest.mark.parametrize("k", [2, 3, 4])
def test_heading_free_area_holds_the_truth_whatever_the_heading(k):
    rng = np.random.default_rng(2300 + k)
    misses = fails = 0
    for _ in range(TRIALS):
        markers, truth, heading, rho, meas, robot = _draw(rng, k)
        fa = exact_fault_area(markers, meas, rho, truth + rng.uniform(-0.01, 0.01, 2),
                              robot_bearings=robot, robot_bearing_error=XI)
        misses += not fa.contains(truth)
        # Negative control: the old wedges, in the world frame of a heading 3 sigma + 2.5 xi off
        # and widened by 3 sigma: every wedge misses the truth by >= 0.5 xi.
        wrong = heading + 3.0 * HEADING_STD + 2.5 * XI
        old = exact_fault_area(markers, meas, rho, truth, bearings=wrap_angle(robot + wrong),
                               bearing_error=XI + 3.0 * HEADING_STD)
        fails += not old.contains(truth)
    assert misses == 0
    assert fails == TRIALS


@pytest.mark.parametrize("k", [2, 3])
def test_heading_free_area_lies_within_its_tolerance_of_the_exact_set(k):
    """Every vertex satisfies each bound up to what the polygonisation may add (module docstring)."""
    rng = np.random.default_rng(2310 + k)
    for _ in range(60):
        markers, truth, heading, rho, meas, robot = _draw(rng, k)
        fa = exact_fault_area(markers, meas, rho, truth, robot_bearings=robot, robot_bearing_error=XI)
        tol = DEFAULT_TOLERANCE_FRACTION * rho.min()
        assert fa.tolerance == tol
        for p in fa.ring:
            d = ranges(p, markers)
            assert np.all(np.abs(d - meas) <= rho + tol * (1.0 + 1e-6))
            for i in range(k):
                for j in range(i + 1, k):
                    slack = tol * (1.0 / d[i] + 1.0 / d[j]) * (1.0 + 1e-6) + 1e-12
                    assert abs(wrap_angle(_angle(p, markers[i], markers[j]) - (robot[i] - robot[j]))) \
                        <= 2.0 * XI + slack


def test_bearings_shrink_the_range_only_area():
    """The bearing pairs only intersect: the area is inside the ranges-only one (the promise's).

    Up to the polygonisation: it lies in the ranges-only exact set of ``rho + tolerance``.
    """
    rng = np.random.default_rng(2320)
    smaller = 0
    for _ in range(100):
        markers, truth, heading, rho, meas, robot = _draw(rng, 2)
        with_b = exact_fault_area(markers, meas, rho, truth, robot_bearings=robot, robot_bearing_error=XI)
        # the polygon lies in the ranges-only exact set of rho + tol, which this one contains
        widened = exact_fault_area(markers, meas, rho + with_b.tolerance, truth)
        assert with_b.polygon.difference(widened.polygon.buffer(1e-9)).is_empty
        assert with_b.diameter <= widened.diameter
        smaller += with_b.area < 0.99 * exact_fault_area(markers, meas, rho, truth).area
    assert smaller > 0   # the bearings do constrain somewhere


def test_robot_frame_bearings_are_checked():
    markers = np.array([[0.0, 0.0], [5.0, 0.0]])
    with pytest.raises(ValueError, match="robot-frame"):
        exact_fault_area(markers, np.array([3.0, 3.0]), np.full(2, 0.01), np.zeros(2),
                         robot_bearings=np.zeros(3), robot_bearing_error=XI)
    with pytest.raises(ValueError, match="> 0"):
        exact_fault_area(markers, np.array([3.0, 3.0]), np.full(2, 0.01), np.zeros(2),
                         robot_bearings=np.zeros(2), robot_bearing_error=0.0)
