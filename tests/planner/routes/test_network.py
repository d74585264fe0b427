"""Route network: simple-path enumeration and Yen's k shortest paths against brute force."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from planner.routes import network
from scenarios.errors import PlanningError
from scenarios.route_network import RouteNetwork


def random_network(rng: np.random.Generator, n: int, p: float) -> RouteNetwork:
    nodes = {f"v{i}": (float(x), float(y)) for i, (x, y) in enumerate(rng.uniform(0, 10, (n, 2)))}
    names = list(nodes)
    segs = tuple((a, b) for a, b in itertools.combinations(names, 2) if rng.random() < p)
    traffic = {f"{a}-{b}": float(rng.uniform()) for a, b in segs if rng.random() < 0.5}
    return RouteNetwork(nodes=nodes, segments=segs, traffic=traffic)


def brute_force_paths(net: RouteNetwork, start: str, goal: str) -> set[tuple[str, ...]]:
    """Every node sequence start..goal without repeats whose consecutive pairs are segments."""
    edges = {frozenset(s) for s in net.segments}
    inner = [n for n in net.nodes if n not in (start, goal)]
    out = set()
    for k in range(len(inner) + 1):
        for mid in itertools.permutations(inner, k):
            seq = (start, *mid, goal)
            if all(frozenset(p) in edges for p in zip(seq[:-1], seq[1:], strict=False)):
                out.add(seq)
    return out


def length(net: RouteNetwork, seq) -> float:
    return sum(math.dist(net.nodes[a], net.nodes[b]) for a, b in zip(seq[:-1], seq[1:], strict=False))


@pytest.mark.parametrize("seed", range(6))
def test_all_simple_paths_match_brute_force(seed):
    rng = np.random.default_rng(seed)
    net = random_network(rng, 7, 0.45)
    g = network.build_graph(net)
    got = network.all_simple_paths(g, "v0", "v1", limit=10_000)
    assert got is not None
    assert len(got) == len({tuple(p) for p in got})  # no duplicates
    assert {tuple(p) for p in got} == brute_force_paths(net, "v0", "v1")


@pytest.mark.parametrize("seed", range(6))
def test_yen_k_shortest_match_brute_force(seed):
    rng = np.random.default_rng(100 + seed)
    net = random_network(rng, 8, 0.5)
    g = network.build_graph(net)
    brute = sorted(length(net, p) for p in brute_force_paths(net, "v0", "v1"))
    k = 7
    got = network.k_shortest_paths(g, "v0", "v1", k)
    assert len(got) == min(k, len(brute))
    assert len({tuple(p) for p in got}) == len(got)
    for p in got:  # simple and made of segments
        assert len(set(p)) == len(p) and p[0] == "v0" and p[-1] == "v1"
    np.testing.assert_allclose([length(net, p) for p in got], brute[:k], rtol=1e-12)


def test_too_many_paths_falls_back_to_yen():
    # A complete graph on 9 nodes has 13700 simple paths between two nodes: above the limit.
    rng = np.random.default_rng(3)
    nodes = {f"v{i}": (float(x), float(y)) for i, (x, y) in enumerate(rng.uniform(0, 10, (9, 2)))}
    net = RouteNetwork(nodes=nodes, segments=tuple(itertools.combinations(nodes, 2)))
    g = network.build_graph(net)
    assert network.all_simple_paths(g, "v0", "v1", limit=200) is None
    routes, method = network.candidate_routes(g, "v0", "v1", k=5)
    assert "Yen" in method and len(routes) == 5
    assert routes[0] == ["v0", "v1"]  # the direct segment is the shortest (triangle inequality)


def test_segment_traffic_and_lengths():
    net = RouteNetwork(nodes={"a": (0.0, 0.0), "b": (3.0, 4.0), "c": (3.0, 0.0)},
                       segments=(("a", "b"), ("b", "c")), traffic={"c-b": 0.4})
    g = network.build_graph(net)
    assert g.path_length(["a", "b", "c"]) == pytest.approx(9.0)
    assert g.segment_traffic(["a", "b", "c"]) == [0.0, 0.4]


def test_attach_dock_to_nearest_reachable_node():
    net = RouteNetwork(nodes={"a": (0.0, 0.0), "b": (10.0, 0.0)}, segments=(("a", "b"),))
    g = network.build_graph(net)
    # "a" is nearest but blocked; the dock must be joined to "b".
    network.attach(g, "D", (2.0, 1.0), lambda p, q: q[0] > 5)
    assert set(g.adj["D"]) == {"b"}
    assert g.adj["D"]["b"] == pytest.approx(math.dist((2, 1), (10, 0)))
    with pytest.raises(PlanningError, match="unreachable dock 'E'"):
        network.attach(g, "E", (5.0, 5.0), lambda p, q: False)


def test_disconnected_goal_raises():
    net = RouteNetwork(nodes={"a": (0.0, 0.0), "b": (1.0, 0.0), "c": (5.0, 5.0), "d": (6.0, 5.0)},
                       segments=(("a", "b"), ("c", "d")))
    with pytest.raises(PlanningError, match="does not connect"):
        network.candidate_routes(network.build_graph(net), "a", "d")


def test_usable_graph_keeps_the_neighbour_order_and_drops_inadmissible_segments():
    rng = np.random.default_rng(4)
    g = network.build_graph(random_network(rng, 9, 0.5))
    edges = g.g.edges()
    for a, b in edges[::3]:  # re-added segments keep their place, the last why_not counts
        g.add_segment(a, b, why_not="one way")
    g.add_segment(*edges[3], why_not="")
    network.attach(g, "D", (5.0, 5.0), lambda p, q: True)
    u = g.usable
    kept = [(a, b) for a, b in g.g.edges() if not g.g.edge(a, b)["why_not"]]
    assert 0 < len(kept) < len(edges) and sum(map(len, u.values())) == 2 * len(kept)
    assert list(u) == list(g.pos)
    # a neighbour list is the graph's own, less the inadmissible segments: the searches' tie-break
    for n in g.pos:
        assert list(u[n]) == [m for m in g.g.adj[n] if not g.g.edge(n, m)["why_not"]]
    assert all(u[a][b] == g.g.edge(a, b)["weight"] == math.dist(g.pos[a], g.pos[b]) for a, b in kept)
