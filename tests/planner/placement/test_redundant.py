"""Redundancy-1 placement: any one marker blocked, every point of the chosen path stays under eps_max.

Checked independently of the tau_r shortcut and of the cover's robustness test: for every placed
marker, the plain PEF (redundancy 0) of the scenario *without* that marker, at every point.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import scenarios
from planner.pef.map import PEF
from planner.placement import placement
from planner.placement.sites import cover_points
from planner.plan import plan_route


def _with_r(sc, r):
    return dataclasses.replace(sc, planning=dataclasses.replace(sc.planning, redundancy=r))


def _worst_without_one(placed, points):
    """Largest, over every single marker removed, of the plain tau at each point, shape (N,)."""
    worst = np.zeros(len(points))
    for drop in range(len(placed.markers)):
        fewer = dataclasses.replace(placed, markers=placed.markers[:drop] + placed.markers[drop + 1:])
        worst = np.maximum(worst, PEF(fewer, redundancy=0).at(points).tau)
    return worst


@pytest.fixture(scope="module")
def docks():
    sc = scenarios.load("paper-docks")
    return {r: (sc_r := _with_r(sc, r), placement.place(sc_r, time_limit=20)) for r in (0, 1)}


def test_redundancy_1_placement_survives_any_one_marker_blocked(docks):
    sc, res = docks[1]
    assert res.redundancy == 1 and len(res.uncovered) == 0
    assert res.count > docks[0][1].count >= 2  # redundancy costs reflectors
    assert res.lower_bound >= docks[0][1].lower_bound
    placed = placement.scenario_with_markers(sc, res)
    pts = cover_points(sc)
    assert np.all(_worst_without_one(placed, pts) < sc.planning.eps_max)
    # the chosen path (planned on tau_1) keeps the bound too, at its own points
    task = sc.tasks[0]
    path = np.asarray(plan_route(placed, task.start, task.goal, schedule=False).path, float)
    seg = [path[i] + np.linspace(0, 1, 20)[:, None] * (path[i + 1] - path[i]) for i in range(len(path) - 1)]
    along = np.vstack(seg)
    assert np.all(_worst_without_one(placed, along) < sc.planning.eps_max)
    assert np.all(PEF(placed).at(along).tau < sc.planning.eps_max)  # tau_1 agrees


def test_negative_control_redundancy_0_placement_breaks_with_a_marker_blocked(docks):
    sc, res = docks[0]
    placed = placement.scenario_with_markers(sc, res)
    pts = cover_points(sc)
    assert np.all(PEF(placed, redundancy=0).at(pts).tau < sc.planning.eps_max)
    assert np.any(_worst_without_one(placed, pts) >= sc.planning.eps_max)


def test_placement_rejects_unsupported_redundancy():
    sc = _with_r(scenarios.load("paper-docks"), 2)
    with pytest.raises(scenarios.PlanningError, match="redundancy.*2"):
        placement.place(sc, time_limit=5)
