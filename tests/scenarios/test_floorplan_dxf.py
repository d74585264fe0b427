"""DXF floor plans: geometry against the drawing (ezdxf-written, see tests/scenarios/drawings.py), units, errors."""

from __future__ import annotations

import math

import ezdxf
import pytest
import shapely

from scenarios import ScenarioError
from scenarios.floorplan.dxf import read_dxf
from tests.scenarios import drawings as dr

LAYERS = ["A-WALL", "A-RACK", "S-COLS"]


def shapes(data):
    """Obstacle dicts -> (polygons, circles) with polygons as shapely objects."""
    polys, circles = [], []
    for ob in data.obstacles:
        if "polygon" in ob:
            polys.append(shapely.Polygon(ob["polygon"], ob.get("holes", [])))
        else:
            circles.append((tuple(ob["center"]), ob["radius"]))
    return polys, circles


def at(polys, x, y):
    """Return the one polygon that covers (x, y)."""
    hit = [p for p in polys if p.covers(shapely.Point(x, y))]
    assert len(hit) == 1, f"{len(hit)} polygons cover ({x}, {y})"
    return hit[0]


@pytest.fixture(scope="module")
def hall(tmp_path_factory):
    path = dr.write_hall(tmp_path_factory.mktemp("dxf") / "hall.dxf")
    return read_dxf(path, obstacle_layers=LAYERS, marker_layer="AGV-REFL")


def test_walls_of_lines_become_one_ring_of_wall_thickness(hall):
    polys, _ = shapes(hall)
    wall = at(polys, 15.0, 0.0)
    assert wall.bounds == pytest.approx((-0.1, -0.1, 30.1, 20.1))
    assert len(wall.interiors) == 1
    assert shapely.Polygon(wall.interiors[0]).bounds == pytest.approx((0.1, 0.1, 29.9, 19.9))
    assert wall.area == pytest.approx(30.2 * 20.2 - 29.8 * 19.8)
    # The corners are closed (square caps), the hall inside is free.
    assert wall.covers(shapely.Point(30.05, 20.05))
    assert not wall.covers(shapely.Point(15.0, 10.0))


def test_nested_closed_outlines_are_a_ring_wall(hall):
    polys, _ = shapes(hall)
    ring = at(polys, 2.1, 15.0)
    assert ring.area == pytest.approx(dr.RING_AREA)
    assert len(ring.interiors) == 1
    assert not ring.covers(shapely.Point(5.0, 15.0))  # inside the inner outline: free


def test_closed_polylines_hatch_and_bulges_are_filled(hall):
    polys, _ = shapes(hall)
    rack = at(polys, 18.0, 5.0)
    assert rack.area == pytest.approx(dr.RACK_AREA)
    assert rack.bounds == pytest.approx((10.0, 4.0, 26.0, 6.0))
    round_rack = at(polys, 15.0, 9.0)
    # The half disc is flattened within simplify (0.02 m): the area loss is at most its arc
    # length times the tolerance.
    assert round_rack.bounds[2] == pytest.approx(21.0, abs=0.02)
    assert abs(round_rack.area - dr.ROUND_RACK_AREA) < math.pi * 0.02
    assert round_rack.area < dr.ROUND_RACK_AREA  # chords lie inside the arc
    assert at(polys, 13.0, 15.0).area == pytest.approx(dr.HATCH_AREA)


def test_block_insert_is_rotated_scaled_and_nested_and_takes_its_layer(hall):
    polys, circles = shapes(hall)
    block = at(polys, 15.0, 15.9)
    assert block.area == pytest.approx(dr.BLOCK_AREA)
    assert block.bounds == pytest.approx((14.5, 14.0, 15.5, 16.0))  # 1 x 0.5 scaled 2, turned 90°
    # (x, y, r) flattened in sorted order: pytest.approx compares flat sequences only (pytest 9)
    flat = [v for (x, y), r in sorted(circles) for v in (x, y, r)]
    assert flat == pytest.approx([5.0, 5.0, 0.3, 15.0, 17.0, 0.2, 25.0, 15.0, 0.3])


def test_text_dimension_and_other_layers_are_ignored(hall):
    polys, circles = shapes(hall)
    assert len(polys) == 6 and len(circles) == 3
    # FURN's line at y = 1 and the dimension line at y = -2 add nothing.
    assert not any(p.intersects(shapely.Point(2.0, 1.0)) for p in polys)
    assert hall.extent == pytest.approx((-0.1, -0.1, 30.1, 20.1))


