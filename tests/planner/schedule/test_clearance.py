"""The body's clearance on the planned path: radius + tracking + certified estimate (issue 45 item 1)."""

from __future__ import annotations

import numpy as np
import pytest

import scenarios
from planner.plan import plan_route
from planner.routes.smoothing import speed_profile
from planner.schedule import clearance
from scenarios.errors import PlanningError

# Posts around a 12 x 8 m hall, a route network A -> c -> B with one 90 deg corner at c; a
# pillar is put in per test.
WORLD = """
name = "pillar-hall"
seed = 3
[workspace]
size = [12.0, 8.0]
{pillar}
[[markers]]
id = "M1"
position = [0.0, 0.0]
[[markers]]
id = "M2"
position = [6.0, 0.0]
[[markers]]
id = "M3"
position = [12.0, 0.0]
[[markers]]
id = "M4"
position = [0.0, 8.0]
[[markers]]
id = "M5"
position = [6.0, 8.0]
[[markers]]
id = "M6"
position = [12.0, 8.0]
[[markers]]
id = "M7"
position = [0.0, 4.0]
[[markers]]
id = "M8"
position = [12.0, 4.0]
[sensor]
relative_error = 1e-4
absolute_error = 0.001
noise = "uniform"
max_range = 20.0
[robot]
radius = 0.4
max_speed = 1.0
max_yaw_rate = 0.5      # arcs of 2 m at cruising speed: the corner is an arc, not a stop
[planning]
eps_max = 0.05
[[docks]]
name = "A"
pose = [1.5, 2.0, 0.0]
[[docks]]
name = "B"
pose = [9.0, 6.5, 90.0]
[routes]
nodes = {{ A = [1.5, 2.0], c = [9.0, 2.0], B = [9.0, 6.5] }}
segments = [["A", "c"], ["c", "B"]]
"""

PILLAR = "[[obstacles]]\ncenter = [{x}, {y}]\nradius = {r}\n"


def world(x=None, y=None, r=0.3):
    return scenarios.loads(WORLD.format(pillar="" if x is None else PILLAR.format(x=x, y=y, r=r)))


def test_a_pillar_grazing_a_straight_is_refused_naming_it():
    """On a straight the tracking bound is 0 and slower does not help.

    The estimate's error (up to eps_max) and the sampling must fit between the radius and the pillar.
    """
    sc = world(5.0, 2.0 + 0.3 + 0.405)   # the path at y = 2 passes 0.405 m from the pillar
    # (the pillar is its circumscribed polygon: within 1 cm of the circle)
    with pytest.raises(PlanningError, match=r"route A -> B passes 0\.40\d m from the obstacle at \(\d\.\d\d, 2\.40\) "
                                            r"at s = 3\.\d m \(\d\.\d\d, 2\.00\), needs 0\.4\d\d m \(radius 0\.40 \+ "
                                            r"tracking 0\.00 \+ estimate 0\.0\d\d \+ sampling 0\.01\)"):
        plan_route(sc, "A", "B")


def test_the_same_pillar_farther_off_plans():
    # negative control of the refusal: 0.47 m holds radius + estimate (< eps_max) + sampling
    sc = world(5.0, 2.0 + 0.3 + 0.47)
    p = plan_route(sc, "A", "B")
    m = clearance.margin(sc, p.path, p.speed, p.schedule.s, p.schedule.predicted_error)
    assert not m.short.any()
    assert m.clearance.min() == pytest.approx(0.47, abs=0.01)


def _arc_middle(plan, m):
    """Return the check's sample nearest the middle of the corner's arc, and the unit vector to its centre."""
    r = 1.0 / plan.candidates[plan.chosen].path.curvature.max()
    centre = np.array([9.0 - r, 2.0 + r])           # the arc is tangent to y = 2 and x = 9
    mid = centre + r * np.array([1.0, -1.0]) / np.sqrt(2.0)
    i = int(np.argmin(np.hypot(*(m.points - mid).T)))
    return i, (centre - m.points[i]) / np.hypot(*(centre - m.points[i]))


def _corner_margin(sc, speed_of):
    p = plan_route(sc, "A", "B")
    return p, clearance.margin(sc, p.path, speed_of(p), p.schedule.s, p.schedule.predicted_error)


def test_a_corner_too_tight_at_cruising_speed_is_taken_slower():
    """A pillar inside the corner, between what the body needs at cruising speed and slowest.

    The plan slows there and clears it; at the cruising profile it would not.
    """
    bare = world()
    p0 = plan_route(bare, "A", "B")
    cruise = clearance.margin(bare, p0.path, speed_profile(p0.candidates[p0.chosen].path, bare.robot),
                              p0.schedule.s, p0.schedule.predicted_error)
    slow = clearance.margin(bare, p0.path, np.minimum(p0.speed, clearance.SLOWEST_LOOKAHEAD_SPEED),
                            p0.schedule.s, p0.schedule.predicted_error)
    i, inward = _arc_middle(p0, cruise)
    assert cruise.tracking[i] > slow.tracking[i] + 0.03   # the lookahead's cut shrinks slower
    # the pillar's surface on the inside of the turn, midway between the two needs
    gap = 0.5 * (cruise.needed[i] + slow.needed[i])
    centre = cruise.points[i] + (gap + 0.3) * inward
    sc = world(round(float(centre[0]), 3), round(float(centre[1]), 3))
    p, m = _corner_margin(sc, lambda p: p.speed)
    assert not m.short.any()
    assert p.speed.max() == pytest.approx(sc.robot.max_speed)            # cruising elsewhere
    near = np.hypot(*(p.path - centre).T) < 1.5
    assert p.speed[near].max() < sc.robot.max_speed                    # slowed at the corner
    # negative control: the cruising profile on this path falls short
    _, m_fast = _corner_margin(sc, lambda p: speed_profile(p.candidates[p.chosen].path, sc.robot))
    assert m_fast.short.any()


def test_a_corner_too_tight_even_slow_is_refused():
    bare = world()
    p0 = plan_route(bare, "A", "B")
    slow = clearance.margin(bare, p0.path, np.minimum(p0.speed, clearance.SLOWEST_LOOKAHEAD_SPEED),
                            p0.schedule.s, p0.schedule.predicted_error)
    i, inward = _arc_middle(p0, slow)
    centre = slow.points[i] + (slow.needed[i] - 0.005 + 0.3) * inward
    sc = world(round(float(centre[0]), 3), round(float(centre[1]), 3))
    with pytest.raises(PlanningError, match=r"route A -> B passes 0\.\d+ m from the obstacle at .* needs 0\.\d+ m "
                                            r"\(radius 0\.40 \+ tracking 0\.\d+"):
        plan_route(sc, "A", "B")
