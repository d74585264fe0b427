"""A route graph file read by its format: Nav2 route server GeoJSON or VDA LIF.

The format readers (:mod:`~scenarios.routegraph.nav2`, :mod:`~scenarios.routegraph.lif`) build on
the graph elements of :mod:`~scenarios.routegraph.graph`; this module chooses between them.
"""

from __future__ import annotations

import json
from pathlib import Path

from scenarios.errors import ScenarioError
from scenarios.limits import MAX_NESTING, nesting_depth
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
