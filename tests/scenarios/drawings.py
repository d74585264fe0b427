"""Floor plans written the way users' tools write them: DXF with ezdxf, ROS maps with Pillow.

The DXF test hall (coordinates in mm; metres in the comments):

- A-WALL: the hall's four walls as LINEs on the rectangle 0..30 x 0..20; a ring wall as two
  nested closed LWPOLYLINEs (outer 2..8 x 12..18, inner 2.2..7.8 x 12.2..17.8, ring area
  36 - 5.6² = 4.64 m²); a TEXT and a DIMENSION (ignored).
- A-RACK: a rack as a closed LWPOLYLINE 10..26 x 4..6 (32 m²); a rack with a round end
  (closed LWPOLYLINE with a bulge: 10..20 x 8..10 plus a half disc of radius 1 m, area
  20 + π/2); a HATCH 12..14 x 14..16 (4 m²).
- S-COLS: two CIRCLE columns r = 0.3 at (5, 5) and (25, 15); an INSERT of block COL
  (a 1 x 0.5 m closed outline on layer 0 and a nested INSERT of block PIN, a circle
  r = 0.1 at (1, 0) on layer 0) at (15, 15) rotated 90°, scaled 2: a 1 x 2 m outline
  (2 m²) centred at (15, 15) and a circle r = 0.2 at (15, 17).
- FURN: a LINE on a layer nobody reads.
- AGV-REFL: reflectors W1 at (10, 0.1) rotated 90° and W2 at (29.9, 10) rotated 180° (INSERTs
  of REFL with an ID attribute), an INSERT without ID at (18, 4) rotated 270° (-> "R1"), a
  POINT at (0.1, 5) (-> "R2").
"""

from __future__ import annotations

import math
from pathlib import Path

import ezdxf
import numpy as np

RING_AREA = 36.0 - 5.6 ** 2
RACK_AREA = 32.0
ROUND_RACK_AREA = 20.0 + math.pi / 2
HATCH_AREA = 4.0
BLOCK_AREA = 2.0
MARKERS = {"W1": ((10.0, 0.1), 90.0), "W2": ((29.9, 10.0), 180.0), "R1": ((18.0, 4.0), 270.0),
           "R2": ((0.1, 5.0), None)}


def hall_doc(insunits: int = 4, scale: float = 1.0):
    """Build the test hall as an ezdxf document; ``scale`` = drawing units per mm."""
    doc = ezdxf.new("R2018", setup=True)
    doc.header["$INSUNITS"] = insunits
    for name in ("A-WALL", "A-RACK", "S-COLS", "FURN", "AGV-REFL", "EMPTY"):
        doc.layers.add(name)
    msp = doc.modelspace()

    def u(*xy):
        return tuple(v * scale for v in xy)

    for a, b in (((0, 0), (30000, 0)), ((30000, 0), (30000, 20000)), ((30000, 20000), (0, 20000)),
                 ((0, 20000), (0, 0))):
        msp.add_line(u(*a), u(*b), dxfattribs={"layer": "A-WALL"})
    msp.add_lwpolyline([u(2000, 12000), u(8000, 12000), u(8000, 18000), u(2000, 18000)], close=True,
                       dxfattribs={"layer": "A-WALL"})
    msp.add_lwpolyline([u(2200, 12200), u(7800, 12200), u(7800, 17800), u(2200, 17800)], close=True,
                       dxfattribs={"layer": "A-WALL"})
    msp.add_text("Hall 1", dxfattribs={"layer": "A-WALL", "height": 500 * scale}).set_placement(u(15000, 10000))
    dim = msp.add_linear_dim(base=u(0, -2000), p1=u(0, 0), p2=u(30000, 0), dxfattribs={"layer": "A-WALL"})
    dim.render()
    msp.add_lwpolyline([u(10000, 4000), u(26000, 4000), u(26000, 6000), u(10000, 6000)], close=True,
                       dxfattribs={"layer": "A-RACK"})
    # x, y, start width, end width, bulge: bulge 1 is a half circle from (20, 8) to (20, 10)
    msp.add_lwpolyline([(*u(10000, 8000), 0, 0, 0), (*u(20000, 8000), 0, 0, 1.0), (*u(20000, 10000), 0, 0, 0),
                        (*u(10000, 10000), 0, 0, 0)], format="xyseb", close=True, dxfattribs={"layer": "A-RACK"})
    hatch = msp.add_hatch(dxfattribs={"layer": "A-RACK"})
    hatch.paths.add_polyline_path([u(12000, 14000), u(14000, 14000), u(14000, 16000), u(12000, 16000)],
                                  is_closed=True)
    for c in ((5000, 5000), (25000, 15000)):
        msp.add_circle(u(*c), 300 * scale, dxfattribs={"layer": "S-COLS"})
    pin = doc.blocks.new("PIN")
    pin.add_circle(u(1000, 0), 100 * scale, dxfattribs={"layer": "0"})
    col = doc.blocks.new("COL")
    col.add_lwpolyline([u(-500, -250), u(500, -250), u(500, 250), u(-500, 250)], close=True,
                       dxfattribs={"layer": "0"})
    col.add_blockref("PIN", (0, 0), dxfattribs={"layer": "0"})
    msp.add_blockref("COL", u(15000, 15000), dxfattribs={"layer": "S-COLS", "rotation": 90.0,
                                                          "xscale": 2.0, "yscale": 2.0})
    msp.add_line(u(1000, 1000), u(3000, 1000), dxfattribs={"layer": "FURN"})
    refl = doc.blocks.new("REFL")
    refl.add_circle((0, 0), 25 * scale)
    refl.add_attdef("ID", (0, 0), dxfattribs={"height": 50 * scale})
    plain = doc.blocks.new("REFL_NOID")
    plain.add_circle((0, 0), 25 * scale)
    for mid in ("W1", "W2"):
        (x, y), rot = MARKERS[mid]
        ref = msp.add_blockref("REFL", u(x * 1000, y * 1000), dxfattribs={"layer": "AGV-REFL", "rotation": rot})
        ref.add_auto_attribs({"ID": mid})
    msp.add_blockref("REFL_NOID", u(18000, 4000), dxfattribs={"layer": "AGV-REFL", "rotation": 270.0})
    msp.add_point(u(100, 5000), dxfattribs={"layer": "AGV-REFL"})
    return doc


