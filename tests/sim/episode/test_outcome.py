"""Every episode knows what it did: collided, stuck or deadlocked, never ``ok`` when it did.

A lone robot drives a plan made for an empty floor into a box that stands on its path; the same
plan on the empty floor is the negative control. A robot whose motors cannot turn its wheels is
stuck. A fleet robot whose zone requests are all refused waits past its bound and is deadlocked.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from planner.fleet import zones as zone_module
from scenarios import loads
from scenarios.obstacles import Obstacle
from sim.episode.drive import prepare, run_episode
from sim.episode.fleet import prepare_fleet, run_fleet_episode
from sim.episode.outcome import longest_run, wait_bound, wait_cycles
from tests.sim.fleets import CROSS

LONE = """
name = "lone"
seed = 3
[workspace]
size = [8.0, 6.0]
[[markers]]
id = "SW"
position = [0.0, 0.0]
[[markers]]
id = "SE"
position = [8.0, 0.0]
[[markers]]
id = "NE"
position = [8.0, 6.0]
[[markers]]
id = "NW"
position = [0.0, 6.0]
[sensor]
[robot]
[planning]
eps_max = 0.05
resolution = 0.2
[[docks]]
name = "W"
pose = [1.0, 3.0, 0.0]
[[docks]]
name = "E"
pose = [7.0, 3.0, 0.0]
[[tasks]]
from = "W"
to = "E"
"""
BOX = (2.6, 3.0)
"""Centre of the box put on the path in the robot's way (the plan was made without it) [m]."""


@pytest.fixture(scope="module")
def lone():
    sc = loads(LONE, source="lone.toml")
    return sc, prepare(sc, 0)


def test_a_robot_driven_into_a_box_collided(lone):
    sc, prepared = lone
    boxed = dataclasses.replace(sc, obstacles=(Obstacle.box(BOX, (0.2, 0.2)),))
    res = run_episode(boxed, 0, seed=1, prepared=prepared, time_limit=8.0)
    s = res.summary
    assert s["status"] in ("collided", "stuck") and s["collisions"] >= 1 and not s["reached"]
    assert s["contact_with"] == "obstacle 0 (box at (2.60, 3.00))"
    # the chassis' front reaches ~half a wheel base ahead of the axle: the first contact is within
    # the robot's radius of the box's face, on the path (y = 3)
    face = BOX[0] - 0.1
    assert face - sc.robot.radius - 0.05 <= s["contact_x"] <= face
    assert abs(s["contact_y"] - 3.0) < 0.05
    assert s["contact_s"] == pytest.approx(s["contact_x"] - 1.0, abs=0.05)
    i = int(np.searchsorted(res.steps.t, s["contact_t"]))
    assert np.hypot(*(res.steps.true_pose[i, :2] - (s["contact_x"], s["contact_y"]))) < 0.02


def test_the_same_plan_on_the_empty_floor_is_ok(lone):
    """Negative control: without the box the same run touches nothing and makes progress."""
    sc, prepared = lone
    s = run_episode(sc, 0, seed=1, prepared=prepared, time_limit=8.0).summary
    assert s["status"] == "ok" and s["collisions"] == 0 and s["contact_x"] is None
    assert not s["stuck"] and s["stall_time"] < s["stuck_bound"]


def test_a_robot_whose_wheels_cannot_turn_is_stuck(lone):
    sc, prepared = lone
    # the simulated motors' torque can hold nothing up: the wheels stay where they are
    blocked = dataclasses.replace(sc, robot_actual=dataclasses.replace(sc.robot_actual, max_wheel_torque=1e-6))
    s = run_episode(blocked, 0, seed=1, prepared=prepared, time_limit=s_bound(sc) + 3.0).summary
    assert s["status"] == "stuck" and s["stuck"] and not s["reached"] and s["collisions"] == 0
    assert s["stall_time"] > s["stuck_bound"]
    assert math.hypot(s["stall_x"] - 1.0, s["stall_y"] - 3.0) < 0.05   # it never left its dock


def s_bound(sc) -> float:
    """Return the stuck bound of the lone robot's follower [s] (what the runs table reports)."""
    from sim.episode.follower import PurePursuit
    from sim.episode.outcome import stuck_bound

    f = PurePursuit(path=np.zeros((2, 2)), speed=np.ones(2), max_speed=sc.robot.max_speed,
                    max_yaw_rate=sc.robot.max_yaw_rate)
    return stuck_bound(f.max_yaw_rate, f.max_yaw_accel, f.max_speed, f.max_accel)


def test_a_fleet_robot_refused_every_zone_is_deadlocked(monkeypatch):
    sc = loads(CROSS, source="cross.toml")
    prepared = prepare_fleet(sc)
    plans = prepared.plan.robots
    end = max(float(rp.timeline.end_time) for rp in plans)
    bound = wait_bound(longest_run(plans[1].timeline.waiting, plans[1].timeline.t), end)
    real = zone_module.ZoneControl.request

    def refuse_north(self, i, s):
        if i == 1:   # "north" is refused whatever it asks, as if "east" held its way for good
            self.refused_by[1] = 0
            return False
        return real(self, i, s)

    monkeypatch.setattr(zone_module.ZoneControl, "request", refuse_north)
    res = run_fleet_episode(sc, seed=5, prepared=prepared, time_limit=bound + 3.0)
    east, north = (r.result.summary for r in res.robots)
    assert north["status"] == "deadlocked" and north["deadlocked"] and not north["reached"]
    assert north["longest_wait"] > north["wait_bound"] == pytest.approx(bound)
    assert north["waited_for"] == "east"
    assert math.hypot(north["wait_x"] - 6.0, north["wait_y"] - 1.0) < 0.1   # at its dock C
    assert east["status"] == "ok" and not east["deadlocked"]   # it drove on and arrived


def test_two_robots_waiting_for_each_other_are_deadlocked_at_once(monkeypatch):
    """A circular wait is a deadlock whenever it forms: both are refused by each other from the start."""
    sc = loads(CROSS, source="cross.toml")
    prepared = prepare_fleet(sc)

    def refuse_both(self, i, s):
        self.refused_by[i] = 1 - i
        return False

    monkeypatch.setattr(zone_module.ZoneControl, "request", refuse_both)
    res = run_fleet_episode(sc, seed=5, prepared=prepared, time_limit=4.0)
    for r, other in zip(res.robots, ("north", "east"), strict=True):
        s = r.result.summary
        assert s["status"] == "deadlocked" and s["waited_for"] == other
        assert s["longest_wait"] < s["wait_bound"]   # caught by the circle, long before the bound


def test_wait_cycles():
    assert wait_cycles([True, True, False], [1, 0, -1]) == [True, True, False]
    assert wait_cycles([True, True, True], [1, 2, 0]) == [True, True, True]
    # negative controls: a chain that ends at a robot still driving, or at nobody, is no circle
    assert wait_cycles([True, True, False], [1, 2, 0]) == [False, False, False]
    assert wait_cycles([True, False], [1, 0]) == [False, False]
    assert wait_cycles([True], [-1]) == [False]
