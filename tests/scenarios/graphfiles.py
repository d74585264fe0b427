"""Route graph files for tests: a Nav2 GeoJSON graph, a two-layout VDA LIF file, scenario text.

The world: a 20 x 10 m hall with a 2 x 2 m box in the middle (9..11 x 4..6) and reflectors in
the corners. The graph is a ring around the box (nodes 0-1-2 along the south, 3-4-5 along the
north) and one edge 4 -> 1 straight through the box.
"""

from __future__ import annotations

import json
from pathlib import Path


def node(i, x, y, **props) -> dict:
    return {"type": "Feature", "geometry": {"type": "Point", "coordinates": [x, y]},
            "properties": {"id": i, "frame": "map", **props}}


def edge(i, a, b, kind="MultiLineString", coords=None, **props) -> dict:
    geometry = {"type": kind}
    if coords is not None:
        geometry["coordinates"] = coords
    return {"type": "Feature", "geometry": geometry, "properties": {"id": i, "startid": a, "endid": b, **props}}


def nav2_graph() -> dict:
    """Return a Nav2 route graph like ``nav2_route/graphs/sample_graph.geojson``."""
    return {"type": "FeatureCollection", "name": "graph", "features": [
        node(0, 2.0, 2.0, metadata={"region": {"class_type": "dock", "lights": 2}},
             operations={"stop": {"type": "stop", "trigger": "NODE"}}),
        node(1, 10.0, 2.0), node(2, 18.0, 2.0), node(3, 2.0, 8.0), node(4, 10.0, 8.0), node(5, 18.0, 8.0),
        edge(10, 0, 1, cost=1.5), edge(11, 1, 0, cost=2.5),  # a bidirectional pair
        edge(12, 1, 2, "LineString", [[10.0, 2.0], [18.0, 2.0]]),
        edge(13, 0, 3, "MultiLineString", [[[2.0, 2.0], [2.0, 8.0]]]),
        edge(14, 3, 4, metadata={"speed_limit": 0.5}, overridable=False),
        edge(15, 4, 5), edge(16, 5, 2), edge(17, 4, 1),  # 17 crosses the box
        {"type": "Feature", "geometry": {"type": "Polygon", "coordinates": []}, "properties": {"zone": "x"}},
    ]}


def lif_file() -> dict:
    """Return a LIF file with two layouts; ``L2``'s edge ``t1`` leads to layout ``L1`` (a lift)."""
    def n(i, x, y):
        return {"nodeId": i, "nodeName": f"node {i}", "nodePosition": {"x": x, "y": y, "theta": 0.0},
                "vehicleTypeNodeProperties": [{"vehicleTypeId": "agv"}]}

    def e(i, a, b):
        return {"edgeId": i, "startNodeId": a, "endNodeId": b,
                "vehicleTypeEdgeProperties": [{"vehicleTypeId": "agv", "rotationAllowed": True}]}

    return {"metaInformation": {"projectIdentification": "test", "creator": "pefsim",
                                "exportTimestamp": "2026-12-01T00:00:00Z", "lifVersion": "1.0.0"},
            "layouts": [
                {"layoutId": "L1", "layoutVersion": "1", "stations": [],
                 "nodes": [n("a", 2.0, 2.0), n("b", 18.0, 2.0)], "edges": [e("ab", "a", "b"), e("ba", "b", "a")]},
                {"layoutId": "L2", "layoutVersion": "1", "stations": [],
                 "nodes": [n("p", 2.0, 8.0), n("q", 18.0, 8.0), n("r", 18.0, 2.5)],
                 "edges": [e("pq", "p", "q"), e("qr", "q", "r"), e("t1", "q", "a")]},
            ]}


def write(path: Path, doc: dict) -> Path:
    path.write_text(json.dumps(doc, indent=1), encoding="utf-8")
    return path


def scenario_text(routes: str, docks: str = "", markers: bool = True, extra: str = "") -> str:
    """TOML of the test world with the given ``[routes]`` body and ``[[docks]]`` tables."""
    mk = "".join(f'[[markers]]\nid = "M{i}"\nposition = [{x}, {y}]\n'
                 for i, (x, y) in enumerate([(0.0, 0.0), (20.0, 0.0), (20.0, 10.0), (0.0, 10.0)], 1))
    return (f'name = "graphs"\n[workspace]\nsize = [20.0, 10.0]\n'
            f'[[obstacles]]\ncenter = [10.0, 5.0]\nsize = [2.0, 2.0]\n'
            f'{mk if markers else ""}[sensor]\n[robot]\nradius = 0.3\nwheel_base = 0.38\n'
            f'[planning]\neps_max = 0.05\nresolution = 0.2\n{docks}[routes]\n{routes}\n{extra}')


NODE_DOCKS = '[[docks]]\nname = "A"\nnode = "0"\n[[docks]]\nname = "B"\nnode = "2"\nyaw_deg = 90.0\n'
TASK = '[[tasks]]\nfrom = "A"\nto = "B"\n'
