"""Floor-plan reading speed: a 2000 x 2000 ROS map and a DXF drawing of 3,700 entities.

The map (0.05 m cells, 100 x 100 m) has border walls, 300 random blocks, 0.2 % sensor specks
and an unknown patch; the drawing (mm) has 1,000 closed rack outlines, 2,000 wall lines, 400
rotated column blocks (a circle and an outline each) and 300 reflector INSERTs with ID
attributes. Both are written into a temporary folder (removed afterwards) with Pillow and
ezdxf, then read with :func:`read_rosmap` / :func:`read_dxf` (the time of the first call,
imports of ezdxf and Pillow excluded, includes everything else: parsing, tracing or filling,
simplification, the scenario's obstacle dicts).

Run: ``python benchmarks/floorplan.py``. The last line is one JSON object.
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

import ezdxf  # noqa: E402
import numpy as np  # noqa: E402
from PIL import Image  # noqa: E402

from scenarios.floorplan.dxf import read_dxf  # noqa: E402
from scenarios.floorplan.rosmap import read_rosmap  # noqa: E402


def write_map(folder: Path, rng: np.random.Generator) -> Path:
    img = np.full((2000, 2000), 254, np.uint8)
    img[:6] = img[-6:] = 0
    img[:, :6] = img[:, -6:] = 0
    for _ in range(300):
        y, x = rng.integers(10, 1950, size=2)
        h, w = rng.integers(2, 60, size=2)
        img[y:y + h, x:x + w] = 0
    img[rng.random(img.shape) < 0.002] = 0
    img[1500:1900, 100:600] = 205
    Image.fromarray(img).save(folder / "map.pgm")
    path = folder / "map.yaml"
    path.write_text("image: map.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
                    "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    return path


def write_drawing(folder: Path, rng: np.random.Generator) -> tuple[Path, int]:
    doc = ezdxf.new()
    doc.header["$INSUNITS"] = 4
    for name in ("W", "R", "C", "REFL"):
        doc.layers.add(name)
    msp = doc.modelspace()
    col = doc.blocks.new("COL")
    col.add_circle((0, 0), 200)
    col.add_lwpolyline([(-300, -300), (300, -300), (300, 300), (-300, 300)], close=True)
    refl = doc.blocks.new("RF")
    refl.add_circle((0, 0), 30)
    refl.add_attdef("ID", (0, 0))
    for i in range(40):
        for j in range(25):
            x, y = 5000 + i * 2300, 3000 + j * 2200
            msp.add_lwpolyline([(x, y), (x + 1800, y), (x + 1800, y + 1000), (x, y + 1000)], close=True,
                               dxfattribs={"layer": "R"})
    for _ in range(2000):
        x, y = rng.uniform(0, 99000), rng.uniform(0, 59000)
        msp.add_line((x, y), (x + 800, y), dxfattribs={"layer": "W"})
    for _ in range(400):
        msp.add_blockref("COL", (rng.uniform(1000, 99000), rng.uniform(1000, 59000)),
                         dxfattribs={"layer": "C", "rotation": 30})
    for k in range(300):
        ref = msp.add_blockref("RF", (k * 300.0 + 50, 10.0), dxfattribs={"layer": "REFL"})
        ref.add_auto_attribs({"ID": f"X{k}"})
    path = folder / "big.dxf"
    doc.saveas(path)
    return path, len(msp)


def main() -> int:
    rng = np.random.default_rng(5)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        yaml_path = write_map(folder, rng)
        dxf_path, n_entities = write_drawing(folder, rng)
        t0 = time.perf_counter()
        rosmap = read_rosmap(yaml_path)
        t_map = time.perf_counter() - t0
        t0 = time.perf_counter()
        drawing = read_dxf(dxf_path, obstacle_layers=["W", "R", "C"], marker_layer="REFL")
        t_dxf = time.perf_counter() - t0
    print(f"ROS map 2000 x 2000 cells: {t_map:.2f} s, {len(rosmap.obstacles)} obstacle polygons")
    print(f"DXF {n_entities} entities: {t_dxf:.2f} s, {len(drawing.obstacles)} obstacles, "
          f"{len(drawing.markers)} markers")
    print(json.dumps({"rosmap_2000_s": round(t_map, 3), "rosmap_obstacles": len(rosmap.obstacles),
                      "dxf_s": round(t_dxf, 3), "dxf_entities": n_entities, "dxf_obstacles": len(drawing.obstacles),
                      "dxf_markers": len(drawing.markers)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