def test_reflectors_ids_from_attributes_else_generated_in_drawing_order(hall):
    got = {m["id"]: (tuple(m["position"]), m.get("facing_deg")) for m in hall.markers}
    assert [m["id"] for m in hall.markers] == ["W1", "W2", "R1", "R2"]
    for mid, (pos, facing) in dr.MARKERS.items():
        assert got[mid][0] == pytest.approx(pos)
        assert got[mid][1] == (pytest.approx(facing) if facing is not None else None)


def test_units_from_insunits_or_the_units_key(tmp_path):
    mm = read_dxf(dr.write_hall(tmp_path / "mm.dxf"), obstacle_layers=LAYERS)
    assert (mm.units, mm.unit_factor) == ("mm", 1e-3)
    # Drawn in cm without $INSUNITS: the key says so.
    cm = read_dxf(dr.write_hall(tmp_path / "cm.dxf", insunits=0, scale=0.1), obstacle_layers=LAYERS, units="cm")
    assert cm.unit_factor == 0.01
    assert shapes(cm)[0][0].area == pytest.approx(shapes(mm)[0][0].area)
    assert cm.extent == pytest.approx(mm.extent)
    # The key overrides $INSUNITS: the same mm drawing read as metres is 1000 times larger.
    m = read_dxf(tmp_path / "mm.dxf", obstacle_layers=["A-RACK"], units="m", simplify=20.0)
    assert at(shapes(m)[0], 18000.0, 5000.0).area == pytest.approx(dr.RACK_AREA * 1e6)


def test_marker_ids_unique_and_generated_ids_skip_given_ones(tmp_path):
    doc = dr.hall_doc()
    msp = doc.modelspace()
    ref = msp.add_blockref("REFL", (5000, 100), dxfattribs={"layer": "AGV-REFL"})
    ref.add_auto_attribs({"ID": "R3"})
    doc.saveas(tmp_path / "h.dxf")
    ids = [m["id"] for m in read_dxf(tmp_path / "h.dxf", obstacle_layers=LAYERS, marker_layer="AGV-REFL").markers]
    assert ids == ["W1", "W2", "R1", "R2", "R3"]
    ref = msp.add_blockref("REFL", (6000, 100), dxfattribs={"layer": "AGV-REFL"})
    ref.add_auto_attribs({"ID": "W1"})
    doc.saveas(tmp_path / "dup.dxf")
    with pytest.raises(ScenarioError, match=r'marker_layer: expected unique reflector IDs in .*dup.dxf, got "W1" tw'):
        read_dxf(tmp_path / "dup.dxf", obstacle_layers=LAYERS, marker_layer="AGV-REFL")


def test_layer_names_are_case_insensitive(tmp_path):
    data = read_dxf(dr.write_hall(tmp_path / "h.dxf"), obstacle_layers=["a-rack"], marker_layer="agv-refl")
    assert len(data.obstacles) == 3 and len(data.markers) == 4


@pytest.mark.parametrize("kwargs, pattern", [
    ({"obstacle_layers": ["A-WALL", "WALLS"]},
     r'h.dxf: floorplan.obstacle_layers: expected a layer of h.dxf \(0, A-RACK, A-WALL, AGV-REFL, .*\), got "WALLS"$'),
    ({"obstacle_layers": ["A-WALL"], "marker_layer": "REFL"}, r'marker_layer: expected a layer of .*got "REFL"'),
    ({"obstacle_layers": ["EMPTY", "FURN"]}, None),
    ({"obstacle_layers": ["EMPTY"]}, r"obstacle_layers: expected lines, .* found none, got \[\"EMPTY\"\]"),
    ({"obstacle_layers": ["A-WALL"], "marker_layer": "EMPTY"}, r'marker_layer: expected POINTs, .* found none'),
])
def test_bad_layers(tmp_path, kwargs, pattern):
    path = dr.write_hall(tmp_path / "h.dxf")
    if pattern is None:
        assert len(read_dxf(path, shown="h.dxf", **kwargs).obstacles) == 1  # FURN's line is a wall
        return
    with pytest.raises(ScenarioError, match=pattern):
        read_dxf(path, shown="h.dxf", **kwargs)


