"""``pefsim export`` and scenarios without markers: file contents, round trips, one-line errors."""

from __future__ import annotations

import csv
import json
import re

import numpy as np
import pytest
import shapely
from shapely.geometry import Polygon

import scenarios
from cli import main
from interop.export.region import region_contours, route_lines
from planner.pef.map import PEF
from tests.scenarios.graphfiles import NODE_DOCKS, TASK, nav2_graph, scenario_text, write


def run_cli(capsys, *argv):
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture
def graph_scenario(tmp_path):
    write(tmp_path / "graph.geojson", nav2_graph())
    path = tmp_path / "s.toml"
    path.write_text(scenario_text('file = "graph.geojson"', NODE_DOCKS, extra=TASK), encoding="utf-8")
    return path


def features(doc):
    nodes = {f["properties"]["id"]: f for f in doc["features"] if f["geometry"]["type"] == "Point"}
    edges = {f["properties"]["id"]: f for f in doc["features"] if f["geometry"]["type"] == "LineString"}
    return nodes, edges


def test_export_imported_graph(capsys, tmp_path, graph_scenario):
    out, mk = tmp_path / "out.geojson", tmp_path / "m.csv"
    code, stdout, err = run_cli(capsys, "export", graph_scenario, "--routes", out, "--markers", mk)
    assert code == 0 and err == "" and f"wrote {out}" in stdout
    doc = json.loads(out.read_text())
    assert doc["type"] == "FeatureCollection"
    nodes, edges = features(doc)
    assert sorted(nodes) == [0, 1, 2, 3, 4, 5] and sorted(edges) == [10, 11, 12, 13, 14, 15, 16, 17]
    assert nodes[0]["geometry"]["coordinates"] == [2.0, 2.0]
    assert nodes[0]["properties"]["metadata"] == {"region": {"class_type": "dock", "lights": 2}}
    assert (edges[10]["properties"]["startid"], edges[10]["properties"]["endid"]) == (0, 1)
    assert (edges[11]["properties"]["startid"], edges[11]["properties"]["endid"]) == (1, 0)
    assert edges[11]["properties"]["cost"] == 2.5 and edges[14]["properties"]["overridable"] is False
    sc = scenarios.load(graph_scenario)
    pef = PEF(sc)
    ok = edges[12]["properties"]
    pts = np.linspace([10.0, 2.0], [18.0, 2.0], 41)  # sampled at the 0.2 m resolution
    tau = pef.at(pts).tau
    assert ok["max_tau"] == pytest.approx(tau.max(), rel=1e-9) and tau.min() < ok["mean_tau"] < tau.max()
    assert ok["min_visible"] == pef.visible(pts).sum(axis=1).min() and ok["admissible"] is True
    assert ok["why_not"] is None
    bad = edges[17]["properties"]
    assert bad["admissible"] is False and bad["why_not"] == "crosses obstacles[0]"
    assert bad["max_tau"] is None and bad["mean_tau"] is None and bad["min_visible"] == 0
    rows = list(csv.DictReader(mk.open()))
    assert [r["id"] for r in rows] == ["M1", "M2", "M3", "M4"]
    assert list(rows[0]) == ["id", "x", "y", "x_mm", "y_mm", "kind", "facing_deg"]
    assert all(r["kind"] == "post" and r["facing_deg"] == "" for r in rows)  # posts face nowhere
    assert (float(rows[2]["x"]), float(rows[2]["y"])) == (20.0, 10.0)
    assert (float(rows[2]["x_mm"]), float(rows[2]["y_mm"])) == (20000.0, 10000.0)


def test_round_trip_hand_written_and_imported(capsys, tmp_path, graph_scenario):
    # hand-written: generated ids survive export -> import
    out = tmp_path / "w.geojson"
    assert run_cli(capsys, "export", "warehouse", "--routes", out)[0] == 0
    src = scenarios.load("warehouse")
    text = re.sub(r"\[routes\]\n(?:.+\n)+", '[routes]\nfile = "w.geojson"\n', src.text, count=1)
    (tmp_path / "w.toml").write_text(text, encoding="utf-8")
    back = scenarios.load(tmp_path / "w.toml").routes
    ids = src.routes.node_ids
    assert {ids[n]: p for n, p in src.routes.nodes.items()} == back.nodes
    assert [e.ids for e in src.routes.edges] == [e.ids for e in back.edges]
    assert [tuple((ids[a], ids[b]) for a, b in e.ends) for e in src.routes.edges] == [e.ends for e in back.edges]
    assert back.node_properties["0"]["name"] == "A"
    # imported: the same nodes and edges with the same ids, properties kept
    again = tmp_path / "again.geojson"
    assert run_cli(capsys, "export", graph_scenario, "--routes", again)[0] == 0
    first = scenarios.load(graph_scenario).routes
    path = tmp_path / "r.toml"
    path.write_text(graph_scenario.read_text().replace("graph.geojson", "again.geojson"), encoding="utf-8")
    second = scenarios.load(path).routes
    assert second.nodes == first.nodes and second.segments == first.segments
    assert [(e.ids, e.ends, e.why_not) for e in second.edges] == [(e.ids, e.ends, e.why_not) for e in first.edges]
    assert second.edges[0].properties[1]["cost"] == 2.5


