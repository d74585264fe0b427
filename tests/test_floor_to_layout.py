"""End to end: a real occupancy map and its route graph, no reflectors, to a layout.

A user with a ROS map (PGM + map_server YAML) and a Nav2 route graph runs the CLI as they
would: ``place`` puts reflectors, ``plan`` finds an admissible route whose every fix keeps its
promise under eps_max, ``run`` drives it, ``validate`` checks the predictions on a small
Monte-Carlo sweep, and ``export`` hands the graph back with every node and edge id.

The floor (metres, map frame): a 24 x 16 m hall (walls 0.2 m thick around 0..24 x 0..16, the
inside free), unknown space (205) outside the walls up to the map's border (-1, -1)..(25, 17);
two rack rows 4..20 x 5..6.2 and 4..20 x 9.8..11; two 0.4 x 0.4 m columns at (8, 15) and
(16, 15). The graph: a ladder through the aisles y = 2.5, 8, 13.5 with rungs at x = 2 and 22,
a spur to a dock 1 m from the west wall, and one edge pair along x = 23.7, 0.3 m from the east
wall's inner face: closer than the robot radius 0.4, so imported but inadmissible.
"""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import scenarios

# the whole loop of a user (map, place, plan, validate on a real sweep, export): the longest test
pytestmark = pytest.mark.e2e

REPO = Path(__file__).resolve().parents[1]
RES = 0.05                  # map resolution [m/cell]
ORIGIN = (-1.0, -1.0)       # map origin [m]
SIZE = (26.0, 18.0)         # map extent [m]
FREE, OCCUPIED, UNKNOWN = 254, 0, 205  # the shades map_saver writes
RUNS = 6                    # validate: the smallest sweep the CLI tests use for a verdict

NODES = {  # Nav2 node id -> (x, y) [m]
    1: (2.0, 2.5), 2: (12.0, 2.5), 3: (22.0, 2.5),
    4: (2.0, 8.0), 5: (12.0, 8.0), 6: (22.0, 8.0),
    7: (2.0, 13.5), 8: (12.0, 13.5), 9: (22.0, 13.5),
    10: (1.0, 8.0),                     # dock A, 1 m from the west wall
    11: (23.7, 4.0), 12: (23.7, 12.0),  # the grazing pair, 0.3 m from the east wall
}
PAIRS = [(1, 2), (2, 3), (4, 5), (5, 6), (7, 8), (8, 9), (1, 4), (4, 7), (3, 6), (6, 9), (10, 4), (11, 12)]
GRAZING = (11, 12)


def map_image() -> np.ndarray:
    """Draw the hall as a map image (H, W) uint8, row 0 at the top (y = 17 m)."""
    h, w = round(SIZE[1] / RES), round(SIZE[0] / RES)
    img = np.full((h, w), UNKNOWN, dtype=np.uint8)

    def fill(x0, y0, x1, y1, shade):
        # metres -> cells; image rows count from the top of the map
        c0, c1 = round((x0 - ORIGIN[0]) / RES), round((x1 - ORIGIN[0]) / RES)
        r0, r1 = h - round((y1 - ORIGIN[1]) / RES), h - round((y0 - ORIGIN[1]) / RES)
        img[r0:r1, c0:c1] = shade

    fill(-0.2, -0.2, 24.2, 16.2, OCCUPIED)   # walls 0.2 m thick around ...
    fill(0.0, 0.0, 24.0, 16.0, FREE)         # ... the free hall
    fill(4.0, 5.0, 20.0, 6.2, OCCUPIED)      # rack rows
    fill(4.0, 9.8, 20.0, 11.0, OCCUPIED)
    for cx, cy in ((8.0, 15.0), (16.0, 15.0)):  # columns
        fill(cx - 0.2, cy - 0.2, cx + 0.2, cy + 0.2, OCCUPIED)
    return img


def route_graph() -> dict:
    """Build the Nav2 route graph: nodes 1-12, each pair as two directed LineString edges 100, 101, ..."""
    feats = [{"type": "Feature", "geometry": {"type": "Point", "coordinates": list(xy)},
              "properties": {"id": i, "frame": "map"}} for i, xy in NODES.items()]
    eid = 100
    for a, b in PAIRS:
        for s, e in ((a, b), (b, a)):
            feats.append({"type": "Feature",
                          "geometry": {"type": "LineString", "coordinates": [list(NODES[s]), list(NODES[e])]},
                          "properties": {"id": eid, "startid": s, "endid": e, "cost": 1.0}})
            eid += 1
    return {"type": "FeatureCollection", "name": "hall", "features": feats}


