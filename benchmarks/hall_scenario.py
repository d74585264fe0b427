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


def rack_x(i: int, pitch: float = PITCH) -> float:
    """Centre x of rack row ``i`` [m] (rows ``pitch`` apart)."""
    return 7.5 + PITCH * i if pitch == PITCH else 5.0 + pitch * i + pitch / 2


def aisle_x(i: int, pitch: float = PITCH) -> float:
    """Centre x of aisle ``i`` (0..rows; aisle i is left of rack i) [m]."""
    return 5.0 + pitch * i


def n_rows(pitch: float = PITCH) -> int:
    """Rack rows ``pitch`` [m] apart that fit the hall (22 at the default 5 m)."""
    return int((WIDTH - 15.0) // pitch) + 1


def hall_toml(markers: bool = True, resolution: float = 0.1, marker_kind: str | None = None,
              pitch: float = PITCH, face_markers: int = 5) -> str:
    """Return the hall scenario as TOML text (``markers`` False: the empty floor).

    ``marker_kind``: ``placement.marker_kind`` (``flat`` or ``post``), default left to the loader.
    ``pitch``: distance between rack rows [m] (aisles ``pitch - ROW_W`` wide); ``face_markers``:
    reflectors on each long rack face, evenly spread. The defaults give the hall of the module
    docstring; other values a hall of other rack and reflector spacing, its docks and routes
    laid out the same way.
    """
    rows = n_rows(pitch)
    step = ROW_LEN / face_markers
    out = ['name = "hall-120x80"' if (pitch, face_markers) == (PITCH, 5) else
           f'name = "hall-120x80-p{pitch:g}-f{face_markers}"']
    docks = [2 * j for j in range(rows // 2)] + [rows]  # under every other aisle, the last at the far wall
    n_markers = 38 + rows * (2 * face_markers + 1) + len(range(0, rows, 4))
    n_segs = 2 * rows + len(range(0, rows + 1, 2)) + (rows // 2 % 2) + 2 * len(docks)
    out += [f'description = "120 x 80 m hall: {rows} rack rows, {n_markers} reflectors, {2 * len(docks)} docks, '
            f'{n_segs} route segments"',
            "seed = 3", "", "[workspace]", f"size = [{WIDTH}, {HEIGHT}]", ""]
    for i in range(rows):
        out += ["[[obstacles]]", f"center = [{rack_x(i, pitch)}, {ROW_Y0 + ROW_LEN / 2}]",
                f"size = [{ROW_W}, {ROW_LEN}]", ""]
    if markers:
        pts = []
        pts += [(x, 0.0) for x in range(5, 120, 10)] + [(x, HEIGHT) for x in range(5, 120, 10)]
        pts += [(0.0, y) for y in range(10, 80, 10)] + [(WIDTH, y) for y in range(10, 80, 10)]
        for i in range(rows):
            for side in (-1, 1):
                fx = rack_x(i, pitch) + side * ROW_W / 2
                pts += [(fx, ROW_Y0 + step / 2 + step * j) for j in range(face_markers)]
            pts.append((rack_x(i, pitch), ROW_Y0))  # the end towards the lower cross aisle
            if i % 4 == 0:
                pts.append((rack_x(i, pitch), ROW_Y0 + ROW_LEN))
        for n, (x, y) in enumerate(pts):
            out += ["[[markers]]", f'id = "R{n + 1}"', f"position = [{float(x)}, {float(y)}]", ""]
    if marker_kind is not None:
        out += ["[placement]", f'marker_kind = "{marker_kind}"', ""]
    out += ["[sensor]", "max_range = 25.0", "", "[robot]", "radius = 0.4", "",
            "[planning]", "eps_max = 0.03", f"resolution = {resolution}", ""]
    nodes, segs = {}, []
    for end, cy in zip("bt", CROSS_Y, strict=True):
        for i in range(rows + 1):
            nodes[f"{end}{i}"] = (aisle_x(i, pitch), cy)
            if i:
                segs.append((f"{end}{i - 1}", f"{end}{i}"))
    middle = [rows // 2] if rows // 2 % 2 else []
    for i in [*range(0, rows + 1, 2), *middle]:  # every other aisle, and the middle one
        segs.append((f"b{i}", f"t{i}"))
    docks_out = []
    for i in docks:
        for end, dy, yaw in (("b", DOCK_Y[0], -90.0), ("t", DOCK_Y[1], 90.0)):
            name = f"D{len(docks_out) + 1}"
            docks_out.append((name, aisle_x(i, pitch), dy, yaw))
            nodes[name] = (aisle_x(i, pitch), dy)
            segs.append((name, f"{end}{i}"))
    for name, x, y, yaw in docks_out:
        out += ["[[docks]]", f'name = "{name}"', f"pose = [{x}, {y}, {yaw}]", ""]
    node_txt = ", ".join(f'{k} = [{x}, {y}]' for k, (x, y) in nodes.items())
    seg_txt = ", ".join(f'["{a}", "{b}"]' for a, b in segs)
    out += ["[routes]", f"nodes = {{ {node_txt} }}", f"segments = [{seg_txt}]", ""]
    out += ["[[tasks]]", 'from = "D1"', f'to = "D{len(docks_out)}"', ""]
    return "\n".join(out)


def write_hall(folder: str | Path, markers: bool = True, marker_kind: str | None = None,
               pitch: float = PITCH, face_markers: int = 5) -> Path:
    """Write the hall into ``folder`` as ``hall.toml`` (or ``empty-hall[-KIND].toml``); return the path.

    Other ``pitch`` or ``face_markers`` (:func:`hall_toml`) add ``-pPITCH-fN`` to the name.
    """
    name = "hall" if markers else "empty-hall" + (f"-{marker_kind}" if marker_kind else "")
    if (pitch, face_markers) != (PITCH, 5):
        name += f"-p{pitch:g}-f{face_markers}"
    path = Path(folder) / f"{name}.toml"
    path.write_text(hall_toml(markers, marker_kind=marker_kind, pitch=pitch, face_markers=face_markers),
                    encoding="utf-8")
    return path


#: The 6-robot fleet of the built-in ``hall-fleet``: each robot's docks in driving order (its tasks
#: go from each dock to the next). Bottom docks D1, D3, ... D23 sit at x = 5, 15, ... 115 m below
#: the lower cross aisle, top docks D2, D4, ... D24 above the upper one. Three pairs, in the west,
#: the middle and the east of the hall, each of two robots that trade docks: the first drives
#: along the lower cross aisle and up the next rack aisle to the dock the second starts from; the
#: second drives along the upper cross aisle and down the first aisle to the dock the first left.
FLEET = (("r1", ("D1", "D3", "D4")), ("r2", ("D4", "D2", "D1")),
         ("r3", ("D9", "D11", "D12")), ("r4", ("D12", "D10", "D9")),
         ("r5", ("D17", "D19", "D20")), ("r6", ("D20", "D18", "D17")))


def hall_fleet_toml() -> str:
    """Return the built-in ``hall-fleet`` scenario: the hall of :func:`hall_toml` with the fleet :data:`FLEET`."""
    text = hall_toml(markers=True)
    head, _, _ = text.rpartition("[[tasks]]")
    desc = text.splitlines()[1].split('"')[1]
    head = head.replace('name = "hall-120x80"', 'name = "hall-fleet"', 1).replace(
        desc, f"{desc}; a fleet of {len(FLEET)} robots trading docks, most with several tasks", 1)
    # the shortest admissible route first: the rack aisles, not the walls' better-lit detours
    head = head.replace("[planning]\n", '[planning]\norder = ["length", "accuracy"]\n', 1)
    out = [head.rstrip(), ""]
    tasks: list[tuple[str, str]] = []
    robots = []
    for name, docks in FLEET:
        idx = []
        for a, b in zip(docks, docks[1:], strict=False):
            idx.append(len(tasks))
            tasks.append((a, b))
        robots.append((name, idx))
    for a, b in tasks:
        out += ["[[tasks]]", f'from = "{a}"', f'to = "{b}"', ""]
    for name, idx in robots:
        out += ["[[robots]]", f'name = "{name}"', f"tasks = {idx}", ""]
    return "\n".join(out)
