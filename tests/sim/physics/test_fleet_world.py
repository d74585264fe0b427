"""A fleet world: robot bodies hide low reflectors from the other robots' lasers, never their own; overlap counts."""

from __future__ import annotations

import math

import pytest

from scenarios import SimulationError, loads
from sim.physics.laser import LaserSensor
from sim.physics.world import PhysicsWorld

TEXT = """
name = "row"
[workspace]
size = [20.0, 6.0]
[[markers]]
id = "low"
position = [19.0, 3.0]
height = 0.3
[[markers]]
id = "high"
position = [19.0, 3.2]
[[markers]]
id = "above"
position = [19.0, 2.8]
height = 0.9
[sensor]
[robot]
[planning]
eps_max = 0.05
[[docks]]
name = "A"
pose = [2.0, 3.0, 0.0]
[[docks]]
name = "B"
pose = [10.0, 3.0, 0.0]
[[docks]]
name = "C"
pose = [2.0, 1.0, 0.0]
[[tasks]]
from = "A"
to = "C"
[[tasks]]
from = "B"
to = "C"
[[robots]]
name = "watcher"
tasks = [0]
[[robots]]
name = "blocker"
tasks = [1]
{extra}
"""


def world(extra: str = "") -> PhysicsWorld:
    return PhysicsWorld(loads(TEXT.format(extra=extra), source="row.toml"), fleet=True)


def test_a_robot_between_hides_only_reflectors_below_its_top():
    with world() as w:
        w.reset_fleet([(2.0, 3.0, 0.0), (10.0, 3.0, 0.0)])
        laser = LaserSensor(w, w.scenario.sensor_actual, w.scenario.marker_positions(), robot=0)
        # the blocker (0.5 m tall) stands on the line to the 0.3 m reflector; the reflector
        # without a height is above every robot; the 0.9 m one is seen over the blocker's top
        assert [laser.visible(i) for i in range(3)] == [False, True, True]
        assert laser.blocked_by == {0: 1}
        # the blocker's own laser looks through its own body
        own = LaserSensor(w, w.scenario.sensor_actual, w.scenario.marker_positions(), robot=1)
        assert [own.visible(i) for i in range(3)] == [True, True, True]
        # moved aside, it hides nothing
        w.reset_fleet([(2.0, 3.0, 0.0), (10.0, 1.0, 0.0)])
        assert [laser.visible(i) for i in range(3)] == [True, True, True] and laser.blocked_by == {}


def test_every_line_of_sight_a_robot_hides_is_named_walls_first():
    with world(extra="[[obstacles]]\ncenter = [14.0, 3.0]\nsize = [0.4, 0.4]") as w:
        w.reset_fleet([(2.0, 3.0, 0.0), (10.0, 3.0, 0.0)])
        laser = LaserSensor(w, w.scenario.sensor_actual, w.scenario.marker_positions(), robot=0)
        # the wall behind the blocker hides the low reflector anyway: not the robot's doing
        assert laser.hidden_by_robots() == {}
    with world() as w:
        w.reset_fleet([(2.0, 3.0, 0.0), (10.0, 3.0, 0.0)])
        laser = LaserSensor(w, w.scenario.sensor_actual, w.scenario.marker_positions(), robot=0)
        assert laser.hidden_by_robots() == {0: 1}     # only the low one, by the blocker
        laser.blocked = frozenset({0})                  # blocked for the fix already: not counted again
        assert laser.hidden_by_robots() == {}
        laser.blocked = frozenset()
        w.reset_fleet([(2.0, 3.0, 0.0), (10.0, 1.0, 0.0)])
        assert laser.hidden_by_robots() == {}
    one = loads(TEXT.format(extra="").split("[[robots]]")[0], source="row.toml")
    with PhysicsWorld(one) as w:                        # a single robot's world: nobody to hide anything
        assert LaserSensor(w, one.sensor_actual, one.marker_positions()).hidden_by_robots() == {}


def test_a_low_robot_hides_nothing_above_it():
    # a 0.25 m robot under the ray from a 0.5 m laser to the 0.3 m reflector 17 m away: the ray
    # is 0.5 - 0.2 * 8 / 17 = 0.41 m high above it
    with world(extra="height = 0.25\nwheel_radius = 0.05") as w:
        w.reset_fleet([(2.0, 3.0, 0.0), (10.0, 3.0, 0.0)])
        laser = LaserSensor(w, w.scenario.sensor_actual, w.scenario.marker_positions(), robot=0)
        assert laser.visible(0)


def test_overlapping_bodies_touch_and_bodies_take_no_part_in_the_dynamics():
    with world() as w:
        w.reset_fleet([(2.0, 3.0, 0.0), (2.7, 3.0, 0.0)])     # 0.7 m apart, radius 0.4 each
        assert w.touching() == [(0, 1)]
        w.reset_fleet([(2.0, 3.0, 0.0), (2.9, 3.0, 0.0)])
        assert w.touching() == []
        # a robot inside its own body (and next to another's) stands still: no contact forces
        w.step(240)
        x, y, th = w.robots[0].true_pose()
        assert math.hypot(x - 2.0, y - 3.0) < 1e-3 and abs(th) < 1e-3


def test_a_fleet_world_needs_robots():
    sc = loads(TEXT.format(extra="").split("[[robots]]")[0], source="row.toml")
    with pytest.raises(SimulationError, match="a fleet world needs \\[\\[robots\\]\\]"):
        PhysicsWorld(sc, fleet=True)


def test_a_fleet_world_starts_each_robot_on_its_first_dock_and_resets_only_as_a_fleet():
    with world() as w:
        # built, every robot stands on the start of its first task, apart, and stays there
        starts = [(2.0, 3.0), (10.0, 3.0)]
        w.step(240)
        for r, (x, y) in zip(w.robots, starts, strict=True):
            px, py, _ = r.true_pose()
            assert math.hypot(px - x, py - y) < 1e-3
        # a lone robot's reset would leave the others' drives chasing what they were told before
        w.robots[1].set_wheel_speeds(5.0, 5.0)
        w.step(48)
        with pytest.raises(SimulationError, match="reset_fleet"):
            w.reset((2.0, 3.0, 0.0))
        w.reset_fleet([(2.0, 3.0, 0.0), (10.0, 1.0, 0.0)])
        w.step(240)
        x, y, _ = w.robots[1].true_pose()
        assert math.hypot(x - 10.0, y - 1.0) < 1e-3
    sc = loads(TEXT.format(extra=""), source="row.toml")
    with pytest.raises(SimulationError, match="reset poses: expected 2 finite"):
        PhysicsWorld(sc, pose=[(2.0, 3.0, 0.0)], fleet=True)
