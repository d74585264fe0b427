"""[floorplan] through the loader: merged obstacles and markers, workspace from the extent, errors."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

import scenarios
from scenarios import ScenarioError
from scenarios.floorplan import FloorPlanKind
from tests.scenarios import drawings as dr
from tests.scenarios.worlds import DXF, scenario_text

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture()
def folder(tmp_path):
    dr.write_hall(tmp_path / "hall.dxf")
    dr.write_map(tmp_path, dr.map_image())
    return tmp_path


def load(folder: Path, text: str, name: str = "fp.toml"):
    path = folder / name
    path.write_text(text)
    return scenarios.load(path)


def test_drawing_merges_after_hand_written_items_and_sets_the_workspace(folder):
    s = load(folder, scenario_text(DXF, '[[obstacles]]\ncenter = [20.0, 17.0]\nsize = [1.0, 1.0]'))
    assert s.obstacles[0].kind == "box"  # hand-written first: its index in messages is the file's
    assert [o.kind for o in s.obstacles[1:]].count("polygon") == 6
    assert [o.kind for o in s.obstacles[1:]].count("circle") == 3
    assert [m.id for m in s.markers] == ["M1", "M2", "W1", "W2", "R1", "R2"]
    assert s.markers[2].position == pytest.approx((10.0, 0.1))
    assert s.markers[2].facing == pytest.approx(math.pi / 2)
    assert s.markers[5].facing is None  # a POINT has no direction
    assert s.workspace.origin == pytest.approx((-0.1, -0.1))
    assert s.workspace.size == pytest.approx((30.2, 20.2))
    plan = s.floorplan
    assert plan.kind is FloorPlanKind.DXF and plan.file == (folder / "hall.dxf").resolve()
    assert (plan.units, plan.unit_factor) == ("mm", 1e-3)
    assert plan.obstacle_layers == ("A-WALL", "A-RACK", "S-COLS") and plan.marker_layer == "AGV-REFL"
    assert plan.extent == pytest.approx((-0.1, -0.1, 30.1, 20.1))
    # The ring wall's hole is free: a point inside it is in no obstacle.
    assert not any(o.geometry().covers(__import__("shapely").Point(5.0, 15.0)) for o in s.obstacles)


def test_given_workspace_values_override_the_extent(folder):
    s = load(folder, scenario_text(DXF, "[workspace]\norigin = [-1.0, -1.0]"))
    assert s.workspace.origin == (-1.0, -1.0)
    assert s.workspace.size == pytest.approx((31.1, 21.1))  # to the far corner of the drawing
    s = load(folder, scenario_text(DXF, "[workspace]\nsize = [40.0, 30.0]"))
    assert s.workspace.size == (40.0, 30.0) and s.workspace.origin == pytest.approx((-0.1, -0.1))


def test_relative_file_is_relative_to_the_scenario_and_the_text_loads_anywhere(folder, tmp_path_factory,
                                                                               monkeypatch):
    monkeypatch.chdir(tmp_path_factory.mktemp("elsewhere"))
    s = load(folder, scenario_text(DXF))
    assert s.floorplan.file == (folder / "hall.dxf").resolve()
    # The text kept with results (pefsim mc) names the drawing absolutely: it loads from anywhere.
    again = scenarios.loads(s.text, source="copy.toml")
    assert again.obstacles == s.obstacles and again.markers == s.markers and again.floorplan == s.floorplan


def test_ros_map_scenario_workspace_is_the_map(folder):
    text = scenario_text('file = "map.yaml"\nsimplify = 0.0')
    for a, b in (("[3.0, 3.0]", "[2.0, 1.5]"), ("[3.5, 3.0]", "[2.0, 1.6]"), ("[3.0, 2.0, 0.0]", "[2.5, 1.6, 0.0]")):
        text = text.replace(a, b)
    s = load(folder, text)
    assert s.workspace.origin == (-1.0, -2.0) and s.workspace.size == pytest.approx((5.0, 4.0))
    assert s.floorplan.kind is FloorPlanKind.ROSMAP and s.floorplan.simplify == 0.0
    img = dr.map_image()
    assert sum(o.geometry().area for o in s.obstacles) == pytest.approx(float((img == dr.OCCUPIED).sum()) * 0.05 ** 2)
    assert sum(o.geometry().area for o in s.unknown) == pytest.approx(float((img == dr.UNKNOWN).sum()) * 0.05 ** 2)
    assert not s.workspace.walls


@pytest.mark.parametrize("floorplan, pattern", [
    ('file = "gone.dxf"\nobstacle_layers = ["A"]',
     r'fp.toml: floorplan.file: cannot read .*gone.dxf: no such file, got "gone.dxf"$'),
    ('file = "hall.svg"\nobstacle_layers = ["A"]',
     r'fp.toml: floorplan.file: expected a DXF drawing \(.dxf\) or a ROS'),
    ('file = "hall.dxf"', r"fp.toml: floorplan.obstacle_layers: missing required key$"),
    ('file = "hall.dxf"\nobstacle_layers = "A-WALL"', r'fp.toml: floorplan.obstacle_layers: expected a non-empty list'),
    ('file = "hall.dxf"\nobstacle_layers = ["WALLS"]',
     r'fp.toml: floorplan.obstacle_layers: expected a layer of hall.dxf \(0, A-RACK, A-WALL, AGV-REFL, .*got "WALLS"$'),
    (DXF + '\nunits = "furlong"', r'fp.toml: floorplan.units: expected one of "m", "mm", .*got "furlong"$'),
    (DXF + "\nwall_thickness = 0", r"fp.toml: floorplan.wall_thickness: expected a number > 0, got 0.0$"),
    (DXF + "\nlayers = 1", r"fp.toml: floorplan.layers: unknown key, got 1$"),
    ('file = "map.yaml"\nmarker_layer = "R"', r'fp.toml: floorplan.marker_layer: expected no such key for a ROS map'),
    ('file = "bad.yaml"', r"fp.toml: floorplan.file: bad.yaml: resolution: missing required key$"),
    ('file = "empty.dxf"\nobstacle_layers = ["0"]',
     r"fp.toml: floorplan.obstacle_layers: expected lines, .*found none"),
    ('file = "inside.dxf"\nobstacle_layers = ["A-RACK"]\nmarker_layer = "AGV-REFL"',
     r'fp.toml: floorplan.marker_layer: expected reflectors outside obstacles .*inside.dxf: "X" at \[15.0, 5.0\]'),
])
def test_bad_floorplans_give_one_line_naming_file_and_key(folder, floorplan, pattern):
    (folder / "bad.yaml").write_text("image: map.pgm\norigin: [0, 0, 0]\n")
    import ezdxf

    doc = ezdxf.new()
    doc.saveas(folder / "empty.dxf")
    doc = dr.hall_doc()
    ref = doc.modelspace().add_blockref("REFL", (15000, 5000), dxfattribs={"layer": "AGV-REFL"})
    ref.add_auto_attribs({"ID": "X"})  # in the middle of a rack
    doc.saveas(folder / "inside.dxf")
    with pytest.raises(ScenarioError, match=pattern) as err:
        load(folder, scenario_text(floorplan))
    assert "\n" not in str(err.value)


def test_cli_prints_one_line_and_exits_2(folder):
    (folder / "fp.toml").write_text(scenario_text('file = "hall.dxf"\nobstacle_layers = ["WALLS"]'))
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    p = subprocess.run([sys.executable, "-m", "cli", "map", "fp.toml"], cwd=folder, env=env,
                       capture_output=True, text=True)
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1
    assert p.stderr.startswith('pefsim: error: fp.toml: floorplan.obstacle_layers: expected a layer of hall.dxf')


def test_builtin_hall_is_the_drawing_its_generator_writes(tmp_path):
    s = scenarios.load("hall")
    assert s.floorplan.file.name == "hall.dxf" and s.floorplan.units == "mm"
    assert len(s.markers) == 12 and all(m.facing is not None for m in s.markers)
    # Regenerating the drawing gives the same obstacles and markers (the shipped file is current).
    out = tmp_path / "hall.dxf"
    subprocess.run([sys.executable, str(ROOT / "scenarios/library/make_hall.py"), str(out)], check=True,
                   capture_output=True)
    text = (ROOT / "scenarios/library/hall.toml").read_text()
    fresh = scenarios.loads(text.replace('file = "hall.dxf"', f'file = "{out}"'), source="hall.toml")
    assert fresh.obstacles == s.obstacles and fresh.markers == s.markers


def test_outlines_whose_holes_touch_at_a_point_still_load(tmp_path):
    import ezdxf

    doc = ezdxf.new()
    doc.header["$INSUNITS"] = 6
    msp = doc.modelspace()
    # A slab with two cut-outs that meet at a corner, and one touching the slab's edge.
    for ring in ([(0, 0), (10, 0), (10, 10), (0, 10)], [(2, 2), (5, 2), (5, 5), (2, 5)],
                 [(5, 5), (8, 5), (8, 8), (5, 8)], [(0, 5), (1, 4), (1, 6)]):
        msp.add_lwpolyline(ring, close=True)
    doc.saveas(tmp_path / "slab.dxf")
    text = scenario_text('file = "slab.dxf"\nobstacle_layers = ["0"]', "[workspace]\norigin = [-1.0, -1.0]\n"
                         "size = [12.0, 12.0]").replace(
        "[3.0, 2.0, 0.0]", "[6.5, 6.5, 0.0]").replace("[3.5, 3.0]", "[4.0, 4.0]")
    s = load(tmp_path, text)
    (slab,) = s.obstacles
    assert len(slab.holes) == 3
    assert slab.geometry().area == pytest.approx(100.0 - 9.0 - 9.0 - 1.0, abs=1e-4)


def test_facing_deg_key_of_hand_written_markers(folder):
    s = load(folder, scenario_text(DXF).replace('position = [3.0, 3.0]', 'position = [3.0, 3.0]\nfacing_deg = 30.0'))
    assert s.markers[0].facing == pytest.approx(math.radians(30.0)) and s.markers[1].facing is None

