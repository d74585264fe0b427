"""Candidate routes through a route network (paper fig. 7).

The network is an undirected graph: nodes at fixed positions, straight segments between
them, edge length = Euclidean distance. Between two docks we enumerate every simple path
when there are few (the paper's small networks), else the k shortest simple paths by
length (Yen's algorithm).
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from scenarios.errors import PlanningError
from scenarios.schema import RouteNetwork

# Networks with at most this many simple paths between the docks are enumerated whole.
MAX_ALL_PATHS = 200
# Depth-first enumeration gives up (and Yen takes over) after this many node visits.
_DFS_BUDGET = 200_000


@dataclass
class RouteGraph:
    """An undirected route graph.

    Attributes
    ----------
    pos : dict[str, tuple[float, float]]
        Node positions [m].
    adj : dict[str, dict[str, float]]
        Neighbours of each node with the segment length [m].
    traffic : dict[frozenset, float]
        Traffic density per segment (missing = 0).
    """

    pos: dict[str, tuple[float, float]]
    adj: dict[str, dict[str, float]] = field(default_factory=dict)
    traffic: dict[frozenset, float] = field(default_factory=dict)

    def add_segment(self, a: str, b: str, traffic: float = 0.0) -> None:
        """Join nodes ``a`` and ``b`` by a straight segment with the given traffic density."""
        length = math.dist(self.pos[a], self.pos[b])
        self.adj.setdefault(a, {})[b] = length
        self.adj.setdefault(b, {})[a] = length
        self.traffic[frozenset((a, b))] = traffic

    def polyline(self, nodes: list[str]) -> np.ndarray:
        """Positions of a node sequence, shape (n, 2) [m]."""
        return np.array([self.pos[n] for n in nodes], dtype=float)

    def segment_traffic(self, nodes: list[str]) -> list[float]:
        """Traffic density of each segment of a node sequence, length n - 1."""
        return [self.traffic.get(frozenset((a, b)), 0.0) for a, b in zip(nodes[:-1], nodes[1:], strict=True)]

    def path_length(self, nodes: list[str]) -> float:
        """Length [m] of a node sequence along its segments."""
        return sum(self.adj[a][b] for a, b in zip(nodes[:-1], nodes[1:], strict=True))


def build_graph(network: RouteNetwork) -> RouteGraph:
    """Build the :class:`RouteGraph` of the scenario's route network."""
    g = RouteGraph(pos=dict(network.nodes), adj={n: {} for n in network.nodes})
    for a, b in network.segments:
        g.add_segment(a, b, network.traffic_of(a, b))
    return g


def attach(graph: RouteGraph, name: str, position: tuple[float, float],
           segment_ok: Callable[[np.ndarray, np.ndarray], bool]) -> None:
    """Add a dock that is not a network node, joined to the nearest node it can reach.

    Parameters
    ----------
    graph : RouteGraph
        Modified in place.
    name : str
        Dock name (becomes a node).
    position : tuple[float, float]
        Dock position [m].
    segment_ok : callable
        ``segment_ok(a (2,), b (2,)) -> bool``: whether the robot can drive straight from a
        to b (clear of obstacles).

    Raises
    ------
    PlanningError
        If no node can be reached in a straight line ("unreachable dock").
    """
    if name in graph.pos:
        return
    p = np.asarray(position, float)
    for node in sorted(graph.pos, key=lambda n: math.dist(graph.pos[n], position)):
        if segment_ok(p, np.asarray(graph.pos[node], float)):
            graph.pos[name] = (float(p[0]), float(p[1]))
            graph.adj[name] = {}
            graph.add_segment(name, node)
            return
    raise PlanningError(f"unreachable dock {name!r} at ({p[0]:g}, {p[1]:g}): "
                        "no route-network node is in straight, obstacle-free reach")