def test_export_errors(capsys, tmp_path, graph_scenario):
    code, _, err = run_cli(capsys, "export", graph_scenario)
    assert code == 2 and err.count("\n") == 1 and "give at least one of routes, markers, dxf" in err
    code, _, err = run_cli(capsys, "export", "paper-two-markers", "--routes", tmp_path / "x.geojson")
    assert code == 2 and "has no route network" in err and not (tmp_path / "x.geojson").exists()
    code, _, err = run_cli(capsys, "export", graph_scenario, "--markers", tmp_path / "no" / "m.csv")
    assert code == 2 and err.count("\n") == 1 and "cannot write the markers" in err


def test_dxf(capsys, tmp_path, graph_scenario):
    import ezdxf

    from planner.routes.edges import segment_reports

    dxf = tmp_path / "d.dxf"
    code, _, err = run_cli(capsys, "export", graph_scenario, "--dxf", dxf)
    assert code == 0 and err == ""
    msp = ezdxf.readfile(dxf).modelspace()
    sc = scenarios.load(graph_scenario)
    pef = PEF(sc)
    region = msp.query('LWPOLYLINE[layer=="PEFSIM-REGION"]')
    rings = region_contours(pef.grid(), sc.planning.eps_max, sc.workspace.bounds)
    assert len(region) == len(rings) > 0
    reports = segment_reports(sc, pef)
    ok = [rep.admissible for rep in reports]
    assert True in ok and False in ok  # both layers have something to hold
    for layer, want in (("PEFSIM-ROUTES", True), ("PEFSIM-ROUTES-INADMISSIBLE", False)):
        lines = msp.query(f'LWPOLYLINE[layer=="{layer}"]')
        assert sorted(e.get_xdata("PEFSIM")[0].value for e in lines) == sorted(
            rid for (rid, _), good in zip(route_lines(sc), ok, strict=True) if good is want)
        labels = [e.dxf.text for e in msp.query(f'TEXT[layer=="{layer}"]')]
        assert len(labels) == len(lines)
    texts = {e.dxf.text.split()[0]: e.dxf.text for e in msp.query("TEXT")}
    for (rid, _), rep in zip(route_lines(sc), reports, strict=True):
        want = f"{rid} max tau {rep.max_tau * 1000:.1f} mm" if np.isfinite(rep.max_tau) else f"{rid} no fix"
        assert texts[rid] == want


def test_region_contours_enclose_the_navigation_region():
    sc = scenarios.load("paper-two-markers")
    pm = PEF(sc).grid(0.05)
    eps = sc.planning.eps_max
    rings = region_contours(pm, eps, sc.workspace.bounds)
    assert rings and all(np.allclose(r[0], r[-1]) for r in rings)
    region = shapely.GeometryCollection()
    for r in rings:  # rings nest (holes): even-odd
        region = region.symmetric_difference(Polygon(r))
    inside = pm.navigable(eps)
    cell = pm.cell_size[0] * pm.cell_size[1]
    assert region.area == pytest.approx(inside.sum() * cell, rel=0.03)
    xx, yy = np.meshgrid(pm.x, pm.y)
    hit = shapely.contains_xy(region, xx, yy)
    # cells whose centre the contour puts on the wrong side lie along it: a few percent at most
    assert np.count_nonzero(hit != inside) < 0.03 * max(inside.sum(), 1)


def test_route_lines(graph_scenario):
    sc = scenarios.load(graph_scenario)
    lines = route_lines(sc)
    assert [k for k, _ in lines] == ["10/11", "12", "13", "14", "15", "16", "17"]
    np.testing.assert_allclose(lines[0][1], [[2.0, 2.0], [10.0, 2.0]])


# ----------------------------------------------------------------------------- no markers


@pytest.fixture
def bare(tmp_path):
    write(tmp_path / "graph.geojson", nav2_graph())
    path = tmp_path / "bare.toml"
    path.write_text(scenario_text('file = "graph.geojson"', NODE_DOCKS, markers=False, extra=TASK), encoding="utf-8")
    return path


def test_no_markers_map(capsys, bare):
    code, out, _ = run_cli(capsys, "map", bare, "--json")
    doc = json.loads(out)
    assert code == 0 and doc["fraction_navigable"] == 0.0
    assert doc["tau_min"] is None and doc["tau_median"] is None and doc["tau_max"] is None
    code, out, _ = run_cli(capsys, "map", bare)
    assert code == 0 and "no markers: tau = inf everywhere" in out


