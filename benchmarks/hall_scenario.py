"""A big floor for the benchmarks: a 120 x 80 m hall written as scenario TOML.

22 rack rows (56 m x 1.2 m, along y, 5 m apart), 286 reflectors (38 on the walls, 5 on each
of the 44 long rack faces, 28 on rack ends), 24 docks on a route network of 81 segments: a
cross aisle at each end of the racks, every other rack aisle, and a spur from each dock. Every
segment keeps the robot radius from the racks and the walls. Used by ``benchmarks/hall.py``
(and its tests); without markers it is the empty floor that ``pefsim place`` equips.
"""

from __future__ import annotations

from pathlib import Path

WIDTH, HEIGHT = 120.0, 80.0
N_ROWS = 22
ROW_LEN, ROW_W, PITCH = 56.0, 1.2, 5.0
ROW_Y0 = 12.0  # racks span y in [12, 68]
CROSS_Y = (6.0, 74.0)  # cross aisles below and above the racks
DOCK_Y = (2.5, 77.5)


def rack_x(i: int) -> float:
    """Centre x of rack row ``i`` [m]."""
    return 7.5 + PITCH * i


def aisle_x(i: int) -> float:
    """Centre x of aisle ``i`` (0..N_ROWS; aisle i is left of rack i) [m]."""
    return 5.0 + PITCH * i


def hall_toml(markers: bool = True, resolution: float = 0.1, marker_kind: str | None = None) -> str:
    """Return the hall scenario as TOML text (``markers`` False: the empty floor).

    ``marker_kind``: ``placement.marker_kind`` (``flat`` or ``post``), default left to the loader.
    """
    out = ['name = "hall-120x80"',
           'description = "120 x 80 m hall: 22 rack rows, 286 reflectors, 24 docks, 81 route segments"',
           "seed = 3", "", "[workspace]", f"size = [{WIDTH}, {HEIGHT}]", ""]
    for i in range(N_ROWS):
        out += ["[[obstacles]]", f"center = [{rack_x(i)}, {ROW_Y0 + ROW_LEN / 2}]", f"size = [{ROW_W}, {ROW_LEN}]", ""]
    if markers:
        pts = []
        pts += [(x, 0.0) for x in range(5, 120, 10)] + [(x, HEIGHT) for x in range(5, 120, 10)]
        pts += [(0.0, y) for y in range(10, 80, 10)] + [(WIDTH, y) for y in range(10, 80, 10)]
        for i in range(N_ROWS):
            for side in (-1, 1):
                fx = rack_x(i) + side * ROW_W / 2
                pts += [(fx, ROW_Y0 + 5.6 + 11.2 * j) for j in range(5)]
            pts.append((rack_x(i), ROW_Y0))  # the end towards the lower cross aisle
            if i % 4 == 0:
                pts.append((rack_x(i), ROW_Y0 + ROW_LEN))
        for n, (x, y) in enumerate(pts):
            out += ["[[markers]]", f'id = "R{n + 1}"', f"position = [{float(x)}, {float(y)}]", ""]
    if marker_kind is not None:
        out += ["[placement]", f'marker_kind = "{marker_kind}"', ""]
    out += ["[sensor]", "max_range = 25.0", "", "[robot]", "radius = 0.4", "",
            "[planning]", "eps_max = 0.03", f"resolution = {resolution}", ""]
    nodes, segs = {}, []
    for end, cy in zip("bt", CROSS_Y, strict=True):
        for i in range(N_ROWS + 1):
            nodes[f"{end}{i}"] = (aisle_x(i), cy)
            if i:
                segs.append((f"{end}{i - 1}", f"{end}{i}"))
    for i in [*range(0, N_ROWS + 1, 2), 11]:  # every other aisle, and the middle one
        segs.append((f"b{i}", f"t{i}"))
    docks = []
    for j in range(12):
        i = 2 * j if j < 11 else N_ROWS  # under every other aisle, the last at the far wall
        for end, dy, yaw in (("b", DOCK_Y[0], -90.0), ("t", DOCK_Y[1], 90.0)):
            name = f"D{len(docks) + 1}"
            docks.append((name, aisle_x(i), dy, yaw))
            nodes[name] = (aisle_x(i), dy)
            segs.append((name, f"{end}{i}"))
    for name, x, y, yaw in docks:
        out += ["[[docks]]", f'name = "{name}"', f"pose = [{x}, {y}, {yaw}]", ""]
    node_txt = ", ".join(f'{k} = [{x}, {y}]' for k, (x, y) in nodes.items())
    seg_txt = ", ".join(f'["{a}", "{b}"]' for a, b in segs)
    out += ["[routes]", f"nodes = {{ {node_txt} }}", f"segments = [{seg_txt}]", ""]
    out += ["[[tasks]]", 'from = "D1"', 'to = "D24"', ""]
    return "\n".join(out)


def write_hall(folder: str | Path, markers: bool = True, marker_kind: str | None = None) -> Path:
    """Write the hall into ``folder`` as ``hall.toml`` (or ``empty-hall[-KIND].toml``); return the path."""
    name = "hall" if markers else "empty-hall" + (f"-{marker_kind}" if marker_kind else "")
    path = Path(folder) / f"{name}.toml"
    path.write_text(hall_toml(markers, marker_kind=marker_kind), encoding="utf-8")
    return path