def all_simple_paths(graph: RouteGraph, start: str, goal: str,
                     limit: int = MAX_ALL_PATHS) -> list[list[str]] | None:
    """Every simple path from ``start`` to ``goal``, or None if there are more than ``limit``.

    Depth-first, neighbours in name order (deterministic). Also returns None when the search
    exceeds a fixed visit budget, so a huge network never stalls here.
    """
    paths: list[list[str]] = []
    path, on_path = [start], {start}
    stack = [iter(sorted(graph.adj[start]))]
    visits = 0
    while stack:
        nxt = next(stack[-1], None)
        if nxt is None:
            stack.pop()
            on_path.discard(path.pop())
            continue
        visits += 1
        if visits > _DFS_BUDGET:
            return None
        if nxt in on_path:
            continue
        if nxt == goal:
            paths.append([*path, goal])
            if len(paths) > limit:
                return None
            continue
        path.append(nxt)
        on_path.add(nxt)
        stack.append(iter(sorted(graph.adj[nxt])))
    return paths


def _dijkstra(graph: RouteGraph, start: str, goal: str, banned_nodes: set[str],
              banned_edges: set[tuple[str, str]]) -> tuple[float, list[str]] | None:
    dist = {start: 0.0}
    prev: dict[str, str] = {}
    heap = [(0.0, start)]
    done: set[str] = set()
    while heap:
        d, u = heapq.heappop(heap)
        if u in done:
            continue
        if u == goal:
            path = [goal]
            while path[-1] != start:
                path.append(prev[path[-1]])
            return d, path[::-1]
        done.add(u)
        for v, w in graph.adj[u].items():
            if v in banned_nodes or (u, v) in banned_edges:
                continue
            nd = d + w
            if nd < dist.get(v, math.inf):
                dist[v] = nd
                prev[v] = u
                heapq.heappush(heap, (nd, v))
    return None


def k_shortest_paths(graph: RouteGraph, start: str, goal: str, k: int) -> list[list[str]]:
    """Find the ``k`` shortest simple paths by length (Yen 1971), shortest first.

    Returns fewer when the graph has fewer simple paths.
    """
    first = _dijkstra(graph, start, goal, set(), set())
    if first is None:
        return []
    found = [first[1]]
    found_set = {tuple(first[1])}
    heap: list[tuple[float, tuple[str, ...]]] = []
    while len(found) < k:
        last = found[-1]
        for i in range(len(last) - 1):
            spur, root = last[i], last[: i + 1]
            banned_edges = set()
            for p in found:
                if p[: i + 1] == root:
                    banned_edges.add((p[i], p[i + 1]))
                    banned_edges.add((p[i + 1], p[i]))
            res = _dijkstra(graph, spur, goal, set(root[:-1]), banned_edges)
            if res is None:
                continue
            cand = tuple(root[:-1] + res[1])
            if cand not in found_set:
                found_set.add(cand)
                heapq.heappush(heap, (graph.path_length(list(cand)), cand))
        while heap and list(heap[0][1]) in found:
            heapq.heappop(heap)
        if not heap:
            break
        found.append(list(heapq.heappop(heap)[1]))
    return found


def candidate_routes(graph: RouteGraph, start: str, goal: str, k: int = 20,
                     limit: int = MAX_ALL_PATHS) -> tuple[list[list[str]], str]:
    """Candidate node sequences from ``start`` to ``goal``.

    Parameters
    ----------
    graph : RouteGraph
    start, goal : str
        Node names.
    k : int
        How many shortest paths to keep when the network is too large to enumerate.
    limit : int
        Enumerate all simple paths when there are at most this many.

    Returns
    -------
    routes : list of list of str
        Sorted by length, then by node names.
    method : str
        ``"all simple paths"`` or ``"k shortest (Yen)"``.

    Raises
    ------
    PlanningError
        If the goal cannot be reached from the start.
    """
    paths = all_simple_paths(graph, start, goal, limit)
    method = "all simple paths"
    if paths is None:
        paths, method = k_shortest_paths(graph, start, goal, k), f"{k} shortest (Yen)"
    if not paths:
        raise PlanningError(f"no route from {start!r} to {goal!r}: the route network does not connect them")
    paths.sort(key=lambda p: (round(graph.path_length(p), 9), p))
    return paths, method
