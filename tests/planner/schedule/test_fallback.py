"""A redundancy-1 schedule survives any one blocked marker at any fix, for the moving robot.

At every fix of ``warehouse-reflectors`` (flat reflectors placed for redundancy 1), each
scheduled marker either has a fallback whose promise, plus the drift until the next fix
completes, stays under eps_max, or the fix before it covers the plan until then (the fix can be
lost). The drift is read off the schedule's own error curve at the path's vertices between the
two completions (a lower bound of the drift over the stretch), and each fallback's promise is recomputed with
:func:`planner.schedule.promise.predict`. Negative control: fallbacks chosen as before the fix,
by static PEF alone without the drift to the next fix (``margin`` left out), break it.
"""

from __future__ import annotations

import numpy as np
import pytest

import scenarios
from planner.pef import map as pef_map
from planner.pef import visibility
from planner.pef.sight import SightRule
from planner.plan import plan_task
from planner.schedule import promise
from planner.schedule import schedule as schedule_module
from planner.schedule.fallback import fallbacks


def _violations(sc, plan) -> list[tuple[int, int, float]]:
    eps = sc.planning.eps_max
    S, fixes = plan.schedule, plan.schedule.fixes
    bad = []
    # a fix completes where its last measurement is taken (straight travel: arc = chord)
    done = [f.s + float(np.hypot(*(np.array(f.poses[-1]) - f.position))) for f in fixes]
    for i, f in enumerate(fixes[:-1]):
        # fix i's area is in force from its completion until the next fix completes
        window = (S.s > done[i]) & (S.s <= done[i + 1])
        drift = float(np.max(S.predicted_error[window] - f.predicted_tau, initial=0.0))
        for q, (sub, tau) in enumerate(zip(f.fallbacks, f.fallback_tau, strict=True)):
            if sub and not tau + drift < eps:
                bad.append((i, q, tau + drift))
    return bad


@pytest.fixture(scope="module")
def reflectors():
    return scenarios.load("warehouse-reflectors")


def test_every_fallback_keeps_its_promise_until_the_next_fix(reflectors):
    sc = reflectors
    plan = plan_task(sc, 0)
    fixes = plan.schedule.fixes
    assert sc.planning.redundancy == 1
    assert _violations(sc, plan) == []
    present = [(i, q) for i, f in enumerate(fixes) for q, sub in enumerate(f.fallbacks) if sub]
    assert len(present) > 0.8 * 2 * len(fixes)
    # the promises are the construction's, recomputed fix by fix
    pick = present[:: max(1, len(present) // 25)]
    pred, _, _ = promise.predict(sc, plan.path, plan.schedule.speed,
                                 np.array([fixes[i].s for i, _ in pick]), [fixes[i].fallbacks[q] for i, q in pick],
                                 np.array([fixes[i].estimate for i, _ in pick]))
    np.testing.assert_allclose(pred, [fixes[i].fallback_tau[q] for i, q in pick], rtol=1e-9)


def test_fallbacks_by_static_pef_alone_break_it(reflectors, monkeypatch):
    # negative control: the choice of the previous version (no drift to the next fix)
    def without_margin(*args, **kwargs):
        return fallbacks(*args[:8])

    monkeypatch.setattr(schedule_module, "fallbacks", without_margin)
    # on the map and with the search of that version (a line-of-sight margin of eps_max + 0.12 m,
    # the search for eps_max itself): with the map's smaller margin of now, more markers are seen
    # and the static choice happens to find fallbacks with room for the drift
    rule = lambda scenario, widen=0.0: SightRule(margin=scenario.planning.eps_max + 0.12 + widen)  # noqa: E731
    monkeypatch.setattr(visibility, "scenario_sight_rule", rule)
    monkeypatch.setattr(pef_map, "scenario_sight_rule", rule)
    monkeypatch.setattr(schedule_module, "rungs", lambda eps_max, floor: [eps_max])
    sc = reflectors
    plan = plan_task(sc, 0)
    assert len(_violations(sc, plan)) >= 3