def test_no_units_missing_and_unreadable_files(tmp_path):
    dr.write_hall(tmp_path / "nounits.dxf", insunits=0)
    with pytest.raises(ScenarioError, match=r"floorplan.units: expected the drawing's units \(.*nounits.dxf has "
                                            r"\$INSUNITS = 0, unitless\): set floorplan.units to one of m, mm"):
        read_dxf(tmp_path / "nounits.dxf", obstacle_layers=LAYERS)
    with pytest.raises(ScenarioError, match=r"floorplan.file: cannot read .*gone.dxf: No such file"):
        read_dxf(tmp_path / "gone.dxf", obstacle_layers=LAYERS)
    (tmp_path / "junk.dxf").write_bytes(b"\x89PNG\r\n\x1a\n not a drawing at all")
    with pytest.raises(ScenarioError, match=r"floorplan.file: expected a DXF drawing, cannot read .*junk.dxf"):
        read_dxf(tmp_path / "junk.dxf", obstacle_layers=LAYERS)
    (tmp_path / "plan.dwg").write_bytes(b"AC1032")
    with pytest.raises(ScenarioError, match=r"floorplan.file: expected a DXF drawing \(save or convert"):
        read_dxf(tmp_path / "plan.dwg", obstacle_layers=LAYERS)


def test_minsert_grid_and_ezdxf_r12_polylines(tmp_path):
    doc = ezdxf.new("R2000")
    doc.header["$INSUNITS"] = 6
    doc.layers.add("RACK")
    blk = doc.blocks.new("BAY")
    blk.add_lwpolyline([(0, 0), (2, 0), (2, 1), (0, 1)], close=True)
    msp = doc.modelspace()
    msp.add_blockref("BAY", (0, 0), dxfattribs={"layer": "RACK"}).grid(size=(1, 3), spacing=(0, 4))
    msp.add_polyline2d([(0, 10), (5, 10), (5, 12)], dxfattribs={"layer": "RACK"})  # open: a wall
    doc.saveas(tmp_path / "g.dxf")
    polys, _ = shapes(read_dxf(tmp_path / "g.dxf", obstacle_layers=["RACK"], wall_thickness=0.1))
    # the wall: 7 m of centre line, 0.1 m thick, plus two square caps of 0.05 x 0.1 m
    assert sorted(p.area for p in polys) == pytest.approx([0.1 * 7.0 + 0.01, 2.0, 2.0, 2.0])


def test_a_wide_open_polyline_is_a_wall_of_its_width(tmp_path):
    doc = ezdxf.new()
    doc.header["$INSUNITS"] = 4
    doc.modelspace().add_lwpolyline([(0, 0), (4000, 0)], dxfattribs={"const_width": 300})
    doc.modelspace().add_line((0, 2000), (4000, 2000))
    doc.saveas(tmp_path / "w.dxf")
    polys, _ = shapes(read_dxf(tmp_path / "w.dxf", obstacle_layers=["0"], wall_thickness=0.1))
    assert at(polys, 2.0, 0.0).area == pytest.approx((4.0 + 0.3) * 0.3)   # square caps of half the width
    assert at(polys, 2.0, 2.0).area == pytest.approx((4.0 + 0.1) * 0.1)


def test_circle_reflectors_and_reflectors_nested_in_blocks(tmp_path):
    doc = ezdxf.new()
    doc.header["$INSUNITS"] = 4
    doc.layers.add("REFL")
    msp = doc.modelspace()
    msp.add_line((0, 0), (10000, 0))
    msp.add_circle((3000, 100), 40, dxfattribs={"layer": "REFL"})
    tag = doc.blocks.new("TAG")
    tag.add_circle((0, 0), 30)
    # A dock block carrying a reflector 1 m ahead of it, turned 10° within the block.
    dock = doc.blocks.new("DOCK")
    dock.add_lwpolyline([(-200, -200), (200, -200), (200, 200), (-200, 200)], close=True)
    dock.add_blockref("TAG", (1000, 0), dxfattribs={"layer": "REFL", "rotation": 10.0})
    msp.add_blockref("DOCK", (5000, 3000), dxfattribs={"rotation": 90.0})
    doc.saveas(tmp_path / "n.dxf")
    data = read_dxf(tmp_path / "n.dxf", obstacle_layers=["0"], marker_layer="REFL")
    assert [m["id"] for m in data.markers] == ["R1", "R2"]
    assert data.markers[0]["position"] == pytest.approx([3.0, 0.1]) and "facing_deg" not in data.markers[0]
    assert data.markers[1]["position"] == pytest.approx([5.0, 4.0])  # (1, 0) turned 90° about (5, 3)
    assert data.markers[1]["facing_deg"] == pytest.approx(100.0)
    polys, _ = shapes(data)
    assert at(polys, 5.0, 3.0).area == pytest.approx(0.16)  # the dock outline, on layer 0
