"""VDA 5050 LIF (Layout Interchange Format) files: ``layouts`` of nodes and directed edges.

A LIF file holds one or more layouts (``layoutId``), each with ``nodes`` (``nodeId``,
``nodePosition`` {x, y} in metres, ...) and ``edges`` (``edgeId``, ``startNodeId``,
``endNodeId``, ...). One layout is one plane: the scenario reads the one ``routes.layout``
names (the only one if there is one). An edge whose end node lies in another layout of the
file is a transition between planes and is left out. Every other key is kept as a property.
"""

from __future__ import annotations

from typing import Any

from scenarios.routegraph.graph import GraphEdge, GraphNode, fail, finite_xy, graph_id


def _layout_ids(layouts: list, shown: str) -> list[str]:
    ids = []
    for i, lay in enumerate(layouts):
        if not isinstance(lay, dict) or "layoutId" not in lay:
            fail(shown, f"layouts[{i}].layoutId", "missing required key", with_value=False)
        lid = graph_id(shown, f"layouts[{i}].layoutId", lay["layoutId"])
        if lid in ids:  # which one a scenario's routes.layout names would be a guess
            fail(shown, f"layouts[{i}].layoutId", f"expected a unique layout id (also layouts[{ids.index(lid)}])",
                 lay["layoutId"])
        ids.append(lid)
    return ids


def read(data: dict[str, Any], shown: str, layout: str | None, scenario_file: str,
         layout_key: str) -> tuple[list[GraphNode], list[GraphEdge], set[str]]:
    """Read the nodes and directed edges of one layout of a parsed LIF file.

    Also returns the node ids of the other layouts (edges to them are transitions between
    planes, left out).

    Raises
    ------
    ScenarioError
        No layouts; ``layout`` missing while the file has several, or naming none of them
        (the error lists the layout ids); a missing or ill-typed id or position.
    """
    layouts = data["layouts"]
    if not isinstance(layouts, list) or not layouts:
        fail(shown, "layouts", "expected a non-empty list of layouts", layouts)
    ids = _layout_ids(layouts, shown)
    listed = ", ".join(show_id(x) for x in ids)
    if layout is None:
        if len(ids) > 1:
            fail(scenario_file, layout_key, f"missing: {shown} has {len(ids)} layouts ({listed}); name one",
                 with_value=False)
        index = 0
    elif layout not in ids:
        fail(scenario_file, layout_key, f"expected a layoutId of {shown} ({listed})", layout)
    else:
        index = ids.index(layout)
    lay, base = layouts[index], f"layouts[{index}]"
    nodes = []
    for i, n in enumerate(_list(lay, "nodes", shown, base)):
        key = f"{base}.nodes[{i}]"
        nid = graph_id(shown, f"{key}.nodeId", _req(n, "nodeId", shown, key))
        p = _req(n, "nodePosition", shown, key)
        xy = finite_xy(shown, f"{key}.nodePosition", [p.get("x"), p.get("y")] if isinstance(p, dict) else p,
                       "{x, y} in metres")
        rest = {k: v for k, v in n.items() if k not in ("nodeId", "nodePosition")}
        if isinstance(p, dict) and set(p) - {"x", "y"}:
            rest["nodePosition"] = {k: v for k, v in p.items() if k not in ("x", "y")}
        nodes.append(GraphNode(nid, xy, rest, key))
    edges = []
    for i, e in enumerate(_list(lay, "edges", shown, base)):
        key = f"{base}.edges[{i}]"
        eid = graph_id(shown, f"{key}.edgeId", _req(e, "edgeId", shown, key))
        a = graph_id(shown, f"{key}.startNodeId", _req(e, "startNodeId", shown, key))
        b = graph_id(shown, f"{key}.endNodeId", _req(e, "endNodeId", shown, key))
        rest = {k: v for k, v in e.items() if k not in ("edgeId", "startNodeId", "endNodeId")}
        edges.append(GraphEdge(eid, a, b, rest, key))
    return nodes, edges, other_layout_nodes(data, index)


def other_layout_nodes(data: dict[str, Any], layout_index: int) -> set[str]:
    """Node ids of the file's other layouts (edges to them are transitions, not errors)."""
    out: set[str] = set()
    for i, lay in enumerate(data.get("layouts", [])):
        if i != layout_index and isinstance(lay, dict):
            nodes = lay.get("nodes", [])
            # another layout's nodes are only looked up: a malformed list there names no node
            out |= {str(n.get("nodeId")) for n in nodes if isinstance(n, dict)} if isinstance(nodes, list) else set()
    return out


def show_id(x: str) -> str:
    return f'"{x}"'


def _list(obj: dict, name: str, shown: str, base: str) -> list:
    v = obj.get(name, [])
    if not isinstance(v, list):
        fail(shown, f"{base}.{name}", "expected a list", v)
    for i, item in enumerate(v):
        if not isinstance(item, dict):
            fail(shown, f"{base}.{name}[{i}]", "expected an object", item)
    return v


def _req(obj: dict, name: str, shown: str, key: str) -> Any:
    if name not in obj:
        fail(shown, f"{key}.{name}", "missing required key", with_value=False)
    return obj[name]
