"""Exports for the tools downstream: DXF labels that do not overlap, VDA LIF, the Nav2 keepout mask.

Each is read back with something other than the writer: the DXF with ezdxf, the LIF by pefsim's
own LIF reader (``[routes] file``), the keepout mask by pefsim's map_server reader (``[floorplan]``)
and its pixels against the PEF evaluated directly.
"""

from __future__ import annotations

import dataclasses
import itertools
import json

import ezdxf
import numpy as np
import pytest

import pefsim
import scenarios
from cli import main
from interop.export.dxf import BAD_ROUTE_LAYER, LABEL_HEIGHT, ROUTE_LAYER
from interop.export.labels import label_box, overlap
from interop.export.region import route_lines
from planner.pef.map import PEF

ROUTED = [n for n in scenarios.builtin_names() if scenarios.load(n).routes is not None]


def label_boxes(path):
    msp = ezdxf.readfile(path).modelspace()
    texts = [e for layer in (ROUTE_LAYER, BAD_ROUTE_LAYER) for e in msp.query(f'TEXT[layer=="{layer}"]')]
    return [label_box(e.dxf.text, (e.dxf.insert.x, e.dxf.insert.y), e.dxf.height) for e in texts]


@pytest.mark.parametrize("name", ROUTED)
def test_dxf_route_labels_do_not_overlap_on_the_builtins(name, tmp_path):
    out = tmp_path / "d.dxf"
    pefsim.export(name, dxf=out)
    boxes = label_boxes(out)
    assert len(boxes) == len(scenarios.load(name).routes.segments)
    assert not [(a, b) for a, b in itertools.combinations(boxes, 2) if overlap(a, b)]


def test_label_overlap_negative_control():
    # the old placement, each label at its segment's first node: labels of edges from one node collide
    sc = scenarios.load("warehouse")
    boxes = [label_box(f"{rid} max tau 10.0 mm", line[0], LABEL_HEIGHT) for rid, line in route_lines(sc)]
    assert any(overlap(a, b) for a, b in itertools.combinations(boxes, 2))


def graph_lif(tmp_path, name="warehouse"):
    out = tmp_path / "routes.lif"
    pefsim.export(name, lif=out)
    return out


def test_lif_keeps_every_id_and_carries_tau_at_nodes(tmp_path):
    sc = scenarios.load("warehouse")
    out = graph_lif(tmp_path)
    doc = json.loads(out.read_text())
    assert {"projectIdentification", "creator", "exportTimestamp", "lifVersion"} <= set(doc["metaInformation"])
    (lay,) = doc["layouts"]
    net = sc.routes
    assert sorted(n["nodeId"] for n in lay["nodes"]) == sorted(net.node_ids[n] for n in net.nodes)
    assert sorted(e["edgeId"] for e in lay["edges"]) == sorted(i for e in net.edges for i in e.ids)
    assert all(n["vehicleTypeNodeProperties"] and e["vehicleTypeEdgeProperties"]
               for n, e in zip(lay["nodes"], lay["edges"], strict=False))
    by_id = {net.node_ids[n]: n for n in net.nodes}
    names = [by_id[n["nodeId"]] for n in lay["nodes"]]
    tau = PEF(sc).at([net.nodes[n] for n in names]).tau
    got = np.array([n["nodePosition"].get("allowedDeviationXY", np.inf) for n in lay["nodes"]])
    np.testing.assert_array_equal(got, tau)  # the PEF's own numbers, inf written as absent
    assert np.isfinite(got).any()
    # read back by pefsim: a scenario on the exported file has the same nodes, segments and ids
    back_path = tmp_path / "back.toml"  # the warehouse without its docks, tasks and hand-written routes
    back_path.write_text(sc.text.split("[[docks]]")[0] + f'[routes]\nfile = "{out.name}"\n')
    back = scenarios.load(back_path).routes
    assert sorted(back.nodes) == sorted(n["nodeId"] for n in lay["nodes"])
    assert sorted(i for e in back.edges for i in e.ids) == sorted(i for e in net.edges for i in e.ids)
    assert all(back.nodes[net.node_ids[n]] == net.nodes[n] for n in net.nodes)