def test_no_markers_plan_run_mc(capsys, tmp_path, bare):
    code, out, err = run_cli(capsys, "plan", bare)
    assert code == 2 and out == "" and err.count("\n") == 1
    assert "no admissible route from 'A' to 'B': the scenario has 0 markers and a fix needs 2" in err
    code, _, err = run_cli(capsys, "run", bare)
    assert code == 2 and err.count("\n") == 1 and "markers: the scenario has 0 markers, a fix needs 2" in err
    code, _, err = run_cli(capsys, "mc", bare, "--runs", "1", "--workers", "1", "--out", tmp_path / "mc")
    assert code == 2 and err.count("\n") == 1 and "no plan is possible" in err
    assert not (tmp_path / "mc").exists()


def test_no_markers_place(capsys, tmp_path, bare):
    out = tmp_path / "placed.toml"
    code, stdout, err = run_cli(capsys, "place", bare, "-o", out, "--json")
    doc = json.loads(stdout)
    assert code == 0 and doc["count"] >= 2 and doc["uncovered"] == []
    placed = scenarios.load(out)
    assert len(placed.markers) == doc["count"] and placed.routes.segments == scenarios.load(bare).routes.segments
    assert placed.dock("A").node == "0"
    code, stdout, _ = run_cli(capsys, "plan", out, "--json")
    assert code == 0 and json.loads(stdout)["chosen"] is not None


def test_workspace_origin_frame(capsys, tmp_path):
    # a hall whose lower-left corner is (100, 50) in the user's frame: graph, markers and outputs all in it
    g = nav2_graph()
    for f in g["features"]:
        if f["geometry"]["type"] == "Point":
            x, y = f["geometry"]["coordinates"]
            f["geometry"]["coordinates"] = [x + 100.0, y + 50.0]
    write(tmp_path / "graph.geojson", g)
    text = (scenario_text('file = "graph.geojson"', NODE_DOCKS, extra=TASK)
            .replace("size = [20.0, 10.0]", "size = [20.0, 10.0]\norigin = [100.0, 50.0]")
            .replace("center = [10.0, 5.0]", "center = [110.0, 55.0]"))
    for x, y in [(0.0, 0.0), (20.0, 0.0), (20.0, 10.0), (0.0, 10.0)]:
        text = text.replace(f"position = [{x}, {y}]", f"position = [{x + 100.0}, {y + 50.0}]")
    path = tmp_path / "o.toml"
    path.write_text(text, encoding="utf-8")
    sc = scenarios.load(path)
    assert sc.routes.nodes["0"] == (102.0, 52.0) and sc.dock("B").position == (118.0, 52.0)
    assert sc.routes.why_not(6) == "crosses obstacles[0]"
    out, mk = tmp_path / "o.geojson", tmp_path / "o.csv"
    assert run_cli(capsys, "export", path, "--routes", out, "--markers", mk)[0] == 0
    nodes, edges = features(json.loads(out.read_text()))
    assert nodes[2]["geometry"]["coordinates"] == [118.0, 52.0]
    assert edges[12]["properties"]["admissible"] is True
    assert next(csv.DictReader(mk.open()))["x_mm"] == "100000.000"
    rings = region_contours(PEF(sc).grid(), sc.planning.eps_max, sc.workspace.bounds)
    pts = np.vstack(rings)
    assert pts[:, 0].min() >= 100.0 and pts[:, 0].max() <= 120.0 and pts[:, 1].min() >= 50.0


def test_lif_ids_are_renumbered_for_nav2(capsys, tmp_path):
    from tests.scenarios.graphfiles import lif_file

    write(tmp_path / "plant.lif.json", lif_file())
    path = tmp_path / "l.toml"
    path.write_text(scenario_text('file = "plant.lif.json"\nlayout = "L2"\ntraffic = { "q-p" = 0.5 }'),
                    encoding="utf-8")
    sc = scenarios.load(path)
    assert sc.routes.traffic_of("p", "q") == 0.5
    out = tmp_path / "l.geojson"
    assert run_cli(capsys, "export", path, "--routes", out)[0] == 0
    nodes, edges = features(json.loads(out.read_text()))
    # Nav2 needs integer ids unique across nodes and edges: LIF's string ids are kept as source_id
    assert {i: f["properties"]["source_id"] for i, f in nodes.items()} == {0: "p", 1: "q", 2: "r"}
    assert {i: (f["properties"]["source_id"], f["properties"]["startid"], f["properties"]["endid"])
            for i, f in edges.items()} == {3: ("pq", 0, 1), 4: ("qr", 1, 2)}
    assert edges[3]["properties"]["vehicleTypeEdgeProperties"][0]["rotationAllowed"] is True


def test_traffic_keys_of_an_imported_graph(tmp_path):
    write(tmp_path / "graph.geojson", nav2_graph())
    path = tmp_path / "t.toml"
    path.write_text(scenario_text('file = "graph.geojson"\ntraffic = { "0-5" = 0.5 }'), encoding="utf-8")
    with pytest.raises(scenarios.ScenarioError, match=r'routes\.traffic\."0-5": expected a segment "a-b" of the '
                                                      r"route network, got 0\.5$"):
        scenarios.load(path)
