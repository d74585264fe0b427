"""Route graphs in: Nav2 GeoJSON and VDA LIF files, docks on nodes, segments clear of obstacles."""

from __future__ import annotations

import math

import pytest

import scenarios
from scenarios import ScenarioError
from tests.scenarios.graphfiles import NODE_DOCKS, TASK, lif_file, nav2_graph, scenario_text, write


def load_text(tmp_path, text, name="s.toml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return scenarios.load(path)


def one_line_error(tmp_path, text, pattern):
    with pytest.raises(ScenarioError) as info:
        load_text(tmp_path, text)
    msg = str(info.value)
    assert "\n" not in msg
    assert __import__("re").search(pattern, msg), msg
    return msg


@pytest.fixture
def nav2(tmp_path):
    write(tmp_path / "graph.geojson", nav2_graph())
    return load_text(tmp_path, scenario_text('file = "graph.geojson"', NODE_DOCKS, extra=TASK))


def test_nav2_nodes_segments_ids_and_properties(nav2):
    net = nav2.routes
    assert net.nodes == {"0": (2.0, 2.0), "1": (10.0, 2.0), "2": (18.0, 2.0), "3": (2.0, 8.0),
                         "4": (10.0, 8.0), "5": (18.0, 8.0)}
    assert net.node_ids == {k: k for k in net.nodes}
    # the pair 10/11 is one segment keeping both ids, directions and properties
    assert net.segments == (("0", "1"), ("1", "2"), ("0", "3"), ("3", "4"), ("4", "5"), ("5", "2"), ("4", "1"))
    pair = net.edges[0]
    assert pair.ids == ("10", "11") and pair.ends == (("0", "1"), ("1", "0"))
    assert pair.properties == ({"cost": 1.5}, {"cost": 2.5})
    assert net.edges[3].properties == ({"metadata": {"speed_limit": 0.5}, "overridable": False},)
    assert net.node_properties["0"] == {"frame": "map", "metadata": {"region": {"class_type": "dock", "lights": 2}},
                                        "operations": {"stop": {"type": "stop", "trigger": "NODE"}}}
    assert net.node_properties["1"] == {"frame": "map"}
    assert net.source.endswith("graph.geojson")
    # the LineString and MultiLineString edges are straight between their nodes; the Polygon is ignored
    assert len(net.edges) == 7 and sum(len(e.ids) for e in net.edges) == 8


def test_imported_edge_through_an_obstacle_is_kept_but_inadmissible(nav2):
    net = nav2.routes
    why = {net.segments[i]: net.why_not(i) for i in range(len(net.segments))}
    assert why[("4", "1")] == "crosses obstacles[0]"
    assert all(not w for seg, w in why.items() if seg != ("4", "1"))
    assert net.edge_label(6) == "17 (4-1)"


def test_docks_on_nodes(nav2):
    a, b = nav2.dock("A"), nav2.dock("B")
    assert a.node == "0" and a.pose == (2.0, 2.0, 0.0)  # yaw_deg defaults to 0
    assert b.node == "2" and b.pose[:2] == (18.0, 2.0) and b.pose[2] == pytest.approx(math.pi / 2)


def test_dock_node_errors(tmp_path):
    write(tmp_path / "graph.geojson", nav2_graph())
    routes = 'file = "graph.geojson"'
    one_line_error(tmp_path, scenario_text(routes, '[[docks]]\nname = "A"\nnode = "99"\n'),
                   r'^.*s\.toml: docks\[0\]\.node: expected a route-network node \("0", "1", .*got "99"$')
    one_line_error(tmp_path, scenario_text(routes, '[[docks]]\nname = "A"\nnode = "0"\npose = [1.0, 1.0, 0.0]\n'),
                   r"docks\[0\]\.pose: expected either pose or node, not both")
    text = scenario_text(routes, '[[docks]]\nname = "A"\nnode = "0"\n').replace('[routes]\nfile = "graph.geojson"', "")
    one_line_error(tmp_path, text, r"docks\[0\]\.node: expected a node of \[routes\], but the scenario has no route")


def test_lif_layouts(tmp_path):
    write(tmp_path / "plant.lif.json", lif_file())
    sc = load_text(tmp_path, scenario_text('file = "plant.lif.json"\nlayout = "L2"'))
    net = sc.routes
    assert net.nodes == {"p": (2.0, 8.0), "q": (18.0, 8.0), "r": (18.0, 2.5)}
    # t1 leads into layout L1 (a transition between planes): left out, not an error
    assert net.segments == (("p", "q"), ("q", "r")) and net.layout == "L2"
    assert [e.ids for e in net.edges] == [("pq",), ("qr",)]
    assert net.node_properties["p"]["nodeName"] == "node p"
    assert net.node_properties["p"]["nodePosition"] == {"theta": 0.0}
    assert net.edges[0].properties[0]["vehicleTypeEdgeProperties"][0]["vehicleTypeId"] == "agv"
    l1 = load_text(tmp_path, scenario_text('file = "plant.lif.json"\nlayout = "L1"'))
    assert l1.routes.segments == (("a", "b"),) and l1.routes.edges[0].ids == ("ab", "ba")


def test_lif_layout_errors(tmp_path):
    write(tmp_path / "plant.lif.json", lif_file())
    one_line_error(tmp_path, scenario_text('file = "plant.lif.json"'),
                   r's\.toml: routes\.layout: missing: .*plant\.lif\.json has 2 layouts \("L1", "L2"\); name one$')
    one_line_error(tmp_path, scenario_text('file = "plant.lif.json"\nlayout = "L3"'),
                   r's\.toml: routes\.layout: expected a layoutId of .*plant\.lif\.json \("L1", "L2"\), got "L3"$')
    write(tmp_path / "graph.geojson", nav2_graph())
    one_line_error(tmp_path, scenario_text('file = "graph.geojson"\nlayout = "L1"'),
                   r"routes\.layout: only for VDA LIF files \(.*graph\.geojson is a GeoJSON route graph\), got \"L1\"")


def test_graph_file_errors(tmp_path):
    text = scenario_text('file = "graph.geojson"')
    one_line_error(tmp_path, text, r's\.toml: routes\.file: no such file .*graph\.geojson, got "graph\.geojson"$')
    (tmp_path / "graph.geojson").write_text('{"type": "FeatureCollection", "features": [', encoding="utf-8")
    one_line_error(tmp_path, text, r"graph\.geojson: malformed JSON: .*line 1 column")
    bad = nav2_graph()
    bad["features"][9]["properties"]["endid"] = 99
    write(tmp_path / "graph.geojson", bad)
    one_line_error(tmp_path, text, r"graph\.geojson: features\[9\]\.properties: expected the end of edge 13 "
                                   r"to be a node id \(no node 99\), got \"99\"$")
    bad = nav2_graph()
    del bad["features"][6]["properties"]["startid"]
    write(tmp_path / "graph.geojson", bad)
    one_line_error(tmp_path, text, r"graph\.geojson: features\[6\]\.properties\.startid: missing required key$")
    bad = nav2_graph()
    bad["features"][1]["geometry"]["coordinates"] = [30.0, 2.0]
    write(tmp_path / "graph.geojson", bad)
    one_line_error(tmp_path, text,
                   r"graph\.geojson: features\[1\]: expected a node inside the workspace .*got \[30\.0, 2\.0\]")
    bad = nav2_graph()
    bad["features"][2]["properties"]["id"] = 1.5
    write(tmp_path / "graph.geojson", bad)
    one_line_error(tmp_path, text,
                   r"features\[2\]\.properties\.id: expected an integer or a non-empty string id, got 1\.5")
    write(tmp_path / "graph.geojson", {"nodes": []})
    one_line_error(tmp_path, text,
                   r"graph\.geojson: expected a Nav2 route graph \(a GeoJSON FeatureCollection\) or a VDA LIF")
    lif = lif_file()
    lif["layouts"][1]["edges"][1]["endNodeId"] = "zz"
    write(tmp_path / "plant.lif.json", lif)
    one_line_error(tmp_path, scenario_text('file = "plant.lif.json"\nlayout = "L2"'),
                   r"plant\.lif\.json: layouts\[1\]\.edges\[1\]: expected the end of edge qr to be a node id "
                   r"\(no node zz\)")
    one_line_error(tmp_path, scenario_text('file = "plant.lif.json"\nnodes = { a = [1.0, 1.0] }'),
                   r"routes\.nodes: expected either routes\.file or routes\.nodes/segments, not both")


HAND = ('nodes = {{ a = [2.0, 2.0], b = [18.0, 2.0], c = [2.0, 8.0], d = [18.0, {dy}] }}\n'
        'segments = [["a", "b"], ["a", "c"], ["c", "d"], ["b", "d"]]')


def test_hand_written_segment_must_clear_obstacles(tmp_path):
    # c-d from (2, 8) to (18, 8) is clear; bent down to (18, 2.2) it crosses the box
    ok = load_text(tmp_path, scenario_text(HAND.format(dy=8.0)))
    assert all(e.admissible for e in ok.routes.edges)
    one_line_error(tmp_path, scenario_text(HAND.format(dy=2.2)),
                   r"s\.toml: routes\.segments\[2\]: c-d crosses obstacles\[0\]$")
    # (2, 6.2) -> (18, 6.2) passes 0.2 m above the box (top at y = 6), closer than the 0.3 m radius
    graze = HAND.format(dy=6.2).replace("c = [2.0, 8.0]", "c = [2.0, 6.2]")
    one_line_error(tmp_path, scenario_text(graze),
                   r"s\.toml: routes\.segments\[2\]: c-d passes 0\.20 m from obstacles\[0\], "
                   r"closer than robot\.radius 0\.3$")


def test_clearance_holds_for_circle_and_polygon_obstacles(tmp_path):
    text = scenario_text(HAND.format(dy=8.0))
    circle = text.replace("[[obstacles]]\ncenter = [10.0, 5.0]\nsize = [2.0, 2.0]\n",
                          "[[obstacles]]\ncenter = [10.0, 5.0]\nsize = [2.0, 2.0]\n"
                          "[[obstacles]]\ncenter = [6.0, 7.6]\nradius = 0.25\n")
    one_line_error(tmp_path, circle, r"routes\.segments\[2\]: c-d passes 0\.1\d m from obstacles\[1\]")
    poly = text.replace("[[obstacles]]\ncenter = [10.0, 5.0]\nsize = [2.0, 2.0]\n",
                        "[[obstacles]]\npolygon = [[14.0, 7.0], [16.0, 7.0], [15.0, 9.0]]\n")
    one_line_error(tmp_path, poly, r"routes\.segments\[2\]: c-d crosses obstacles\[0\]")


def test_hand_written_ids_are_generated():
    sc = scenarios.load("paper-docks")
    net = sc.routes
    n = len(net.nodes)
    assert list(net.node_ids.values()) == [str(i) for i in range(n)]
    assert [e.ids for e in net.edges] == [(str(n + 2 * i), str(n + 2 * i + 1)) for i in range(len(net.segments))]
    assert all(e.ends == ((a, b), (b, a)) for e, (a, b) in zip(net.edges, net.segments, strict=True))


@pytest.mark.parametrize("name", scenarios.builtin_names())
def test_builtin_segments_are_clear(name):
    sc = scenarios.load(name)
    if sc.routes is not None:
        assert all(e.admissible for e in sc.routes.edges)


def test_markers_are_optional(tmp_path):
    sc = load_text(tmp_path, scenario_text(HAND.format(dy=8.0), markers=False))
    assert sc.markers == ()
    one_marker = scenario_text(HAND.format(dy=8.0), markers=False).replace(
        "[sensor]", '[[markers]]\nid = "M1"\nposition = [0.0, 0.0]\n[sensor]')
    one_line_error(tmp_path, one_marker, r"sensor\.markers_per_fix: expected at most the number of markers \(1\)")


def test_text_names_the_graph_file_absolutely(nav2, tmp_path, monkeypatch):
    # Scenario.text is stored beside results and loaded again from elsewhere
    assert 'file = "graph.geojson"' not in nav2.text and str(tmp_path / "graph.geojson") in nav2.text
    monkeypatch.chdir("/")
    again = scenarios.loads(nav2.text, source="stored.toml")
    assert again.routes.nodes == nav2.routes.nodes and again.routes.edges == nav2.routes.edges
    # without a graph file the text is kept as written (comments too)
    from scenarios.load import LIBRARY

    assert scenarios.load("warehouse").text == (LIBRARY / "warehouse.toml").read_text(encoding="utf-8")
