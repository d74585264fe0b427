"""A route graph file read by its format: Nav2 route server GeoJSON or VDA LIF.

The format readers (:mod:`~scenarios.routegraph.nav2`, :mod:`~scenarios.routegraph.lif`) build on
the graph elements of :mod:`~scenarios.routegraph.graph`; this module chooses between them.
"""

from __future__ import annotations

import json
from pathlib import Path

from scenarios.errors import ScenarioError
from scenarios.limits import MAX_GRAPH_BYTES, MAX_GRAPH_EDGES, MAX_GRAPH_NODES, MAX_NESTING, long_integer, nesting_depth
from scenarios.routegraph import lif, nav2
from scenarios.routegraph.graph import GraphEdge, GraphNode, fail


def read_graph_file(path: Path, shown: str, *, layout: str | None, scenario_file: str,
                    layout_key: str) -> tuple[list[GraphNode], list[GraphEdge], set[str]]:
    """Read the nodes and directed edges of a Nav2 GeoJSON or VDA LIF file.

    Returns the nodes, the edges and the ids of nodes that exist in the file outside the graph
    read (a LIF file's other layouts; see ``known_elsewhere`` of
    :func:`~scenarios.routegraph.graph.build_network`).

    Parameters
    ----------
    path : Path
        The file.
    shown : str
        How errors name the file.
    layout : str or None
        LIF only: the ``layoutId`` to read (needed when the file has several layouts).
    scenario_file, layout_key : str
        Scenario file and key path of ``layout`` (``routes.layout``), for its errors.

    Raises
    ------
    ScenarioError
        Unreadable file, malformed JSON, an unknown format, or a bad value (naming file and key).
    """
    try:
        size = path.stat().st_size
        if size > MAX_GRAPH_BYTES:  # parsed whole: refused before it is read
            raise ScenarioError(f"{shown}: a route graph of {size} bytes, at most {MAX_GRAPH_BYTES:.0e}")
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(f"{shown}: cannot read: {getattr(exc, 'strerror', None) or exc}") from None
    depth = nesting_depth(text)
    if depth > MAX_NESTING:  # json recurses per level: refused before it parses
        raise ScenarioError(f"{shown}: arrays and objects nested {depth} deep, at most {MAX_NESTING}")
    try:
        data = json.loads(text, parse_constant=lambda c: fail(shown, "<json>", "expected finite numbers", c))
    except json.JSONDecodeError as exc:
        raise ScenarioError(f"{shown}: malformed JSON: {exc}") from None
    except RecursionError:  # only if the scan above under-counted a malformed file
        raise ScenarioError(f"{shown}: arrays and objects nested deeper than {MAX_NESTING}") from None
    except ValueError:  # Python's int-string limit (4300 digits): no coordinate or id is that long
        raise ScenarioError(f"{shown}: malformed JSON: {long_integer(text)}") from None
    _check_counts(data, shown)
    if isinstance(data, dict) and data.get("type") == "FeatureCollection":
        if layout is not None:
            fail(scenario_file, layout_key, f"only for VDA LIF files ({shown} is a GeoJSON route graph)", layout)
        nodes, edges = nav2.read(data, shown)
        elsewhere: set[str] = set()
    elif isinstance(data, dict) and "layouts" in data:
        nodes, edges, elsewhere = lif.read(data, shown, layout, scenario_file, layout_key)
    else:
        raise ScenarioError(f"{shown}: expected a Nav2 route graph (a GeoJSON FeatureCollection) or a "
                            "VDA LIF file (an object with \"layouts\")")
    return nodes, edges, elsewhere


def _check_counts(data, shown: str) -> None:
    """Refuse a graph over the node or edge budget from its lists' lengths, before any element is read."""
    counts = {}
    if isinstance(data, dict) and isinstance(data.get("features"), list):
        points = sum(1 for f in data["features"] if isinstance(f, dict) and isinstance(g := f.get("geometry"), dict)
                     and g.get("type") == "Point")
        counts["nodes (Point features)"] = (points, MAX_GRAPH_NODES)
        counts["edges (other features)"] = (len(data["features"]) - points, MAX_GRAPH_EDGES)
    if isinstance(data, dict) and isinstance(data.get("layouts"), list):
        lays = [lay for lay in data["layouts"] if isinstance(lay, dict)]
        counts["nodes"] = (sum(len(v) for lay in lays if isinstance(v := lay.get("nodes"), list)), MAX_GRAPH_NODES)
        counts["edges"] = (sum(len(v) for lay in lays if isinstance(v := lay.get("edges"), list)), MAX_GRAPH_EDGES)
    for what, (n, most) in counts.items():
        if n > most:
            raise ScenarioError(f"{shown}: a route graph of {n} {what}, at most {most}")
