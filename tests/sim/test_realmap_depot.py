"""Nav2's depot map with Nav2's own route graph, from an empty floor: place, plan, drive, no contact.

Nav2's depot map (``depot.yaml`` and ``.pgm``) and its route graph (``depot_graph.geojson``)
are checked in beside the scenario (``tests/data/realmaps/README.md``: source, licence). The
scenario is ``tests/data/realmaps/depot.toml`` (a robot of Nav2's default size: radius 0.22 m,
wheel base 0.287 m, wheel radius 0.033 m; three tasks between graph nodes across the depot).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

import pefsim
import scenarios
from planner.placement.placement import scenario_with_markers
from planner.plan import plan_task
from planner.schedule import clearance
from scenarios.errors import ScenarioWarning
from tests.sim.episode.bodyclear import body_clearance, excess_offset

pytestmark = pytest.mark.e2e

SCENARIO = Path(__file__).resolve().parents[1] / "data" / "realmaps" / "depot.toml"
RUNS = 3
"""Sweep runs (one per task): every one must reach its goal without touching anything."""


@pytest.fixture(scope="module")
def placed():
    # Nav2's own graph gives two edges each of three ids: read, said once, every edge kept
    with pytest.warns(ScenarioWarning, match="repeated edge ids 10006, 10007, 10012, 10013, 10020, 10021"):
        sc = scenarios.load(str(SCENARIO))
    assert not sc.markers
    assert len(sc.routes.nodes) == 34 and len(sc.routes.segments) == 39
    assert not any(e.why_not for e in sc.routes.edges)   # every edge keeps the radius from the map
    result = pefsim.place(sc)
    assert not result.unplanned
    return scenario_with_markers(sc, result)


def test_every_task_plans_on_the_graph_with_the_body_clear(placed):
    """Each task's route runs along the graph's edges (through its nodes), with the body clear."""
    nodes = np.array(list(placed.routes.nodes.values()))
    for i, task in enumerate(placed.tasks):
        p = plan_task(placed, i)
        m = clearance.margin(placed, p.path, p.speed, p.schedule.s, p.schedule.predicted_error,
                             placed.dock(task.start).pose[2])
        assert not m.short.any(), clearance.Shortfall.worst(placed, m).message(task.start, task.goal)
        # the route leaves one graph node and ends at another; the smoothed path stays near the edges
        ends = [placed.routes.nodes[placed.dock(d).node] for d in (task.start, task.goal)]
        assert np.allclose(p.path[[0, -1]], ends, atol=1e-6)
        d_node = np.hypot(*(p.path[:, None, :] - nodes[None, :, :]).transpose(2, 0, 1)).min(axis=0)
        assert (d_node < 1.5).sum() >= 3   # it passes nodes between its ends: a route of the graph


def test_a_sweep_reaches_every_goal_without_contact(placed, tmp_path):
    """Every run reaches its goal, and the true body keeps a gap >= 0 to every obstacle.

    The body is taken as the disc of its reach around the true axle midpoint, which contains it
    at any heading; every true position lies inside the offset bound the clearance check assumes.
    """
    s = pefsim.sweep(placed, tmp_path / "mc", runs=RUNS, workers=1, steps="all", report=False)
    runs = pq.read_table(tmp_path / "mc" / "runs.parquet").to_pydict()
    assert len(runs["run"]) == RUNS and all(runs["reached"]), s
    assert set(runs["status"]) == {"ok"} and not any(runs["collisions"])
    assert sorted(set(runs["task"])) == [0, 1, 2]
    plans = [plan_task(placed, i) for i in range(len(placed.tasks))]
    gaps, excess = [], []
    for part in sorted((tmp_path / "mc" / "steps").glob("*.parquet")):
        st = pq.read_table(part).to_pydict()
        xy = np.column_stack([st["true_x"], st["true_y"]])
        gaps.append(body_clearance(placed, xy).min())
        excess.append(excess_offset(placed, plans[runs["task"][runs["run"].index(st["run"][0])]], xy).max())
    assert len(gaps) == RUNS
    assert min(gaps) >= 0.0
    assert max(excess) <= 0.0   # the bound the clearance check assumes holds at every step
