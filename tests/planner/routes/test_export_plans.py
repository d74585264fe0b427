"""``export`` and ``plan`` give a segment of the route graph one verdict.

Property (random small worlds of ``pefsim worlds``, seed 46): for every segment of the graph and
an ε_max just over the τ of its worst sample (where the bound over each sample's stretch
decides, :mod:`planner.pef.stretch`), the segment is admissible in ``export``'s segment reports
(:func:`planner.routes.edges.segment_reports`) exactly when ``plan``'s candidate route along it,
for a task between docks on its two nodes (judged by :func:`planner.plan.route_tau`), is admissible.
Whether that route also has a measurement schedule is ``plan``'s next question (the drift between
fixes needs room under ε_max; ``plan`` names it).

Negative control: ``plan`` judging by the samples' own τ (no bound over the stretch) calls
candidates admissible that ``export`` does not.
"""

from __future__ import annotations

import numpy as np
import pytest

import scenarios
from planner import plan as plan_module
from planner.pef.map import PEF
from planner.routes.admissible import stretch_widen
from planner.routes.candidates import network_candidates
from planner.routes.edges import segment_reports
from planner.worlds import world_rng
from scenarios.worlds import SMALLEST_MAX_SIZE, draw_world

WORLDS = (0, 2, 8, 9, 13)
"""gdop k = 4 with bearings, strips k = 4, parallelogram with bearings, gdop k = 3, strips k = 3."""


def world_data(index: int, eps: float = 1.0) -> dict:
    drawn = draw_world(world_rng(46, index), f"random-46-{index:03d}", max_size=SMALLEST_MAX_SIZE)
    drawn.data["planning"]["eps_max"] = eps
    return drawn.data


def on_segment(data: dict, a: str, b: str) -> scenarios.Scenario:
    """Return the world with docks P on node ``a`` and Q on node ``b`` and the one task P -> Q."""
    d = dict(data, docks=[{"name": "P", "node": a}, {"name": "Q", "node": b}], tasks=[{"from": "P", "to": "Q"}])
    return scenarios.from_dict(d, source="segment.toml")


def disagreements(index: int) -> tuple[int, list[str]]:
    """Return how many segments were compared, and those where export and plan disagree."""
    data = world_data(index)
    sc = scenarios.from_dict(data, source="world.toml")
    pef = PEF(sc)
    h = stretch_widen(sc.planning.resolution)
    compared, out = 0, []
    for r in segment_reports(sc, pef):
        worst = float(np.max(pef.at(r.points, h).tau))
        if not np.isfinite(worst):
            continue
        eps = worst * 1.005
        d = world_data(index, eps)
        s = scenarios.from_dict(d, source="world.toml")
        exported = segment_reports(s, PEF(s))[r.index]
        a, b = s.routes.segments[r.index]
        direct = np.array([s.routes.nodes[a], s.routes.nodes[b]], float)
        seg = on_segment(d, a, b)
        cands = [c for c in network_candidates(seg, "P", "Q", plan_module.route_tau(seg, PEF(seg)))
                 if len(c.polyline) == 2 and np.allclose(c.polyline, direct)]
        assert len(cands) == 1, "the direct route is a candidate"
        compared += 1
        if cands[0].admissible != exported.admissible:
            out.append(f"{a}-{b} at {eps * 1e3:.4g} mm: export {exported.why_not or 'admissible'}, "
                       f"plan {cands[0].why_not or 'admissible'}")
    return compared, out


@pytest.mark.parametrize("index", WORLDS)
def test_export_and_plan_give_a_segment_one_verdict(index):
    compared, out = disagreements(index)
    assert compared > 0
    assert out == []


def test_negative_control_plan_by_the_samples_own_tau_disagrees(monkeypatch):
    def sample_only(pef, points, spacing, target):
        return np.asarray(pef.at(np.asarray(points, float).reshape(-1, 2), widen=stretch_widen(spacing)).tau, float)

    monkeypatch.setattr(plan_module, "tau_along", sample_only)
    assert any(disagreements(i)[1] for i in WORLDS)
