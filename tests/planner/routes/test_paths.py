"""The route network's own graph searches against networkx's (same paths, same order)."""

from __future__ import annotations

import itertools

import networkx as nx
import numpy as np
import pytest

from planner.routes import paths


def random_graph(rng: np.random.Generator, n: int, p: float, integer: bool) -> paths.Graph:
    g = paths.Graph()
    names = [f"v{i}" for i in rng.permutation(n)]
    for a in names:
        g.add_node(a)
    for a, b in itertools.combinations(names, 2):
        if rng.random() < p:  # integer lengths: many equally long paths, the tie-breaks matter
            g.add_edge(b, a, weight=float(rng.integers(1, 4)) if integer else float(rng.uniform(1.0, 5.0)))
    return g


@pytest.mark.parametrize("seed", range(4))
def test_searches_return_networkx_paths_in_networkx_order(seed):
    rng = np.random.default_rng(seed)
    for trial in range(40):
        g = random_graph(rng, int(rng.integers(3, 11)), float(rng.uniform(0.2, 0.7)), integer=trial % 2 == 0)
        adj, nxg = g.weights(), g.to_networkx()
        assert all(list(nxg.adj[u]) == list(adj[u]) for u in adj)
        s, t = list(adj)[0], list(adj)[-1]
        ours = list(itertools.islice(paths.all_simple_paths(adj, s, t), 300))
        assert ours == list(itertools.islice(nx.all_simple_paths(nxg, s, t), 300))
        try:
            theirs = list(itertools.islice(nx.shortest_simple_paths(nxg, s, t, weight="weight"), 25))
        except nx.NetworkXNoPath:
            with pytest.raises(paths.NoPath):
                next(paths.shortest_simple_paths(adj, s, t))
            continue
        assert list(itertools.islice(paths.shortest_simple_paths(adj, s, t), 25)) == theirs


def test_yen_lists_paths_shortest_first_and_the_order_matters():
    g = paths.Graph()
    for a, b, w in [("a", "b", 1.0), ("b", "d", 1.0), ("a", "c", 1.0), ("c", "d", 1.0), ("a", "d", 3.0)]:
        g.add_edge(a, b, weight=w)
    found = list(paths.shortest_simple_paths(g.weights(), "a", "d"))
    assert found == [["a", "b", "d"], ["a", "c", "d"], ["a", "d"]]
    # negative control: the tie between the two 2 m paths follows the neighbour order
    g2 = paths.Graph()
    for a, b, w in [("a", "c", 1.0), ("c", "d", 1.0), ("a", "b", 1.0), ("b", "d", 1.0), ("a", "d", 3.0)]:
        g2.add_edge(a, b, weight=w)
    assert list(paths.shortest_simple_paths(g2.weights(), "a", "d"))[:2] == [["a", "c", "d"], ["a", "b", "d"]]
