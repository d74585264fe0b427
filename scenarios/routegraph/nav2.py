"""Nav2 route graphs: the GeoJSON that Nav2's route server reads (``geojson_graph_file_loader``).

A ``FeatureCollection`` whose ``Point`` features are nodes (``properties.id``, optional
``frame``, ``metadata``, ``operations``, ...; coordinates [x, y] in metres in the map frame)
and whose ``LineString``/``MultiLineString`` features are directed edges (``properties.id``,
``startid``, ``endid``, optional ``cost``, ``overridable``, ``metadata``, ``operations``, ...).
Other geometries are ignored, as Nav2 ignores them. Every other property is kept.

Nav2 asks for unique ids, but its own example graphs reuse edge ids (``turtlebot4_graph.geojson``
of the depot world: six ids, each on two edges to different nodes) and its route server loads
them. So does this reader: both edges are kept with the id as given (exports keep it too), and
one :class:`~scenarios.errors.ScenarioWarning` names the repeated ids. Repeated node ids stay
an error (an edge could not tell which node it meant).
"""

from __future__ import annotations

import warnings
from collections import Counter
from dataclasses import replace
from typing import Any

from scenarios.errors import ScenarioWarning
from scenarios.routegraph.graph import GraphEdge, GraphNode, fail, finite_xy, graph_id

EDGE_TYPES = ("LineString", "MultiLineString")


def read(data: dict[str, Any], shown: str) -> tuple[list[GraphNode], list[GraphEdge]]:
    """Nodes and directed edges of a parsed Nav2 GeoJSON route graph.

    Raises
    ------
    ScenarioError
        A feature without geometry or properties, or a missing or ill-typed id, naming the file
        and the feature (``features[12].properties.endid``).
    """
    features = data.get("features")
    if not isinstance(features, list):
        fail(shown, "features", "expected a list of GeoJSON features", features)
    nodes, edges = [], []
    for i, f in enumerate(features):
        key = f"features[{i}]"
        if not isinstance(f, dict) or not isinstance(f.get("geometry"), dict):
            fail(shown, f"{key}.geometry", "expected a GeoJSON feature with a geometry",
                 f.get("geometry") if isinstance(f, dict) else f)
        kind = f["geometry"].get("type")
        if kind != "Point" and kind not in EDGE_TYPES:
            continue
        p = f.get("properties")
        if not isinstance(p, dict):
            fail(shown, f"{key}.properties", "expected an object with the id", p)
        if "id" not in p:
            fail(shown, f"{key}.properties.id", "missing required key", with_value=False)
        fid = graph_id(shown, f"{key}.properties.id", p["id"])
        if kind == "Point":
            xy = finite_xy(shown, f"{key}.geometry.coordinates", f["geometry"].get("coordinates"), "[x, y]")
            rest = {k: v for k, v in p.items() if k != "id"}
            nodes.append(GraphNode(fid, xy, rest, key))
            continue
        ends = []
        for name in ("startid", "endid"):
            if name not in p:
                fail(shown, f"{key}.properties.{name}", "missing required key", with_value=False)
            ends.append(graph_id(shown, f"{key}.properties.{name}", p[name]))
        rest = {k: v for k, v in p.items() if k not in ("id", "startid", "endid")}
        edges.append(GraphEdge(fid, ends[0], ends[1], rest, f"{key}.properties"))
    counts = Counter(e.id for e in edges)
    repeated = [i for i, c in counts.items() if c > 1]
    if repeated:
        warnings.warn(f"{shown}: features: repeated edge ids {', '.join(repeated)} (Nav2 asks for unique ids); "
                      "each kept on all its edges", ScenarioWarning, stacklevel=2)
        edges = [replace(e, repeated_ok=counts[e.id] > 1) for e in edges]
    return nodes, edges
