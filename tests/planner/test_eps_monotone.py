"""A looser requirement never plans worse (DESIGN §9 "Margins from the plan").

For ε_max growing over :data:`EPS`, on the same floor and markers:

- the set of admissible routes of every task never shrinks: a route is admissible when the one
  admissibility keeps τ under ε_max along it (:mod:`planner.routes.admissible`) and it has a
  measurement schedule (:func:`planner.schedule.schedule.make_schedule`);
- the promise of a route (its schedule's worst predicted error) never grows where its schedule
  was taken at speed (no fix slowed down); a
  schedule that had to slow down may give way to one at speed with a larger promise when ε_max
  grows (warehouse: 29.8 mm at 0.1, slowed, then 41.2 mm at 0.2, at speed: the paper's speed
  for accuracy; the ladder that never lets a promise grow drove paper-docks twice as long);
- the placement's count never grows.

All three are exact consequences of the construction, not statistics: the map's line of sight
does not depend on ε_max (:func:`planner.pef.sight.sight_rule`), τ is compared with ε_max, and a
schedule is searched on a fixed ladder of bounds (:func:`planner.schedule.schedule.rungs`) that
only grows with ε_max; every value of :data:`EPS` is a rung, so equality of promises is exact.
Negative control: the ε-dependent margin of before (ε_max + 0.12 m) put back by monkeypatch hides
markers as ε_max grows, and a route admissible at a tighter ε_max is lost at a looser one.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import scenarios
from planner.pef import map as pef_map
from planner.pef import visibility
from planner.pef.map import PEF
from planner.pef.sight import SightRule
from planner.routes.admissible import tau_along
from planner.routes.candidates import free_candidates, network_candidates
from planner.schedule.schedule import make_schedule
from planner.worlds import plannable_world
from scenarios.errors import PlanningError
from scenarios.worlds import SMALLEST_MAX_SIZE

EPS = (0.03, 0.05, 0.1, 0.2, 0.5, 1.0)
"""The ε_max values swept [m]."""


def with_eps(sc: scenarios.Scenario, eps: float) -> scenarios.Scenario:
    return dataclasses.replace(sc, planning=dataclasses.replace(sc.planning, eps_max=eps))


def small_world(index: int, seed: int = 45) -> scenarios.Scenario:
    """World ``index`` of ``pefsim worlds --seed 45 --max-size 12``, redrawn until it plans (ε_max set by the sweep).

    A world as first drawn may have no route with a fix anywhere (random-45-008: τ = ∞ on its
    one route at every ε_max), which would leave nothing to compare.
    """
    sc = plannable_world(seed, index, max_size=SMALLEST_MAX_SIZE).scenario
    return with_eps(sc, EPS[0])


def outcomes(sc: scenarios.Scenario, eps_values=EPS, tasks: int | None = None) -> dict[float, dict]:
    """``{eps: {(task, route key): (promise, taken at speed)}}`` of every admissible route (module docstring)."""
    out = {}
    for eps in eps_values:
        s = with_eps(sc, eps)
        pef = PEF(s)
        tau_fn = lambda p, pef=pef, s=s: tau_along(pef, p, s.planning.resolution, s.planning.eps_max)  # noqa: E731
        got = {}
        for t in list(s.tasks)[:tasks]:
            try:
                cands = (network_candidates(s, t.start, t.goal, tau_fn) if s.routes is not None
                         else free_candidates(s, t.start, t.goal, pef, tau_fn))
            except PlanningError:
                continue
            for c in cands:
                if not c.admissible:
                    continue
                key = (t.start, t.goal, c.polyline.round(6).tobytes())
                try:
                    sched = make_schedule(s, pef, c.path.points, c.speed)
                except PlanningError:
                    continue
                got[key] = (sched.worst, sched.slowdown_time == 0.0)
        out[eps] = got
    return out


def violations(res: dict[float, dict]) -> list[str]:
    """Return what breaks monotonicity between consecutive ε_max values."""
    bad = []
    eps = sorted(res)
    for a, b in zip(eps[:-1], eps[1:], strict=True):
        lost = set(res[a]) - set(res[b])
        if lost:
            bad.append(f"{len(lost)} admissible route(s) at eps {a:g} lost at {b:g}")
        for key in set(res[a]) & set(res[b]):
            (pa, fast), (pb, _) = res[a][key], res[b][key]
            if fast and pb > pa:
                bad.append(f"promise grew from {pa:.5g} m at eps {a:g} to {pb:.5g} m at {b:g}")
    return bad


def eps_margin(monkeypatch) -> None:
    """Put the margin of before back: ε_max + 0.12 m (the negative control)."""
    def rule(scenario, widen=0.0):
        return SightRule(margin=scenario.planning.eps_max + 0.12 + widen)
    monkeypatch.setattr(visibility, "scenario_sight_rule", rule)
    monkeypatch.setattr(pef_map, "scenario_sight_rule", rule)


FAST = (0,)
"""Random world of the fast tier, swept over :data:`FAST_EPS` (the rest, and the built-ins, are e2e)."""
FAST_EPS = (0.05, 1.0)


@pytest.mark.parametrize("index", FAST)
def test_looser_never_worse_small_world(index):
    sc = small_world(index)
    res = outcomes(sc, eps_values=FAST_EPS, tasks=1)
    assert any(res[e] for e in FAST_EPS), "no route admissible at any eps_max: the test would not test"
    assert violations(res) == []


@pytest.mark.e2e
def test_negative_control_eps_margin_fails(monkeypatch):
    """With the margin ε_max + 0.12 m back, a looser ε_max loses routes on a world where it plans."""
    eps_margin(monkeypatch)
    found = []
    for index in (0, 1, 2, 3):
        res = outcomes(small_world(index), eps_values=(0.05, 1.0), tasks=1)
        found += violations(res)
        if found:
            break
    assert found, "the ε-dependent margin broke nothing: the monotonicity test could not fail"


@pytest.mark.e2e
@pytest.mark.parametrize("name", ["warehouse", "paper-docks", *[f"random:{i}" for i in range(10)]])
def test_looser_never_worse(name):
    sc = small_world(int(name.split(":")[1])) if name.startswith("random:") else scenarios.load(name)
    res = outcomes(sc)
    assert any(res[e] for e in EPS)
    assert violations(res) == []


@pytest.mark.e2e
@pytest.mark.parametrize("name", ["warehouse", "paper-docks", *[f"random:{i}" for i in range(10)]])
def test_looser_never_more_reflectors(name):
    from planner.placement.plannable import place_plannable

    sc = small_world(int(name.split(":")[1])) if name.startswith("random:") else scenarios.load(name)
    counts = []
    for eps in EPS:
        r = place_plannable(with_eps(sc, eps)).result
        counts.append(r.count if not len(r.uncovered) else np.inf)
    assert all(b <= a for a, b in zip(counts[:-1], counts[1:], strict=True)), counts