def write_floor(folder: Path) -> Path:
    """Write hall.pgm, hall.yaml, hall.geojson and the scenario hall.toml into ``folder``."""
    from PIL import Image

    Image.fromarray(map_image()).save(folder / "hall.pgm")
    (folder / "hall.yaml").write_text(
        f"image: hall.pgm\nresolution: {RES}\norigin: [{ORIGIN[0]}, {ORIGIN[1]}, 0.0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n", encoding="utf-8")
    (folder / "hall.geojson").write_text(json.dumps(route_graph()), encoding="utf-8")
    scen = folder / "hall.toml"
    scen.write_text(
        'name = "floor-to-layout"\nseed = 3\n'
        '[floorplan]\nfile = "hall.yaml"\n'
        '[routes]\nfile = "hall.geojson"\n'
        '[[docks]]\nname = "A"\nnode = "10"\n'
        '[[docks]]\nname = "B"\nnode = "9"\nyaw_deg = 180.0\n'
        '[[tasks]]\nfrom = "A"\nto = "B"\n'
        '[sensor]\nmax_range = 15.0\n[robot]\nradius = 0.4\n'
        '[planning]\neps_max = 0.03\nresolution = 0.2\n', encoding="utf-8")
    return scen


def cli(cwd: Path, *argv) -> subprocess.CompletedProcess:
    """Run ``python -m cli`` as a user would; the step must succeed without noise on stderr."""
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "cli", *map(str, argv)], cwd=cwd, env=env,
                       capture_output=True, text=True, timeout=300)
    took = time.perf_counter() - t0
    assert p.returncode == 0, f"{argv[0]} exit {p.returncode} after {took:.1f} s:\n{p.stdout}\n{p.stderr}"
    # a library warning or a traceback is a bug even when the step succeeds
    assert "Traceback" not in p.stderr and "Warning" not in p.stderr, p.stderr
    return p


def test_map_and_graph_to_placed_planned_validated_exported_layout(tmp_path):
    scen = write_floor(tmp_path)
    placed = tmp_path / "placed.toml"

    doc = json.loads(cli(tmp_path, "place", scen, "-o", placed, "--json").stdout)
    assert doc["count"] >= 2 and doc["uncovered"] == []
    ids = [m["id"] for m in doc["markers"]]
    # the placed scenario still reads the map (not a copy of its traced polygons), wherever it is run from
    kept = scenarios.load(placed)
    assert kept.floorplan is not None and kept.floorplan.file == (tmp_path / "hall.yaml").resolve()
    assert "[floorplan]" in placed.read_text() and "[[obstacles]]" not in placed.read_text()

    plan = json.loads(cli(tmp_path, "plan", placed, "--json").stdout)
    chosen = next(c for c in plan["candidates"] if c["id"] == plan["chosen"])
    eps = plan["eps_max"]
    assert chosen["admissible"] and chosen["max_tau"] < eps
    assert chosen["nodes"][0] == "10" and chosen["nodes"][-1] == "9"
    assert not {"11", "12"} & set(chosen["nodes"])  # the grazing edge is never used
    assert plan["schedule"], "an admissible plan fixes at least once"
    assert all(f["predicted_tau"] < eps for f in plan["schedule"])
    assert all(set(f["markers"]) <= set(ids) for f in plan["schedule"])

    run = json.loads(cli(tmp_path, "run", placed, "--json").stdout)
    assert run["reached"] and run["violations"] == 0 and run["fixes"] > 0
    assert run["max_error"] < eps and run["max_predicted_tau"] < eps

    report = json.loads(cli(tmp_path, "validate", placed, "--runs", RUNS, "--workers", 2, "--json").stdout)
    assert report["failed"] == [], report
    status = {c["name"]: c["status"] for c in report["checks"]}
    # uniform noise: the set-membership checks apply and must pass, not be skipped
    assert {status[k] for k in ("containment", "promise", "bound", "nees", "nis", "plan")} == {"pass"}, status

    out, mk = tmp_path / "out.geojson", tmp_path / "out.csv"
    cli(tmp_path, "export", placed, "--routes", out, "--markers", mk)
    feats = json.loads(out.read_text())["features"]
    nodes = {f["properties"]["id"]: f for f in feats if f["geometry"]["type"] == "Point"}
    edges = {f["properties"]["id"]: f["properties"] for f in feats if f["geometry"]["type"] == "LineString"}
    assert sorted(nodes) == sorted(NODES)
    for i, xy in NODES.items():
        assert nodes[i]["geometry"]["coordinates"] == list(xy)
    given = {f["properties"]["id"]: f["properties"] for f in route_graph()["features"]
             if f["geometry"]["type"] == "LineString"}
    assert sorted(edges) == sorted(given)
    for i, p in given.items():
        assert (edges[i]["startid"], edges[i]["endid"]) == (p["startid"], p["endid"])
        grazing = {p["startid"], p["endid"]} == set(GRAZING)
        assert edges[i]["admissible"] is not grazing, (i, edges[i])
        if grazing:
            assert "closer than robot.radius" in edges[i]["why_not"]
        else:
            assert edges[i]["why_not"] is None
    rows = list(csv.DictReader(mk.open()))
    assert [r["id"] for r in rows] == ids
    for r, m in zip(rows, doc["markers"], strict=True):
        assert (float(r["x"]), float(r["y"])) == tuple(m["position"])
