"""Scenario loading: the built-in library loads, and every kind of bad input names file, key, value."""

from __future__ import annotations

import math
import re

import pytest

import scenarios
from scenarios import NoiseModel, PefModel, ScenarioError
from tests.scenarios.worlds import BAD, MINIMAL


@pytest.mark.parametrize("name", scenarios.builtin_names())
def test_builtin_scenarios_load(name):
    s = scenarios.load(name)
    assert s.name == name
    assert len(s.markers) >= s.sensor.markers_per_fix
    assert s.tasks, "every built-in scenario has at least one task"
    for d in s.docks:
        assert s.workspace.contains(d.position)
        assert not any(o.contains(d.position) for o in s.obstacles)


def test_library_has_the_three_promised_scenarios():
    assert {"paper-two-markers", "paper-docks", "warehouse"} <= set(scenarios.builtin_names())
    two = scenarios.load("paper-two-markers")
    assert two.marker_positions().tolist() == [[0.0, 0.0], [5.0, 0.0]]
    assert two.sensor.relative_error == pytest.approx(0.001 / 15, rel=1e-3)
    wh = scenarios.load("warehouse")
    assert 8 <= len(wh.markers) <= 12 and wh.workspace.size == (30.0, 20.0)
    assert len(scenarios.load("paper-docks").routes.segments) >= 7


def test_minimal_values_units_and_actual_overrides():
    s = scenarios.loads(MINIMAL, source="mini.toml")
    assert s.sensor.noise is NoiseModel.GAUSSIAN
    assert s.planning.pef_model is PefModel.PARALLELOGRAM
    assert s.sensor.bearing_error == pytest.approx(math.radians(0.5))
    assert s.dock("A").pose[2] == pytest.approx(math.pi / 2)
    assert s.obstacles[0].yaw == pytest.approx(math.radians(30))
    # [sensor.actual] overrides one key and keeps the rest of the declared sensor
    assert s.sensor_actual.relative_error == 3e-4 and s.sensor.relative_error == 1e-4
    assert s.sensor_actual.absolute_error == s.sensor.absolute_error
    assert s.sensor_actual.noise is NoiseModel.GAUSSIAN
    assert s.robot_actual.wheel_radius_error == 0.004 and s.robot.wheel_radius_error == 0.002
    assert s.robot_actual.wheel_radius == 0.1
    assert s.sensor.range_bound(10.0) == pytest.approx(1e-4 * 10 + 0.001)


def test_obstacle_corners_are_rotated():
    s = scenarios.loads(MINIMAL, source="mini.toml")
    c = s.obstacles[0].corners()
    assert c.shape == (4, 2)
    assert c.mean(axis=0) == pytest.approx([5.0, 4.0])
    edge = c[1] - c[0]
    assert math.atan2(edge[1], edge[0]) == pytest.approx(math.radians(30))
    assert math.hypot(*edge) == pytest.approx(2.0)


@pytest.mark.parametrize("label,text,pattern", BAD, ids=[b[0] for b in BAD])
def test_bad_input_names_file_key_and_value(label, text, pattern):
    with pytest.raises(ScenarioError) as info:
        scenarios.loads(text, source="mini.toml")
    msg = str(info.value)
    assert "\n" not in msg
    assert re.search(pattern, msg), msg


def test_the_minimal_text_itself_is_valid():
    # the negative control for the table above: without the edit, it loads
    scenarios.loads(MINIMAL, source="mini.toml")


def test_unknown_builtin_name_lists_the_library():
    with pytest.raises(ScenarioError, match=r"not a file and not a built-in scenario \(built-in: .*warehouse"):
        scenarios.load("no-such-scenario")


def test_route_network_validation():
    text = MINIMAL + """
[routes]
nodes = { A = [1.0, 1.0], B = [9.0, 7.0], n1 = [1.0, 7.0] }
segments = [["A", "n1"], ["n1", "B"], ["A", "q"]]
"""
    with pytest.raises(ScenarioError, match=r'routes\.segments\[2\]: expected node names \(unknown node "q"\)'):
        scenarios.loads(text, source="mini.toml")
    ok = text.replace(', ["A", "q"]', "") + 'traffic = { "n1-A" = 0.5 }\n'
    s = scenarios.loads(ok, source="mini.toml")
    assert s.routes.traffic_of("A", "n1") == 0.5 and s.routes.traffic_of("n1", "B") == 0.0
    moved = ok.replace("A = [1.0, 1.0], B", "A = [1.5, 1.0], B")
    with pytest.raises(ScenarioError, match=r"routes\.nodes\.A: expected the position of dock A"):
        scenarios.loads(moved, source="mini.toml")