def test_lif_of_a_lif_input_keeps_the_file_and_sets_the_deviation(tmp_path):
    first = graph_lif(tmp_path)
    doc = json.loads(first.read_text())
    first_node = doc["layouts"][0]["nodes"][0]["nodeId"]
    doc["layouts"][0]["stations"] = [{"stationId": "S1", "interactionNodeIds": [first_node]}]
    doc["layouts"][0]["nodes"][0]["nodePosition"]["allowedDeviationXY"] = 99.0  # stale: must be replaced
    src = tmp_path / "in.lif"
    src.write_text(json.dumps(doc))
    sc_path = tmp_path / "lif.toml"
    base = scenarios.load("warehouse").text.split("[[docks]]")[0]
    sc_path.write_text(base + f'[routes]\nfile = "{src.name}"\n')
    out = tmp_path / "again.lif"
    pefsim.export(sc_path, lif=out)
    again = json.loads(out.read_text())
    assert again["layouts"][0]["stations"] == doc["layouts"][0]["stations"]
    assert [n["nodeId"] for n in again["layouts"][0]["nodes"]] == [n["nodeId"] for n in doc["layouts"][0]["nodes"]]
    assert [e["edgeId"] for e in again["layouts"][0]["edges"]] == [e["edgeId"] for e in doc["layouts"][0]["edges"]]
    assert again["layouts"][0]["nodes"][0]["nodePosition"].get("allowedDeviationXY") != 99.0


def test_keepout_mask_is_the_navigation_region(tmp_path):
    from PIL import Image

    sc = scenarios.load("warehouse")
    yml = tmp_path / "keepout.yaml"
    written = pefsim.export(sc, keepout=yml)["keepout"]
    assert [p.name for p in written] == ["keepout.yaml", "keepout.pgm"]
    import yaml

    meta = yaml.safe_load(yml.read_text())
    assert meta["image"] == "keepout.pgm" and meta["mode"] == "trinary" and meta["negate"] == 0
    img = np.asarray(Image.open(tmp_path / "keepout.pgm"))
    res, (ox, oy) = meta["resolution"], meta["origin"][:2]
    h, w = img.shape
    xs, ys = ox + (np.arange(w) + 0.5) * res, oy + (np.arange(h)[::-1] + 0.5) * res  # row 0 is the top
    gx, gy = np.meshgrid(xs, ys)
    pts = np.column_stack([gx.ravel(), gy.ravel()])
    tau = PEF(sc).at(pts).tau
    outside = np.zeros(len(pts), dtype=bool)
    for ob in sc.obstacles:
        outside |= ob.contains_points(pts)
    region = (tau < sc.planning.eps_max) & ~outside
    assert 0 < region.sum() < len(pts)  # both kinds of cell
    np.testing.assert_array_equal(img.ravel() == 254, region)
    assert set(np.unique(img)) <= {0, 254}
    # pefsim's own map_server reader takes it as a floor plan: its obstacles are the keepout
    fp = tmp_path / "fp.toml"
    fp.write_text(f'name = "k"\n[floorplan]\nfile = "{yml.name}"\n[sensor]\n[planning]\neps_max = 0.03\n')
    assert scenarios.load(fp).obstacles


def test_keepout_of_a_map_is_on_the_maps_grid(tmp_path):
    """A map-based scenario's mask has the source map's resolution, origin and size (Nav2 lays it over)."""
    import yaml
    from PIL import Image

    from tests.scenarios import drawings as dr

    dr.write_map(tmp_path, dr.room_map(), origin=(*dr.ROOM_ORIGIN, 0.0))
    (tmp_path / "room.toml").write_text(dr.room_text())
    sc = scenarios.load(tmp_path / "room.toml")
    source = yaml.safe_load((tmp_path / "map.yaml").read_text())
    yml = tmp_path / "keepout.yaml"
    pefsim.export(sc, keepout=yml)
    meta = yaml.safe_load(yml.read_text())
    img = np.asarray(Image.open(tmp_path / "keepout.pgm"))
    assert meta["resolution"] == source["resolution"] and meta["origin"] == source["origin"]
    assert img.shape == dr.ROOM_SHAPE
    # unknown cells, and everything outside the known area, are kept out
    assert (img[dr.room_map() == dr.UNKNOWN] == 0).all()
    # negative control: the same world without its map is masked on the PEF's grid over the workspace
    plain = dataclasses.replace(sc, floorplan=None)
    pefsim.export(plain, keepout=tmp_path / "plain.yaml")
    meta = yaml.safe_load((tmp_path / "plain.yaml").read_text())
    assert meta["origin"][:2] == list(sc.workspace.origin)
    assert np.asarray(Image.open(tmp_path / "plain.pgm")).shape == (80, 120)  # 4 x 6 m of 5 cm, not 5 x 7 m


@pytest.mark.parametrize("flag,name", [("--lif", "out.geojson"), ("--keepout", "mask.pgm"), ("--dxf", "d.dwg"),
                                       ("--markers", "m.txt"), ("--routes", "r.lif")])
def test_export_format_from_extension_or_one_line_refusal(capsys, tmp_path, flag, name):
    code = main(["export", "warehouse", flag, str(tmp_path / name)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "expected a ." in err
    assert not list(tmp_path.iterdir())
