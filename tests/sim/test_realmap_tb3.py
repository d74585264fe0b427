"""The turtlebot3 world map from an empty floor: place, plan, drive; the body never touches a pillar.

The ROBOTIS map (``tb3_world.yaml`` and ``.pgm``) is checked in beside the scenario
(``tests/data/realmaps/README.md``: source, licence). The scenario is
``tests/data/realmaps/tb3_world.toml`` (a turtlebot3-sized robot: radius 0.2 m, wheel base 0.3 m,
wheel radius 0.033 m; three tasks across the arena).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

import pefsim
import scenarios
from planner.placement.placement import scenario_with_markers
from planner.plan import plan_task
from planner.schedule import clearance
from scenarios.errors import PlanningError
from tests.sim.episode.bodyclear import body_clearance, excess_offset

pytestmark = pytest.mark.e2e

SCENARIO = Path(__file__).resolve().parents[1] / "data" / "realmaps" / "tb3_world.toml"
RUNS = 6
"""Sweep runs (two per task): every one must reach its goal without touching anything."""


@pytest.fixture(scope="module")
def placed():
    sc = scenarios.load(str(SCENARIO))
    assert not sc.markers
    result = pefsim.place(sc)
    assert not result.unplanned
    return scenario_with_markers(sc, result)


def test_every_task_plans_with_the_body_clear(placed):
    for i, task in enumerate(placed.tasks):
        p = plan_task(placed, i)
        m = clearance.margin(placed, p.path, p.speed, p.schedule.s, p.schedule.predicted_error,
                             placed.dock(task.start).pose[2])
        assert not m.short.any(), clearance.Shortfall.worst(placed, m).message(task.start, task.goal)


def test_a_sweep_reaches_every_goal_without_contact(placed, tmp_path):
    """Every run reaches its goal, and the true body keeps a gap >= 0 to every obstacle.

    The body is taken as the disc of its reach around the true axle midpoint, which contains it
    at any heading.
    """
    s = pefsim.sweep(placed, tmp_path / "mc", runs=RUNS, workers=1, steps="all", report=False)
    runs = pq.read_table(tmp_path / "mc" / "runs.parquet").to_pydict()
    assert len(runs["run"]) == RUNS and all(runs["reached"]), s
    assert sorted(set(runs["task"])) == [0, 1, 2]
    plans = [plan_task(placed, i) for i in range(len(placed.tasks))]
    gaps, excess = [], []
    for part in sorted((tmp_path / "mc" / "steps").glob("*.parquet")):
        st = pq.read_table(part).to_pydict()
        xy = np.column_stack([st["true_x"], st["true_y"]])
        gaps.append(body_clearance(placed, xy).min())
        excess.append(excess_offset(placed, plans[runs["task"][runs["run"].index(st["run"][0])]], xy).max())
    assert len(gaps) == RUNS
    # measured at 200 runs (7 reflectors placed): the smallest gap 6.0 cm, every step >= 5.1 mm inside the offset bound
    assert min(gaps) >= 0.0
    assert max(excess) <= 0.0   # the bound the clearance check assumes holds at every step


def test_radius_0_3_plans_with_clearance_or_names_the_place(placed):
    """A robot radius of 0.3 m (the body within it): each task plans or names the place.

    Each task plans with the body clear, or is refused naming the obstacle it would pass too
    close to.
    """
    robot = dataclasses.replace(placed.robot, radius=0.3)
    sc = dataclasses.replace(placed, robot=robot, robot_actual=dataclasses.replace(placed.robot_actual, radius=0.3))
    planned = 0
    for i, task in enumerate(sc.tasks):
        try:
            p = plan_task(sc, i)
        except PlanningError as exc:
            assert "from the obstacle at (" in str(exc) and "needs" in str(exc), exc
            continue
        m = clearance.margin(sc, p.path, p.speed, p.schedule.s, p.schedule.predicted_error,
                             sc.dock(task.start).pose[2])
        assert not m.short.any()
        planned += 1
    assert planned >= 1
