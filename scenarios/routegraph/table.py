"""The ``[routes]`` table of a scenario, and docks placed on route-network nodes.

``[routes]`` is either hand-written (``nodes``, ``segments``) or read from a graph ``file``
(relative to the scenario file; a Nav2 route graph or a VDA LIF file, ``layout`` picks a LIF
layout); ``traffic`` works with both (keys ``"a-b"`` of node names, an imported node's name
being its id). A hand-written segment that crosses an obstacle or passes closer than
``robot.radius`` is an error; an imported one is kept but marked inadmissible (real graphs
graze walls), see :mod:`scenarios.routegraph.clearance`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from scenarios.fields import Table, show, show_path
from scenarios.files import unreadable_because
from scenarios.route_network import RouteEdge, RouteNetwork
from scenarios.routegraph.clearance import obstacle_geometry, segment_conflict
from scenarios.routegraph.file import read_graph_file
from scenarios.routegraph.graph import build_network
from scenarios.schema import Dock, Obstacle, Workspace

FreePoint = Callable[[Table, str, tuple, str], None]


def read_routes(t: Table, *, workspace: Workspace, obstacles: Sequence[Obstacle], radius: float,
                docks: Sequence[Dock], free_point: FreePoint, base_dir: Path | None) -> RouteNetwork:
    """Read a ``[routes]`` table into a :class:`RouteNetwork`.

    Parameters
    ----------
    t : Table
        The ``routes`` table.
    workspace, obstacles : Workspace, sequence of Obstacle
    radius : float
        Robot radius [m], the clearance every segment must keep from the obstacles.
    docks : sequence of Dock
        A dock given by its pose and named like a hand-written node must sit on it.
    free_point : callable
        ``free_point(table, key, value, what)`` fails unless the point is free.
    base_dir : Path or None
        Directory a relative ``file`` is taken from (the scenario file's; None: the current one).
    """
    if t.has("file"):
        net = _from_file(t, workspace, obstacles, radius, base_dir)
    else:
        net = _hand_written(t, workspace, obstacles, radius, docks, free_point)
    traffic_t = t.table("traffic", {})
    seg_keys = {f"{a}-{b}" for a, b in net.segments} | {f"{b}-{a}" for a, b in net.segments}
    traffic = {}
    for k in list(traffic_t.data):
        if k not in seg_keys:
            traffic_t.fail(traffic_t.key(f'"{k}"'), "expected a segment \"a-b\" of the route network",
                           traffic_t.data[k])
        traffic[k] = traffic_t.number(k, low=0.0, high=1.0)
    traffic_t.done()
    t.done()
    return replace(net, traffic=traffic)


def _from_file(t: Table, workspace, obstacles, radius, base_dir) -> RouteNetwork:
    for other in ("nodes", "segments"):
        if t.has(other):
            t.fail(t.key(other), "expected either routes.file or routes.nodes/segments, not both", t.data[other])
    name = t.string("file")
    path = Path(name) if Path(name).is_absolute() or base_dir is None else base_dir / name
    why = unreadable_because(path)  # a FIFO or a device is not a graph file (reading it could block)
    if why is not None:
        t.fail(t.key("file"), f"no such file {show_path(path)}" if why == "no such file"
               else f"cannot read {show_path(path)}: {why}", name)
    layout = t.string("layout") if t.has("layout") else None
    nodes, edges, elsewhere = read_graph_file(path, str(path), layout=layout, scenario_file=t.file,
                                              layout_key=t.key("layout"))
    net = build_network(nodes, edges, str(path), workspace=workspace, obstacles=obstacles, radius=radius,
                        known_elsewhere=elsewhere.__contains__)
    return replace(net, layout=layout or "", file=path.resolve())


def _hand_written(t: Table, workspace, obstacles, radius, docks, free_point) -> RouteNetwork:
    nodes_t = t.table("nodes")
    nodes: dict[str, tuple[float, float]] = {}
    for name in list(nodes_t.data):
        p = nodes_t.vector(name, 2, what="[x, y]")
        free_point(nodes_t, name, p, "[x, y]")
        nodes[name] = (p[0], p[1])
    nodes_t.done()
    for d in docks:
        # A dock that is also a node must sit where the dock is: routes start at docks.
        if d.node is None and d.name in nodes and math.dist(nodes[d.name], d.position) > 1e-9:
            nodes_t.fail(nodes_t.key(d.name), f"expected the position of dock {d.name} {list(d.position)}",
                         list(nodes[d.name]))
    segs_raw = t.raw("segments")
    if not isinstance(segs_raw, list):
        t.fail(t.key("segments"), "expected a list of [node, node] pairs", segs_raw)
    geoms = [obstacle_geometry(o) for o in obstacles]
    segments = []
    for i, s in enumerate(segs_raw):
        key = f"{t.key('segments')}[{i}]"
        if not (isinstance(s, list) and len(s) == 2 and all(isinstance(x, str) for x in s)):
            t.fail(key, "expected [node, node]", s)
        for x in s:
            if x not in nodes:
                t.fail(key, f"expected node names (unknown node {show(x)})", s)
        if s[0] == s[1]:
            t.fail(key, "expected two different nodes", s)
        why = segment_conflict(nodes[s[0]], nodes[s[1]], obstacles, radius, geoms)
        if why:
            t.fail(key, f"{s[0]}-{s[1]} {why}")
        segments.append((s[0], s[1]))
    # Generated ids, unique across nodes and edges (Nav2 requires it): nodes 0..n-1 in file
    # order, then two directed edges per segment (a->b, b->a: Nav2 edges are one-way) in file order.
    n = len(nodes)
    node_ids = {name: str(i) for i, name in enumerate(nodes)}
    edges = tuple(RouteEdge(ids=(str(n + 2 * i), str(n + 2 * i + 1)), ends=((a, b), (b, a)), properties=({}, {}))
                  for i, (a, b) in enumerate(segments))
    return RouteNetwork(nodes=nodes, segments=tuple(segments), edges=edges, node_ids=node_ids,
                        node_properties={name: {} for name in nodes})


def read_node_dock(t: Table, name: str) -> Dock:
    """Read a ``[[docks]]`` entry with ``node`` (instead of ``pose``); see :func:`place_node_docks`.

    Its yaw is ``yaw_deg`` (default 0); the position is NaN until the network is read.
    """
    if t.has("pose"):
        t.fail(t.key("pose"), "expected either pose or node, not both", t.data["pose"])
    node = t.string("node")
    yaw = math.radians(t.number("yaw_deg", 0.0))
    return Dock(name, (math.nan, math.nan, yaw), node=node)


def place_node_docks(docks: list[Dock], tables: Sequence[Table], routes: RouteNetwork | None,
                     free_point: FreePoint) -> list[Dock]:
    """Put docks given by ``node`` on their node's position.

    Parameters
    ----------
    docks : list of Dock
        All docks, in file order.
    tables : sequence of Table
        Their ``[[docks]]`` tables (for errors).
    routes : RouteNetwork or None
    free_point : callable
        The dock's position must be free.
    """
    out = []
    for d, t in zip(docks, tables, strict=True):
        if d.node is not None:
            if routes is None:
                t.fail(t.key("node"), "expected a node of [routes], but the scenario has no route network", d.node)
            if d.node not in routes.nodes:
                some = ", ".join(show(n) for n in list(routes.nodes)[:8])
                more = ", ..." if len(routes.nodes) > 8 else ""
                t.fail(t.key("node"), f"expected a route-network node ({some}{more})", d.node)
            x, y = routes.nodes[d.node]
            free_point(t, "node", (x, y), f"node {d.node} at [x, y]")
            d = replace(d, pose=(x, y, d.pose[2]))
        out.append(d)
    return out


def portable_routes_text(text: str, data: dict[str, Any], base: Path | None) -> str:
    """Return the scenario text with a relative ``routes.file`` made absolute.

    ``Scenario.text`` is stored beside results (``pefsim mc``) and loaded again from there,
    where a path relative to the original scenario file would not resolve. A text without a
    relative graph file is returned unchanged (comments kept); otherwise it is re-serialised
    (comments lost).
    """
    routes = data.get("routes")
    if base is None or not isinstance(routes, dict) or not isinstance(routes.get("file"), str):
        return text
    if Path(routes["file"]).is_absolute():
        return text
    import tomli_w

    out = dict(data)
    try:
        absolute = (Path(base) / routes["file"]).resolve()
    except (OSError, RuntimeError):  # a link loop, a name too long: the reader names the cause
        return text
    out["routes"] = {**routes, "file": str(absolute)}
    return tomli_w.dumps(out)
