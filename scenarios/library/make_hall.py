"""Write ``hall.dxf``, the drawing of the built-in ``hall`` scenario, with ezdxf.

Usage: ``python scenarios/library/make_hall.py OUT.dxf`` (the shipped file is
``scenarios/library/hall.dxf``; rerun this after changing the hall).

A 30 x 20 m hall drawn the way an architect's CAD file is (millimetres, ``$INSUNITS`` = 4):

- ``A-WALL``: the outer walls as centre LINEs (0.2 m thick in the scenario); an office
  24..28 x 15..18 m drawn as two nested closed outlines (a ring wall 0.15 m thick);
- ``A-RACK``: three rack rows as closed LWPOLYLINEs (rows 7..23 x 4..6, 8..10 with a round
  east end, 7..21 x 12..14 m) and a pallet stack as a HATCH;
- ``S-COLS``: two round columns (CIRCLE r 0.3 m) and a square column as an INSERT of block
  ``COLUMN`` turned 45°;
- ``AGV-REFL``: 12 reflectors as INSERTs of block ``REFLECTOR`` with an ``ID`` attribute,
  rotated to face into the hall;
- ``A-ANNO``: room labels and a dimension (not read).
"""

from __future__ import annotations

import sys
from pathlib import Path

import ezdxf

# id: (x, y) [m] on a wall's inner face or a rack face, facing [deg]
REFLECTORS = {
    "W1": ((0.1, 7.0), 0.0), "W2": ((0.1, 11.0), 0.0), "W3": ((29.9, 7.0), 180.0), "W4": ((29.9, 11.0), 180.0),
    "S1": ((10.0, 0.1), 90.0), "S2": ((20.0, 0.1), 90.0), "N1": ((10.0, 19.9), 270.0), "N2": ((20.0, 19.9), 270.0),
    "R1": ((15.0, 6.0), 90.0), "R2": ((15.0, 10.0), 90.0), "R3": ((14.0, 14.0), 90.0), "O1": ((26.0, 15.0), 270.0),
}


def mm(*xy_m: float) -> tuple[float, ...]:
    """Metres -> the drawing's millimetres."""
    return tuple(round(v * 1000.0, 6) for v in xy_m)


def make_hall():
    """Build the hall drawing (an ezdxf document)."""
    doc = ezdxf.new("R2010")
    doc.header["$INSUNITS"] = 4  # millimetres
    for name, colour in (("A-WALL", 7), ("A-RACK", 4), ("S-COLS", 6), ("AGV-REFL", 1), ("A-ANNO", 8)):
        doc.layers.add(name, color=colour)
    msp = doc.modelspace()
    corners = [(0, 0), (30, 0), (30, 20), (0, 20)]
    for a, b in zip(corners, corners[1:] + corners[:1], strict=True):
        msp.add_line(mm(*a), mm(*b), dxfattribs={"layer": "A-WALL"})
    office = [(24.0, 15.0), (28.0, 15.0), (28.0, 18.0), (24.0, 18.0)]
    inner = [(24.15, 15.15), (27.85, 15.15), (27.85, 17.85), (24.15, 17.85)]
    for outline in (office, inner):
        msp.add_lwpolyline([mm(*p) for p in outline], close=True, dxfattribs={"layer": "A-WALL"})

    msp.add_lwpolyline([mm(7, 4), mm(23, 4), mm(23, 6), mm(7, 6)], close=True, dxfattribs={"layer": "A-RACK"})
    # x, y, start width, end width, bulge: bulge 1 = a half circle to the next vertex (a round end)
    msp.add_lwpolyline([(*mm(7, 8), 0, 0, 0), (*mm(23, 8), 0, 0, 1.0), (*mm(23, 10), 0, 0, 0), (*mm(7, 10), 0, 0, 0)],
                       format="xyseb", close=True, dxfattribs={"layer": "A-RACK"})
    msp.add_lwpolyline([mm(7, 12), mm(21, 12), mm(21, 14), mm(7, 14)], close=True, dxfattribs={"layer": "A-RACK"})
    pallets = msp.add_hatch(color=4, dxfattribs={"layer": "A-RACK"})
    pallets.paths.add_polyline_path([mm(1.0, 14.0), mm(2.5, 14.0), mm(2.5, 15.5), mm(1.0, 15.5)], is_closed=True)

    for c in ((10.0, 16.0), (16.0, 16.0)):
        msp.add_circle(mm(*c), 300.0, dxfattribs={"layer": "S-COLS"})
    column = doc.blocks.new("COLUMN")
    column.add_lwpolyline([(-300, -300), (300, -300), (300, 300), (-300, 300)], close=True,
                          dxfattribs={"layer": "0"})  # layer 0: takes the INSERT's layer
    msp.add_blockref("COLUMN", mm(19.0, 16.0), dxfattribs={"layer": "S-COLS", "rotation": 45.0})

    refl = doc.blocks.new("REFLECTOR")
    refl.add_circle((0, 0), 40.0)
    refl.add_line((0, 0), (80.0, 0))  # the facing direction
    refl.add_attdef("ID", (60.0, 60.0), dxfattribs={"height": 150.0})
    for mid, (pos, facing) in REFLECTORS.items():
        ref = msp.add_blockref("REFLECTOR", mm(*pos), dxfattribs={"layer": "AGV-REFL", "rotation": facing})
        ref.add_auto_attribs({"ID": mid})

    for text, pos in (("HALL 1", (12.0, 2.5)), ("OFFICE", (25.0, 16.5)), ("PALLETS", (1.0, 13.5))):
        msp.add_text(text, height=300.0, dxfattribs={"layer": "A-ANNO"}).set_placement(mm(*pos))
    msp.add_linear_dim(base=mm(0, -1.5), p1=mm(0, 0), p2=mm(30, 0), dxfattribs={"layer": "A-ANNO"}).render()
    return doc


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print("usage: python scenarios/library/make_hall.py OUT.dxf", file=sys.stderr)
        return 2
    out = Path(argv[0])
    make_hall().saveas(out)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
