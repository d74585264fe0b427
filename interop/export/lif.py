"""The route network as a VDA LIF file, each node with its predicted worst-case position error.

LIF (the VDMA's Layout Interchange Format, 1.0) holds ``layouts`` of ``nodes`` (``nodeId``,
``nodePosition`` {x, y} [m], ``vehicleTypeNodeProperties``) and directed ``edges``
(``edgeId``, ``startNodeId``, ``endNodeId``, ``vehicleTypeEdgeProperties``), and
``metaInformation``. Each node gets ``nodePosition.allowedDeviationXY`` [m]: where VDA 5050
puts how far a vehicle may be from the node and still count as on it, here the PEF's τ at the
node (the diameter of the region the fix confines the robot to, so no position in it is
farther from the estimate than τ: the predicted worst-case position error). A node without a
fix (τ = inf) gets none.

A network read from a LIF file is written back into a copy of that file (every other layout,
station, property and id as they were; only ``allowedDeviationXY`` of the layout read is set).
Any other network (a Nav2 graph, a hand-written ``[routes]`` table) becomes one layout named
after the scenario, every node and directed edge keeping its id as a string (a Nav2 graph's
repeated edge id too), with one vehicle type ``pefsim`` (its ``robot``) on every node and edge.
"""

from __future__ import annotations

import datetime as dt
import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from scenarios.errors import output_errors
from scenarios.schema import RouteNetwork, Scenario

LIF_VERSION = "1.0.0"
VEHICLE_TYPE = "pefsim"
"""``vehicleTypeId`` of the one vehicle type written (LIF asks for at least one per node and edge)."""


def _deviation(tau: float) -> dict[str, float]:
    return {"allowedDeviationXY": float(tau)} if math.isfinite(tau) else {}


def _source_lif(net: RouteNetwork) -> dict | None:
    """Return the parsed LIF file the network was read from, or None (another source)."""
    if not net.source:
        return None
    try:
        data = json.loads(Path(net.source).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None
    return data if isinstance(data, dict) and isinstance(data.get("layouts"), list) else None


def lif_document(scenario: Scenario, node_tau: Mapping[str, float], timestamp: str | None = None) -> dict[str, Any]:
    """Build the LIF document of the scenario's route network.

    Parameters
    ----------
    scenario : Scenario
        With a route network.
    node_tau : mapping of str to float
        Node name -> τ at the node [m] (inf: no fix).
    timestamp : str, optional
        ``metaInformation.exportTimestamp`` (ISO 8601, UTC); default now.

    Returns
    -------
    dict
        The LIF document (JSON-ready).
    """
    net = scenario.routes
    own = {net.node_ids.get(n, n): n for n in net.nodes}
    data = _source_lif(net)
    if data is not None:
        ids = [str(lay.get("layoutId")) for lay in data["layouts"] if isinstance(lay, dict)]
        index = ids.index(net.layout) if net.layout else 0
        for node in data["layouts"][index].get("nodes", []):
            name = own.get(str(node.get("nodeId")))
            if name is not None:
                pos = node["nodePosition"] if isinstance(node["nodePosition"], dict) else {}
                x, y = net.nodes[name]
                pos = {**pos, "x": pos.get("x", x), "y": pos.get("y", y)}
                pos.pop("allowedDeviationXY", None)  # an old value is not this layout's
                node["nodePosition"] = {**pos, **_deviation(node_tau[name])}
        return data
    nodes = []
    for name, (x, y) in net.nodes.items():
        node = {"nodeId": str(net.node_ids.get(name, name)),
                "nodePosition": {"x": float(x), "y": float(y), **_deviation(node_tau[name])},
                "vehicleTypeNodeProperties": [{"vehicleTypeId": VEHICLE_TYPE}]}
        if node["nodeId"] != name:
            node["nodeName"] = name
        nodes.append(node)
    edges = []
    for i, (a, b) in enumerate(net.segments):
        directed = (zip(net.edges[i].ids, net.edges[i].ends, strict=True) if net.edges
                    else ((f"{a}-{b}", (a, b)), (f"{b}-{a}", (b, a))))
        for eid, (s, e) in directed:
            edges.append({"edgeId": str(eid), "startNodeId": str(net.node_ids.get(s, s)),
                          "endNodeId": str(net.node_ids.get(e, e)),
                          "vehicleTypeEdgeProperties": [{"vehicleTypeId": VEHICLE_TYPE, "rotationAllowed": True}]})
    stamp = timestamp or dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%fZ")
    return {"metaInformation": {"projectIdentification": scenario.name, "creator": "pefsim",
                                "exportTimestamp": stamp, "lifVersion": LIF_VERSION},
            "layouts": [{"layoutId": scenario.name, "layoutName": scenario.name, "layoutVersion": "1",
                         "nodes": nodes, "edges": edges, "stations": []}]}


def write_lif(path: str | Path, scenario: Scenario, node_tau: Mapping[str, float]) -> Path:
    """Write :func:`lif_document` to ``path`` (UTF-8 JSON); raises OutputError if it cannot."""
    text = json.dumps(lif_document(scenario, node_tau), indent=2, allow_nan=False)
    out = Path(path)
    with output_errors(out, "write the LIF file"):
        out.write_text(text + "\n", encoding="utf-8")
    return out
