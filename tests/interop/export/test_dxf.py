"""DXF export: reflectors, region and routes on their layers, in the drawing's units; the round trip."""

from __future__ import annotations

import math

import ezdxf
import numpy as np
import pytest
import shapely

import scenarios
from interop.export.dxf import MARKER_LAYER, REGION_LAYER, ROUTE_LAYER, write_dxf
from scenarios.floorplan.dxf import read_dxf
from tests.scenarios import drawings as dr

SCENARIO = """
name = "fp"
[floorplan]
file = "hall.dxf"
obstacle_layers = ["A-WALL", "A-RACK", "S-COLS"]
marker_layer = "AGV-REFL"
[[markers]]
id = "M1"
position = [3.0, 3.0]
facing_deg = 45.0
[sensor]
[planning]
eps_max = 0.05
"""

_T = np.linspace(0, 2 * np.pi, 33)
CIRCLE = np.column_stack([15 + 2 * np.cos(_T), 11 + 2 * np.sin(_T)])  # closed: last point = first
OPEN = np.array([[0.1, 1.0], [5.0, 1.0], [5.0, 3.0]])
ROUTE = np.array([[3.0, 2.0], [5.0, 7.0], [25.0, 7.0]])


@pytest.fixture()
def hall(tmp_path):
    dr.write_hall(tmp_path / "hall.dxf")
    (tmp_path / "fp.toml").write_text(SCENARIO)
    return scenarios.load(tmp_path / "fp.toml")


def test_export_copies_the_drawing_and_adds_layers_in_its_units(hall, tmp_path):
    out = write_dxf(hall, tmp_path / "out.dxf", region_contours=[CIRCLE, OPEN], route_lines=[("R1", ROUTE)])
    assert out == tmp_path / "out.dxf"
    doc = ezdxf.readfile(out)
    assert doc.header["$INSUNITS"] == 4
    msp = doc.modelspace()
    # The original drawing is all there.
    original = ezdxf.readfile(tmp_path / "hall.dxf").modelspace()
    for layer in ("A-WALL", "A-RACK", "S-COLS", "AGV-REFL"):
        assert len(msp.query(f'*[layer=="{layer}"]')) == len(original.query(f'*[layer=="{layer}"]'))
    region = msp.query(f'LWPOLYLINE[layer=="{REGION_LAYER}"]')
    assert [p.closed for p in region] == [True, False]
    assert np.array(region[0].get_points("xy")) == pytest.approx(CIRCLE[:-1] * 1000.0)  # mm
    assert np.array(region[1].get_points("xy")) == pytest.approx(OPEN * 1000.0)
    route = msp.query(f'LWPOLYLINE[layer=="{ROUTE_LAYER}"]')[0]
    assert np.array(route.get_points("xy")) == pytest.approx(ROUTE * 1000.0)
    assert route.get_xdata("PEFSIM") == [(1000, "R1")]
    assert [t.dxf.text for t in msp.query(f'TEXT[layer=="{ROUTE_LAYER}"]')] == ["R1"]
    inserts = msp.query(f'INSERT[layer=="{MARKER_LAYER}"]')
    assert [i.get_attrib_text("ID") for i in inserts] == [m.id for m in hall.markers]
    assert inserts[0].dxf.rotation == pytest.approx(45.0)


def test_round_trip_gives_the_same_markers_and_ids(hall, tmp_path):
    write_dxf(hall, tmp_path / "out.dxf", region_contours=[], route_lines=[])
    back = read_dxf(tmp_path / "out.dxf", obstacle_layers=["A-WALL"], marker_layer=MARKER_LAYER)
    assert [m["id"] for m in back.markers] == [m.id for m in hall.markers]
    for got, m in zip(back.markers, hall.markers, strict=True):
        assert got["position"] == pytest.approx(m.position, abs=1e-9)
        assert got["facing_deg"] == pytest.approx(0.0 if m.facing is None else math.degrees(m.facing) % 360.0)
    # Exporting the export again replaces the PEFSIM layers instead of doubling them.
    (tmp_path / "fp2.toml").write_text(SCENARIO.replace("hall.dxf", "out.dxf").replace(
        'marker_layer = "AGV-REFL"', f'marker_layer = "{MARKER_LAYER}"').replace('id = "M1"', 'id = "M9"'))
    again = scenarios.load(tmp_path / "fp2.toml")
    write_dxf(again, tmp_path / "out2.dxf", region_contours=[], route_lines=[])
    ids = [i.get_attrib_text("ID") for i in ezdxf.readfile(tmp_path / "out2.dxf").modelspace().query(
        f'INSERT[layer=="{MARKER_LAYER}"]')]
    assert ids == [m.id for m in again.markers] and len(ids) == len(set(ids))


def test_a_scenario_without_drawing_gets_a_new_one_in_metres(tmp_path):
    s = scenarios.load("warehouse")
    write_dxf(s, tmp_path / "w.dxf", region_contours=[CIRCLE], route_lines=[("A-B", ROUTE)])
    doc = ezdxf.readfile(tmp_path / "w.dxf")
    assert doc.header["$INSUNITS"] == 6
    obstacles = doc.modelspace().query('LWPOLYLINE[layer=="PEFSIM-OBSTACLES"]')
    assert len(obstacles) == len(s.obstacles)
    back = read_dxf(tmp_path / "w.dxf", obstacle_layers=["PEFSIM-OBSTACLES"], marker_layer=MARKER_LAYER,
                    simplify=0.0)
    assert [m["id"] for m in back.markers] == s.marker_ids()
    area = shapely.union_all([shapely.Polygon(o["polygon"]) for o in back.obstacles]).area
    assert area == pytest.approx(shapely.union_all([o.geometry() for o in s.obstacles]).area)


def test_unwritable_path_is_one_output_error(hall, tmp_path):
    with pytest.raises(scenarios.OutputError, match=r"cannot write the DXF drawing"):
        write_dxf(hall, tmp_path / "no" / "such" / "dir.dxf", region_contours=[], route_lines=[])
