"""The route network as a Nav2 route graph (GeoJSON), with the PEF along every edge.

The file is what Nav2's route server reads (``geojson_graph_file_loader``) and what
``[routes] file`` reads back: a ``FeatureCollection`` of ``Point`` nodes (``properties.id``
and the node's other properties) and ``LineString`` edges, one per *directed* edge
(``id``, ``startid``, ``endid``, the edge's other properties), coordinates in metres in the
scenario's frame, which is the user's (``workspace.origin`` is where the workspace starts in it).

Nav2 needs integer ids, unique across nodes and edges. A network whose ids are all such
integers keeps them (an edge id its graph file repeated included: Nav2's own examples do it);
otherwise (a LIF layout's string ids) nodes are renumbered 0, 1, ... and
edges after them, in network order, and each original id is kept as ``source_id``. A
hand-written network already has generated integer ids (:class:`scenarios.route_network.RouteNetwork`).

Every edge also carries the PEF along its segment (:mod:`planner.routes.edges`): ``max_tau``,
``mean_tau`` [m] (null when infinite: some point has no fix), ``min_visible`` (fewest markers
visible), ``admissible`` and ``why_not`` (null when admissible).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from scenarios.errors import output_errors
from scenarios.jsonable import json_number
from scenarios.route_network import RouteNetwork
from scenarios.schema import Scenario

#: Properties the export computes; they replace any read from the graph file.
COMPUTED = ("max_tau", "mean_tau", "min_visible", "admissible", "why_not")


def export_ids(net: RouteNetwork) -> tuple[dict[str, int], list[list[int]], bool]:
    """Nav2 ids of the nodes and of every directed edge.

    Returns
    -------
    node_ids : dict[str, int]
        Node name -> id.
    edge_ids : list of list of int
        Per segment, the ids of its directed edges (in ``RouteEdge.ids`` order).
    renumbered : bool
        True when the network's own ids were not all distinct non-negative integers.
    """
    own_nodes = [net.node_ids.get(n, n) for n in net.nodes]
    own_edges = [list(e.ids) for e in net.edges]
    flat = own_nodes + [i for ids in own_edges for i in ids]
    # an edge id the graph file itself repeats (Nav2's own examples do) is kept as given
    node_set, edge_set = {int(i) for i in own_nodes if i.isdecimal()}, {int(i) for i in flat[len(own_nodes):]
                                                                         if i.isdecimal()}
    if (all(i.isdecimal() for i in flat) and len(node_set) == len(own_nodes) and not node_set & edge_set):
        return ({n: int(i) for n, i in zip(net.nodes, own_nodes, strict=True)},
                [[int(i) for i in ids] for ids in own_edges], False)
    node_ids = {n: k for k, n in enumerate(net.nodes)}
    nxt, edge_ids = len(node_ids), []
    for ids in own_edges:
        edge_ids.append(list(range(nxt, nxt + len(ids))))
        nxt += len(ids)
    return node_ids, edge_ids, True


def route_graph(scenario: Scenario, reports: Sequence[Any]) -> dict:
    """Build the GeoJSON document of the scenario's route network.

    Parameters
    ----------
    scenario : Scenario
        With a route network whose ``edges`` are filled (as every loaded scenario's are).
    reports : sequence of planner.routes.edges.SegmentReport
        The PEF along each segment, in segment order.

    Returns
    -------
    dict
        A GeoJSON ``FeatureCollection``.
    """
    net = scenario.routes
    node_ids, edge_ids, renumbered = export_ids(net)
    features = []
    for name, (x, y) in net.nodes.items():
        props: dict[str, Any] = {"id": node_ids[name]}
        props.update(net.node_properties.get(name, {}))
        props.setdefault("frame", "map")
        own = net.node_ids.get(name, name)
        if renumbered:
            props["source_id"] = own
        if name != own:
            props["name"] = name  # a hand-written node's name (docks and traffic use it)
        features.append(_feature("Point", [x, y], props))
    for i, (edge, rep) in enumerate(zip(net.edges, reports, strict=True)):
        computed = {"max_tau": json_number(rep.max_tau), "mean_tau": json_number(rep.mean_tau),
                    "min_visible": rep.min_visible, "admissible": rep.admissible, "why_not": rep.why_not or None}
        for k, (own, (a, b)) in enumerate(zip(edge.ids, edge.ends, strict=True)):
            props = {"id": edge_ids[i][k], "startid": node_ids[a], "endid": node_ids[b]}
            extra = edge.properties[k] if k < len(edge.properties) else {}
            props.update({key: v for key, v in extra.items() if key not in COMPUTED})
            if renumbered:
                props["source_id"] = own
            props.update(computed)
            (xa, ya), (xb, yb) = net.nodes[a], net.nodes[b]
            features.append(_feature("LineString", [[xa, ya], [xb, yb]], props))
    return {"type": "FeatureCollection", "name": scenario.name, "features": features}


def write_route_graph(path: str | Path, scenario: Scenario, reports: Sequence[Any]) -> Path:
    """Write :func:`route_graph` to ``path`` (UTF-8 JSON); raises OutputError if it cannot."""
    doc = route_graph(scenario, reports)
    out = Path(path)
    text = json.dumps(doc, indent=2, allow_nan=False)
    with output_errors(out, "write the route graph"):
        out.write_text(text + "\n", encoding="utf-8")
    return out


def _feature(kind: str, coordinates: list, properties: dict) -> dict:
    return {"type": "Feature", "geometry": {"type": kind, "coordinates": coordinates}, "properties": properties}
