"""The user's frame: a scenario moved by workspace.origin gives the same maps, plans and episodes, moved."""

from __future__ import annotations

import numpy as np
import pytest

import scenarios
from planner.pef.map import PEF
from planner.plan import plan_route
from sim.episode.drive import run_episode
from tests.scenarios.worlds import shifted


@pytest.mark.parametrize("name", ["paper-docks", "warehouse"])
def test_map_and_plan_move_with_the_origin(name):
    dx, dy = 250.0, -80.0
    base, moved = scenarios.load(name), shifted(name, dx, dy)
    a, b = PEF(base).grid(), PEF(moved).grid()
    assert np.allclose(b.x - dx, a.x, atol=1e-9) and np.allclose(b.y - dy, a.y, atol=1e-9)
    assert np.array_equal(a.free, b.free) and np.array_equal(np.isfinite(a.tau), np.isfinite(b.tau))
    fin = np.isfinite(a.tau)
    assert np.allclose(b.tau[fin], a.tau[fin], rtol=1e-9, atol=0)
    t = base.tasks[0]
    pa, pb = plan_route(base, t.start, t.goal), plan_route(moved, t.start, t.goal)
    assert pa.candidates[pa.chosen].id == pb.candidates[pb.chosen].id
    assert np.allclose(np.asarray(pb.path) - [dx, dy], np.asarray(pa.path), atol=1e-6)


def test_an_episode_far_from_zero_drives_like_the_one_at_zero():
    dx, dy = 250000.0, 80000.0
    base, moved = scenarios.load("paper-docks"), shifted("paper-docks", dx, dy)
    a, b = run_episode(base, 0, seed=5), run_episode(moved, 0, seed=5)
    assert a.summary["reached"] and b.summary["reached"]
    assert a.summary["fixes"] == b.summary["fixes"]
    # Built in local coordinates, the physics sees the same world: the true paths agree to a
    # micrometre (the plan's coordinates differ in their last bits only).
    n = min(len(a.steps.t), len(b.steps.t))
    assert abs(len(a.steps.t) - len(b.steps.t)) <= 2
    err = np.abs(b.steps.true_pose[:n, :2] - [dx, dy] - a.steps.true_pose[:n, :2]).max()
    assert err < 1e-6, err
    assert abs(a.summary["max_error"] - b.summary["max_error"]) < 1e-6


def test_a_marker_on_the_far_wall_of_a_far_workspace_is_inside():
    # 250000.3 + 30.3 and 5300000.1 + 20.1 round below the literals 250030.6 and 5300020.2:
    # markers written on those walls are still on them.
    assert 250000.3 + 30.3 < 250030.6 and 5300000.1 + 20.1 < 5300020.2
    text = """
name = "far"
[workspace]
size = [30.3, 20.1]
origin = [250000.3, 5300000.1]
[[markers]]
id = "A"
position = [250030.6, 5300020.2]
[[markers]]
id = "B"
position = [250000.3, 5300000.1]
[sensor]
[planning]
eps_max = 0.05
"""
    sc = scenarios.loads(text)
    assert sc.workspace.contains(sc.markers[0].position)
    with pytest.raises(scenarios.ScenarioError, match=r"markers\[0\]\.position: expected \[x, y\] inside"):
        scenarios.loads(text.replace("250030.6", "250030.601"))
