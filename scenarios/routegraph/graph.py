"""Route graph files into a :class:`~scenarios.route_network.RouteNetwork`.

A graph file holds nodes with ids and positions and *directed* edges between them. The
route network is undirected: every directed edge between the same two nodes (typically a
pair of opposite edges, one per direction) becomes one segment that keeps all their ids,
directions and properties (:class:`~scenarios.route_network.RouteEdge`). Segments are straight
between their nodes, as Nav2's route server drives them (an edge's own geometry is not used).

The file's format is told by its content (:mod:`scenarios.routegraph.file`): a GeoJSON
``FeatureCollection`` is a Nav2 route graph (:mod:`scenarios.routegraph.nav2`), an object with
``layouts`` a VDA LIF file (:mod:`scenarios.routegraph.lif`); both build on the elements here.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from scenarios.errors import ScenarioError
from scenarios.fields import show
from scenarios.route_network import RouteEdge, RouteNetwork
from scenarios.routegraph.clearance import obstacle_geometry, segment_conflict
from scenarios.schema import Obstacle, Workspace


@dataclass(frozen=True)
class GraphNode:
    """A node read from a graph file.

    ``id``, ``position`` (x, y) [m] in the scenario's frame, its other ``properties`` and
    ``key``, where it is in the file (for messages).
    """

    id: str
    position: tuple[float, float]
    properties: dict = field(default_factory=dict)
    key: str = ""


@dataclass(frozen=True)
class GraphEdge:
    """A directed edge read from a graph file.

    ``id``, ``start`` and ``end`` node ids, its other ``properties`` and ``key``, where it is
    in the file (for messages).
    """

    id: str
    start: str
    end: str
    properties: dict = field(default_factory=dict)
    key: str = ""
    repeated_ok: bool = False
    """The file's format lets this edge share its id with another (see :mod:`.nav2`)."""


def fail(file: str, key: str, expected: str, value: Any = None, *, with_value: bool = True) -> None:
    """Raise the one-line error ``file: key: expected, got value``."""
    got = f", got {show(value)}" if with_value else ""
    raise ScenarioError(f"{file}: {key}: {expected}{got}")


def graph_id(file: str, key: str, value: Any) -> str:
    """Return an id as a node name: a JSON integer (Nav2) or string (LIF), as a string."""
    if isinstance(value, bool) or not isinstance(value, (int, str)) or value == "":
        fail(file, key, "expected an integer or a non-empty string id", value)
    return str(value)


def finite_xy(file: str, key: str, value: Any, what: str) -> tuple[float, float]:
    """Two finite numbers (x, y) [m] (a GeoJSON position may carry a third, z, which is dropped)."""
    ok = isinstance(value, (list, tuple)) and len(value) in (2, 3) and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)
    if not ok:
        fail(file, key, f"expected {what}", value)
    return float(value[0]), float(value[1])


def build_network(nodes: Sequence[GraphNode], edges: Sequence[GraphEdge], shown: str, *,
                  workspace: Workspace, obstacles: Sequence[Obstacle], radius: float,
                  known_elsewhere: Callable[[str], bool] = lambda _: False) -> RouteNetwork:
    """Merge directed edges into undirected segments and check them against the obstacles.

    Parameters
    ----------
    nodes, edges : sequences of GraphNode, GraphEdge
        As read from the file.
    shown : str
        The file, for messages.
    workspace : Workspace
        Every node must lie inside it.
    obstacles : sequence of Obstacle
    radius : float
        Robot radius [m]; a segment closer to an obstacle is kept but marked inadmissible.
    known_elsewhere : callable
        ``known_elsewhere(node_id)``: the node exists outside the graph read (a LIF edge to
        another layout); such edges are left out, not errors.

    Raises
    ------
    ScenarioError
        Duplicate ids (edge ids marked ``repeated_ok`` excepted), a node outside the workspace, an edge
        to an unknown node or from a node to itself.
    """
    pos: dict[str, tuple[float, float]] = {}
    props: dict[str, dict] = {}
    for n in nodes:
        if n.id in pos:
            fail(shown, n.key, "expected a unique node id", n.id)
        if not workspace.contains(n.position):
            x0, y0, x1, y1 = workspace.bounds
            fail(shown, n.key, f"expected a node inside the workspace [{x0:g}, {x1:g}] x [{y0:g}, {y1:g}] m "
                               f"(node {n.id})", list(n.position))
        pos[n.id], props[n.id] = n.position, dict(n.properties)
    groups: dict[frozenset, list[GraphEdge]] = {}
    seen: set[str] = set()
    for e in edges:
        if e.id in seen and not e.repeated_ok:
            fail(shown, e.key, "expected a unique edge id", e.id)
        seen.add(e.id)
        for end, name in ((e.start, "start"), (e.end, "end")):
            if end not in pos and not known_elsewhere(end):
                fail(shown, e.key, f"expected the {name} of edge {e.id} to be a node id (no node {end})", end)
        if e.start not in pos or e.end not in pos:
            continue  # a transition to another layout: not drivable on this one
        if e.start == e.end:
            fail(shown, e.key, f"expected edge {e.id} to join two different nodes", e.start)
        groups.setdefault(frozenset((e.start, e.end)), []).append(e)
    geoms = [obstacle_geometry(o) for o in obstacles]
    segments, route_edges = [], []
    for group in groups.values():
        a, b = group[0].start, group[0].end
        why = segment_conflict(pos[a], pos[b], obstacles, radius, geoms)
        segments.append((a, b))
        route_edges.append(RouteEdge(ids=tuple(e.id for e in group), ends=tuple((e.start, e.end) for e in group),
                                     properties=tuple(dict(e.properties) for e in group), why_not=why))
    return RouteNetwork(nodes=pos, segments=tuple(segments), edges=tuple(route_edges),
                        node_ids={k: k for k in pos}, node_properties=props, source=shown)
