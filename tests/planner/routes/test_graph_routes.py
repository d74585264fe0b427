"""Planning over imported route graphs: inadmissible edges are not driven, and are named when needed."""

from __future__ import annotations

import numpy as np
import pytest

import scenarios
from planner.pef.map import PEF
from planner.plan import plan_route
from planner.routes.edges import segment_reports
from scenarios import PlanningError
from tests.scenarios.graphfiles import NODE_DOCKS, TASK, nav2_graph, scenario_text, write


def load(tmp_path, graph, docks=NODE_DOCKS):
    write(tmp_path / "graph.geojson", graph)
    path = tmp_path / "s.toml"
    path.write_text(scenario_text('file = "graph.geojson"', docks, extra=TASK), encoding="utf-8")
    return scenarios.load(path)


def test_routes_avoid_the_inadmissible_edge(tmp_path):
    sc = load(tmp_path, nav2_graph())
    p = plan_route(sc, "A", "B", schedule=False)
    routes = [c.nodes for c in p.candidates]
    assert ("0", "1", "2") in routes and ("0", "3", "4", "5", "2") in routes
    assert not any(("4", "1") in zip(r[:-1], r[1:], strict=True) or ("1", "4") in zip(r[:-1], r[1:], strict=True)
                   for r in routes)
    # routes start and end at the docks' nodes
    np.testing.assert_allclose(p.path[0], (2.0, 2.0))
    np.testing.assert_allclose(p.path[-1], (18.0, 2.0))


def test_plan_only_through_an_inadmissible_edge_says_why(tmp_path):
    g = nav2_graph()
    # keep only 4 -> 1 (through the box) and the south edges: dock A on node 4 reaches B only over 17
    g["features"] = [f for f in g["features"] if f["properties"].get("id") in (0, 1, 2, 3, 4, 5, 10, 11, 12, 17)
                     and f["geometry"]["type"] != "Polygon"]
    docks = '[[docks]]\nname = "A"\nnode = "4"\n[[docks]]\nname = "B"\nnode = "2"\n'
    sc = load(tmp_path, g, docks)
    with pytest.raises(PlanningError, match=r"^no admissible route from 'A' to 'B' \(nodes 4 and 2\): the route "
                                            r"network joins them only over inadmissible segments; the shortest "
                                            r"such route uses edge 17 \(4-1\): crosses obstacles\[0\]$"):
        plan_route(sc, "A", "B", schedule=False)


def test_segment_reports(tmp_path):
    sc = load(tmp_path, nav2_graph())
    pef = PEF(sc)
    reps = segment_reports(sc, pef)
    assert len(reps) == len(sc.routes.segments)
    for r in reps:
        a, b = sc.routes.segments[r.index]
        np.testing.assert_allclose(r.points[[0, -1]], [sc.routes.nodes[a], sc.routes.nodes[b]])
        tau = pef.at(r.points).tau
        assert r.max_tau == tau.max()
        assert r.min_visible == pef.visible(r.points).sum(axis=1).min()
        if np.isfinite(tau).all():
            assert tau.min() <= r.mean_tau <= tau.max()
    through = reps[6]  # 4 -> 1 through the box: no fix inside it
    assert through.why_not == "crosses obstacles[0]" and through.max_tau == np.inf and through.min_visible == 0
    assert all(r.admissible for r in reps[:6])
