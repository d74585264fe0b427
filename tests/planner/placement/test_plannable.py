"""place_plannable: the layout is planned for every task, the cover tightened until it plans."""

from __future__ import annotations

import numpy as np

import scenarios
from planner.pef.map import PEF
from planner.placement import plannable
from planner.placement.placement import scenario_with_markers
from planner.placement.sites import cover_points
from planner.plan import plan_task


def test_paper_docks_layout_plans_every_task():
    sc = scenarios.load("paper-docks")
    pp = plannable.place_plannable(sc, time_limit=20)
    assert pp.checked and pp.unplanned == ()
    placed = scenario_with_markers(sc, pp.result)
    # independently: every task plans on the placed markers, and the cover holds its target
    for i in range(len(sc.tasks)):
        plan = plan_task(placed, i)
        assert max(f.predicted_tau for f in plan.schedule.fixes) < sc.planning.eps_max
    assert np.all(PEF(placed).at(cover_points(sc)).tau < pp.target)


def test_tightens_until_the_planner_accepts(monkeypatch):
    # The planner is replaced by one that refuses every layout whose cover target is above
    # 0.8 eps_max: the loop must try the margins in order and stop at the first accepted one.
    sc = scenarios.load("paper-docks")
    targets = []
    real_place = plannable.place

    def place(scenario, eps_max, **kw):
        targets.append(eps_max)
        return real_place(scenario, eps_max=eps_max, **kw)

    monkeypatch.setattr(plannable, "place", place)
    monkeypatch.setattr(plannable, "_unplanned",
                        lambda s, progress=None: ((("A->B: refused",), True)
                                                  if targets[-1] > 0.8 * sc.planning.eps_max + 1e-12 else ((), True)))
    pp = plannable.place_plannable(sc, time_limit=20)
    eps = sc.planning.eps_max
    np.testing.assert_allclose(targets, [eps, 0.9 * eps, 0.8 * eps])
    assert pp.target == targets[-1] and pp.unplanned == ()


def test_reports_tasks_that_never_plan(monkeypatch):
    # negative control of the loop: a planner that refuses everything leaves the last layout
    # with its reason, after every margin was tried
    sc = scenarios.load("paper-docks")
    monkeypatch.setattr(plannable, "_unplanned", lambda s, progress=None: (("A->B: refused",), True))
    pp = plannable.place_plannable(sc, time_limit=20, tighten=(0.0, 0.25))
    assert pp.unplanned == ("A->B: refused",)
    assert np.isclose(pp.target, 0.75 * sc.planning.eps_max)


def test_stops_where_no_layout_mends_the_refusal(monkeypatch):
    """A task refused on the body's clearance with no estimate term to gain is not tightened for.

    Against the control above (same refusal, mendable: every margin tried), one cover only.
    """
    sc = scenarios.load("paper-docks")
    targets = []
    real_place = plannable.place

    def place(scenario, eps_max, **kw):
        targets.append(eps_max)
        return real_place(scenario, eps_max=eps_max, **kw)

    lines = []
    monkeypatch.setattr(plannable, "place", place)
    monkeypatch.setattr(plannable, "_unplanned", lambda s, progress=None: (("A->B: passes 0.348 m",), False))
    pp = plannable.place_plannable(sc, time_limit=20, tighten=(0.0, 0.25), progress=lines.append)
    assert targets == [sc.planning.eps_max]
    assert pp.unplanned == ("A->B: passes 0.348 m",)
    assert "no layout of markers clears the body there" in lines[-1]
