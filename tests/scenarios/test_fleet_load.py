"""[[robots]], robot.height and [[markers]] height: read, defaulted, and refused in one line."""

from __future__ import annotations

import pytest

from scenarios import ScenarioError, load, loads

BASE = """
name = "f"
[workspace]
size = [20.0, 10.0]
[[markers]]
id = "a"
position = [0.0, 0.0]
[[markers]]
id = "b"
position = [20.0, 0.0]
{marker_extra}
[sensor]
[robot]
max_speed = 0.8
{robot_extra}
[planning]
eps_max = 0.05
[[docks]]
name = "A"
pose = [1.0, 1.0, 0.0]
[[docks]]
name = "B"
pose = [19.0, 9.0, 0.0]
[[docks]]
name = "C"
pose = [19.0, 1.0, 0.0]
[[tasks]]
from = "A"
to = "B"
[[tasks]]
from = "B"
to = "C"
[[tasks]]
from = "C"
to = "A"
{robots}
"""


def text(robots: str = "", robot_extra: str = "", marker_extra: str = "") -> str:
    return BASE.format(robots=robots, robot_extra=robot_extra, marker_extra=marker_extra)


def test_no_robots_is_one_robot_with_defaults():
    sc = loads(text(), source="f.toml")
    assert sc.robots == () and not sc.is_fleet
    assert sc.robot.height == 0.5
    assert all(m.height is None for m in sc.markers)


def test_robots_override_the_shared_robot():
    sc = loads(text(robots="""
[[robots]]
name = "r1"
tasks = [0, 1, 2]
height = 1.2
[robots.actual]
max_speed = 0.7
[[robots]]
name = "r2"
tasks = [2]
start_time = 4.5
""", marker_extra='height = 0.3'), source="f.toml")
    r1, r2 = sc.robots
    assert (r1.name, r1.tasks, r1.start_time) == ("r1", (0, 1, 2), 0.0)
    assert r1.robot.height == 1.2 and r1.robot.max_speed == 0.8
    assert r1.robot_actual.height == 1.2 and r1.robot_actual.max_speed == 0.7
    assert r2.robot == sc.robot and r2.robot_actual == sc.robot_actual and r2.start_time == 4.5
    assert r1.park is None and r2.park is None
    parked = loads(text(robots='[[robots]]\nname = "r1"\ntasks = [0]\npark = "C"'), source="f.toml")
    assert parked.robots[0].park == "C"
    assert [m.height for m in sc.markers] == [None, 0.3]


@pytest.mark.parametrize("robots,pattern", [
    ('[[robots]]\nname = "r"\ntasks = [3]',
     r"f\.toml: robots\[0\]\.tasks\[0\]: expected a task index in 0\.\.2 .*got 3"),
    ('[[robots]]\nname = "r"\ntasks = []', r"robots\[0\]\.tasks: expected a non-empty list"),
    ('[[robots]]\nname = "r"\ntasks = [0, 2]',
     r"robots\[0\]\.tasks\[1\]: expected a task starting at dock 'B' where task 0 ends .*got 2"),
    ('[[robots]]\nname = "r"\ntasks = [0]\n[[robots]]\nname = "r"\ntasks = [1]',
     r'robots\[1\]\.name: expected a unique robot name, got "r"'),
    ('[[robots]]\nname = "r"\ntasks = [0]\nstart_time = -1.0',
     r"robots\[0\]\.start_time: expected a number >= 0, got -1\.0"),
    ('[[robots]]\nname = "r"\ntasks = [0]\nwings = 2', r"robots\[0\]\.wings: unknown key"),
    ('[[robots]]\nname = "r"\ntasks = [0]\nheight = 0.1',
     r"robots\[0\]\.height: expected a body taller than its wheels"),
    ('[[robots]]\nname = "r"\ntasks = [0]\n[robots.actual]\nheight = 500.0',
     r"robots\[0\]\.actual\.height: expected a number <= 20"),
    ('[[robots]]\nname = "r"\ntasks = [true]', r"robots\[0\]\.tasks: expected a non-empty list"),
    ('[[robots]]\nname = "r"\ntasks = [0]\npark = "Z"',
     r'robots\[0\]\.park: expected a dock name \(A, B, C\), got "Z"'),
    ('[[robots]]\nname = "r"\ntasks = [0]\npark = "B"',
     r"robots\[0\]\.park: expected a dock other than 'B', where the robot's last task ends"),
    ('[[robots]]\nname = "r"\ntasks = [0]\npark = 3', r"robots\[0\]\.park: expected a string, got 3"),
])
def test_bad_robots_name_file_key_and_value(robots, pattern):
    with pytest.raises(ScenarioError, match=pattern):
        loads(text(robots=robots), source="f.toml")


@pytest.mark.parametrize("robot_extra,marker_extra,pattern", [
    ("height = 0.0", "", r"f\.toml: robot\.height: expected a number > 0, got 0\.0"),
    ("height = 0.15", "", r"robot\.height: expected a body taller than its wheels \(0\.2"),
    ("", "height = -0.3", r"markers\[1\]\.height: expected a number > 0, got -0\.3"),
    ("", 'height = "low"', r'markers\[1\]\.height: expected a number, got "low"'),
])
def test_bad_heights(robot_extra, marker_extra, pattern):
    with pytest.raises(ScenarioError, match=pattern):
        loads(text(robot_extra=robot_extra, marker_extra=marker_extra), source="f.toml")


def test_builtin_fleet_loads():
    sc = load("warehouse-fleet")
    assert [r.name for r in sc.robots] == ["r1", "r2", "r3"]
    assert all(m.height is not None and m.height < sc.robot.height for m in sc.markers)


def test_builtin_hall_fleet_is_the_hall_its_generator_writes():
    # the 120 x 80 m hall of the benchmarks with six robots trading docks, most with two tasks
    import importlib.util
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    spec = importlib.util.spec_from_file_location("hall_scenario", root / "benchmarks" / "hall_scenario.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    assert (root / "scenarios" / "library" / "hall-fleet.toml").read_text() == gen.hall_fleet_toml()
    sc = load("hall-fleet")
    assert sc.workspace.size == (120.0, 80.0) and len(sc.robots) == 6
    assert sum(len(r.tasks) > 1 for r in sc.robots) >= 3
    starts = {sc.tasks[r.tasks[0]].start for r in sc.robots}
    ends = {sc.tasks[r.tasks[-1]].goal for r in sc.robots}
    assert len(starts & ends) >= 2      # robots end on docks others start from: they trade docks
