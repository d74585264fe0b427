"""Candidate routes through a route network (paper fig. 7).

The network is an undirected graph: nodes at fixed positions, straight segments between
them, edge length = Euclidean distance. Between two docks we enumerate every simple path
when there are few (the paper's small networks), else the k shortest simple paths by
length (Yen's algorithm). The graph and both searches are networkx's.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable

import numpy as np

from planner.routes.paths import Graph, NoPath
from planner.routes.paths import all_simple_paths as _all_simple_paths
from planner.routes.paths import shortest_simple_paths as _shortest_simple_paths
from scenarios.errors import PlanningError
from scenarios.route_network import RouteNetwork

# Networks with at most this many simple paths between the docks are enumerated whole.
MAX_ALL_PATHS = 200


class RouteGraph:
    """An undirected route graph: a :class:`planner.routes.paths.Graph` with node positions.

    Edges carry ``weight`` (the segment's length [m]), ``traffic`` (its density, 0 if
    missing) and ``why_not`` (why it may not be driven, "" if it may; see
    :class:`scenarios.route_network.RouteEdge`). Searches use only drivable edges (:attr:`usable`).

    Parameters
    ----------
    pos : dict[str, tuple[float, float]]
        Node positions [m].
    """

    def __init__(self, pos: dict[str, tuple[float, float]]):
        self.pos = dict(pos)
        self.g = Graph()
        for n in self.pos:
            self.g.add_node(n)

    @property
    def adj(self) -> dict[str, dict[str, float]]:
        """Neighbours of each node with the segment length [m] (a fresh dict)."""
        return self.g.weights()

    def add_segment(self, a: str, b: str, traffic: float = 0.0, why_not: str = "", label: str = "") -> None:
        """Join nodes ``a`` and ``b`` by a straight segment with the given traffic density.

        ``why_not`` marks a segment that may not be driven (kept to explain a failed search);
        ``label`` names it in messages (default ``"a-b"``).
        """
        self.g.add_edge(a, b, weight=math.dist(self.pos[a], self.pos[b]), traffic=traffic,
                        why_not=why_not, label=label or f"{a}-{b}")

    @property
    def usable(self) -> dict[str, dict[str, float]]:
        """Segment lengths ``{u: {v: m}}`` without the segments that may not be driven.

        Every node, each neighbour list in the graph's order (the searches' tie-breaks).
        """
        return self.g.weights(keep=lambda d: not d["why_not"])

    def polyline(self, nodes: list[str]) -> np.ndarray:
        """Positions of a node sequence, shape (n, 2) [m]."""
        return np.array([self.pos[n] for n in nodes], dtype=float)

    def segment_traffic(self, nodes: list[str]) -> list[float]:
        """Traffic density of each segment of a node sequence, length n - 1."""
        return [self.g.edge(a, b)["traffic"] for a, b in zip(nodes[:-1], nodes[1:], strict=True)]

    def path_length(self, nodes: list[str]) -> float:
        """Length [m] of a node sequence along its segments."""
        return sum(self.g.edge(a, b)["weight"] for a, b in zip(nodes[:-1], nodes[1:], strict=True))


def build_graph(network: RouteNetwork) -> RouteGraph:
    """Build the :class:`RouteGraph` of the scenario's route network."""
    g = RouteGraph(pos=dict(network.nodes))
    for i, (a, b) in enumerate(network.segments):
        g.add_segment(a, b, network.traffic_of(a, b), network.why_not(i), network.edge_label(i))
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
            graph.g.add_node(name)
            graph.add_segment(name, node)
            return
    raise PlanningError(f"unreachable dock {name!r} at ({p[0]:g}, {p[1]:g}): "
                        "no route-network node is in straight, obstacle-free reach")


def all_simple_paths(graph: RouteGraph, start: str, goal: str,
                     limit: int = MAX_ALL_PATHS) -> list[list[str]] | None:
    """Every simple path from ``start`` to ``goal``, or None if there are more than ``limit``.

    A depth-first enumeration (networkx's), stopped after ``limit + 1`` paths so a huge network
    never stalls here.
    """
    paths = list(itertools.islice(_all_simple_paths(graph.usable, start, goal), limit + 1))
    return None if len(paths) > limit else paths


def k_shortest_paths(graph: RouteGraph, start: str, goal: str, k: int) -> list[list[str]]:
    """Find the ``k`` shortest simple paths by length (Yen, as networkx), shortest first.

    Returns fewer when the graph has fewer simple paths.
    """
    try:
        return list(itertools.islice(_shortest_simple_paths(graph.usable, start, goal), k))
    except NoPath:
        return []


def candidate_routes(graph: RouteGraph, start: str, goal: str, k: int = 20,
                     limit: int = MAX_ALL_PATHS, names: tuple[str, str] | None = None) -> tuple[list[list[str]], str]:
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
    names : (str, str), optional
        Dock names of ``start`` and ``goal`` for messages, when they sit on nodes of other names.

    Returns
    -------
    routes : list of list of str
        Sorted by length, then by node names.
    method : str
        ``"all simple paths"`` or ``"k shortest (Yen)"``.

    Raises
    ------
    PlanningError
        If the goal cannot be reached from the start over drivable segments; when only
        inadmissible segments connect them, the message names those of the shortest such
        route and why each may not be driven.
    """
    paths = all_simple_paths(graph, start, goal, limit)
    method = "all simple paths"
    if paths is None:
        paths, method = k_shortest_paths(graph, start, goal, k), f"{k} shortest (Yen)"
    if not paths:
        raise _unconnected(graph, start, goal, names)
    paths.sort(key=lambda p: (round(graph.path_length(p), 9), p))
    return paths, method


def _unconnected(graph: RouteGraph, start: str, goal: str, names: tuple[str, str] | None) -> PlanningError:
    """Build the error for docks no drivable route joins, naming the inadmissible segments in the way."""
    if names is not None and names != (start, goal):
        what = f"from {names[0]!r} to {names[1]!r} (nodes {start} and {goal})"
    else:
        what = f"from {start!r} to {goal!r}"
    import networkx as nx  # here: its import costs 0.2 s, and only a failed search gets here

    try:
        through = nx.shortest_path(graph.g.to_networkx(), start, goal, weight="weight")
    except nx.NetworkXNoPath:
        return PlanningError(f"no route {what}: the route network does not connect them")
    blocked = [graph.g.edge(a, b) for a, b in zip(through[:-1], through[1:], strict=True)]
    blocked = [f"edge {e['label']}: {e['why_not']}" for e in blocked if e["why_not"]]
    return PlanningError(f"no admissible route {what}: the route network joins them only over inadmissible "
                         "segments; the shortest such route uses " + "; ".join(blocked))