def write_hall(path: Path, **kwargs) -> Path:
    """Write the test hall DXF to ``path`` and return it."""
    hall_doc(**kwargs).saveas(path)
    return path


# --- ROS maps --------------------------------------------------------------------------------

FREE, OCCUPIED, UNKNOWN = 254, 0, 205  # the shades map_saver writes


def map_image(h: int = 80, w: int = 100) -> np.ndarray:
    """Make a map image (H, W) uint8, row 0 at the top.

    Free floor, 2-cell border walls, a 10 x 10 cell occupied block with a 4 x 4 free hole,
    a 6 x 5 unknown patch.
    """
    img = np.full((h, w), FREE, dtype=np.uint8)
    img[:2, :] = img[-2:, :] = OCCUPIED
    img[:, :2] = img[:, -2:] = OCCUPIED
    img[20:30, 40:50] = OCCUPIED
    img[23:27, 43:47] = FREE
    img[60:66, 10:15] = UNKNOWN
    return img


def write_map(folder: Path, img: np.ndarray, *, name: str = "map", suffix: str = ".pgm", yaml_extra: str = "",
              resolution: float = 0.05, origin=(-1.0, -2.0, 0.0), negate: int = 0, mode: str | None = None,
              pil_mode: str | None = None) -> Path:
    """Write ``img`` with Pillow and a map_server YAML beside it; return the YAML path."""
    from PIL import Image

    image = Image.fromarray(img, mode=pil_mode) if pil_mode else Image.fromarray(img)
    image.save(folder / f"{name}{suffix}")
    lines = [f"image: {name}{suffix}", f"resolution: {resolution}", f"origin: [{', '.join(map(str, origin))}]",
             f"negate: {negate}", "occupied_thresh: 0.65", "free_thresh: 0.196"]
    if mode:
        lines.append(f"mode: {mode}")
    path = folder / f"{name}.yaml"
    path.write_text("\n".join(lines) + "\n" + yaml_extra, encoding="utf-8")
    return path


# A map as SLAM leaves it (map_saver's shades): an unknown band all round, a 4 x 6 m room of
# 2-cell walls whose right wall has a 1 m opening (free cells up to the known area's edge),
# an unknown pocket inside, and a rack wall at 30 degrees.
ROOM_SHAPE = (100, 140)             # rows, columns of 5 cm
ROOM_ORIGIN = (-1.0, -2.0)          # [m]
ROOM_KNOWN = (-0.5, -1.5, 5.5, 2.5)  # bounding box of the known cells [m]
ROOM_POCKET = (0.5, -0.8, 1.3, 0.0)  # the unknown pocket [m]
ROOM_OPENING_Y = (0.0, 1.0)         # the opening in the right wall (x = 5.4 .. 5.5) [m]
ROOM_RACK_DEG = 30.0                # direction of the rack wall [degrees]
ROOM_RACK = ((2.5, -0.8), (4.5, -0.8 + 2.0 * math.tan(math.radians(ROOM_RACK_DEG))))  # its centre line [m]
ROOM_RACK_HALF = 0.12               # half its thickness [m]


def room_map() -> np.ndarray:
    """Make the room map (see ``ROOM_*``), shape ROOM_SHAPE, uint8, row 0 at the top."""
    h, w = ROOM_SHAPE
    img = np.full((h, w), UNKNOWN, dtype=np.uint8)
    img[10:90, 10:130] = FREE
    img[10:12, 10:130] = img[88:90, 10:130] = OCCUPIED
    img[10:90, 10:12] = img[10:90, 128:130] = OCCUPIED
    img[40:60, 128:130] = FREE        # the opening: rows 40..59 are y 0 .. 1 m
    img[60:76, 30:46] = UNKNOWN       # the pocket: x 0.5 .. 1.3, y -0.8 .. 0 m
    r, c = np.mgrid[:h, :w]
    x = ROOM_ORIGIN[0] + (c + 0.5) * 0.05
    y = ROOM_ORIGIN[1] + (h - r - 0.5) * 0.05
    (ax, ay), (bx, by) = ROOM_RACK
    dx, dy = bx - ax, by - ay
    t = np.clip(((x - ax) * dx + (y - ay) * dy) / (dx * dx + dy * dy), 0.0, 1.0)
    img[np.hypot(x - ax - t * dx, y - ay - t * dy) <= ROOM_RACK_HALF] = OCCUPIED
    return img


def room_text(extra: str = "") -> str:
    """Return a scenario on the room map (``map.yaml`` beside it); ``extra``: lines of ``[workspace]``."""
    return f"""name = "room"
[floorplan]
file = "map.yaml"
[workspace]
{extra}
[sensor]
max_range = 10.0
[robot]
radius = 0.2
wheel_base = 0.3
wheel_radius = 0.04
[planning]
eps_max = 0.05
resolution = 0.05
[placement]
spacing = 0.5
[[docks]]
name = "A"
pose = [0.0, -0.4, 0.0]
[[docks]]
name = "B"
pose = [2.0, -0.4, 0.0]
[[tasks]]
from = "A"
to = "B"
"""
