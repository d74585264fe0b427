"""Obstacles from a ROS map_server occupancy map (a YAML file and the PGM/PNG image it names).

Thresholding follows map_server (ROS 1 ``image_loader.cpp``, ROS 2 ``nav2_map_server``
``map_io.cpp``): the shade of a pixel is the mean of its colour channels (in ``trinary``
mode an alpha channel is averaged in too), p = (255 − shade)/255, or shade/255 with
``negate``; a cell is occupied if p > occupied_thresh, free if p < free_thresh, else
unknown; in ``scale`` mode a pixel that is not opaque is unknown; in ``raw`` mode the
shade is the occupancy in percent (0..100, anything else unknown, ``negate`` ignored) and
the same thresholds apply to it / 100. Occupied cells are obstacles; unknown cells (and the
probabilities between the thresholds in ``scale`` mode) are neither floor nor wall: they
become the scenario's unknown areas (``[[unknown]]``), which the planner does not drive
through nor see across and the simulation leaves empty. The map is cropped to the bounding
box of its known cells (the default workspace); its edge is no wall.
"""

from __future__ import annotations

import math
import re
import stat
import struct
import warnings
from pathlib import Path

import numpy as np
import shapely

from scenarios.errors import ScenarioError
from scenarios.fields import Table, show, show_path
from scenarios.floorplan import geometry
from scenarios.floorplan.spec import FloorPlanData
from scenarios.floorplan.trace import trace
from scenarios.limits import MAX_MAP_PIXELS, MAX_NESTING, MAX_YAML_NODES

MODES = ("trinary", "scale", "raw")
# PBM/PGM/PPM: magic, then width and height, with comments and white space between.
_PNM_HEADER = re.compile(rb"P[1-6](?:\s+|#[^\n]*\n)+(\d+)(?:\s+|#[^\n]*\n)+(\d+)")


def _map_loader():
    """PyYAML's safe loader reading numbers like ROS's yaml-cpp (YAML 1.2): ``5e-2`` is 0.05.

    Under YAML 1.1 (PyYAML's) a float needs a dot, so ``resolution: 5e-2``, which map_server
    reads as 0.05, would be the string "5e-2".
    """
    import yaml

    class MapLoader(yaml.SafeLoader):
        def construct_mapping(self, node, deep=False):
            # A key written twice is ambiguous (PyYAML keeps the last, other readers the first).
            seen: set[str] = set()
            for key, _ in node.value if isinstance(node, yaml.MappingNode) else ():
                if isinstance(key, yaml.ScalarNode) and key.tag != "tag:yaml.org,2002:merge":
                    if key.value in seen:
                        raise yaml.constructor.ConstructorError(
                            None, None, f"duplicate key {key.value!r} (at line {key.start_mark.line + 1}): "
                                        f"expected each key once", key.start_mark)
                    seen.add(key.value)
            return super().construct_mapping(node, deep=deep)

    MapLoader.add_implicit_resolver("tag:yaml.org,2002:float",
                                    re.compile(r"^[-+]?[0-9][0-9_]*(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
                                    list("-+0123456789"))
    return MapLoader


def _expanded_nodes(text: str, loader, where: str, shown: str) -> None:
    """Refuse a YAML text whose aliases expand it beyond MAX_YAML_NODES nodes, or nested too deep.

    Counted on the parser's events (no document is built): each collection's size is the sum
    of its items', an alias counts the size of its anchor's node.
    """
    import yaml

    sizes: dict[str, int] = {}
    stack = [[0, None]]  # open collections: [nodes so far, anchor]

    def add(n: int) -> None:
        stack[-1][0] += n
        if stack[-1][0] > MAX_YAML_NODES:
            raise ScenarioError(f"{where}.file: {shown}: more than {MAX_YAML_NODES} YAML nodes once its aliases "
                                f"are expanded, at most {MAX_YAML_NODES}")

    for ev in yaml.parse(text, Loader=loader):
        if isinstance(ev, yaml.AliasEvent):
            add(sizes.get(ev.anchor, 1))
        elif isinstance(ev, yaml.ScalarEvent):
            if ev.anchor:
                sizes[ev.anchor] = 1
            add(1)
        elif isinstance(ev, yaml.CollectionStartEvent):
            stack.append([1, ev.anchor])
            if len(stack) > MAX_NESTING:
                raise ScenarioError(f"{where}.file: {shown}: YAML nested more than {MAX_NESTING} deep, "
                                    f"at most {MAX_NESTING}")
        elif isinstance(ev, yaml.CollectionEndEvent):
            n, anchor = stack.pop()
            if anchor:
                sizes[anchor] = n
            add(n)


def read_yaml(path: Path, where: str, shown: str) -> dict:
    """Parse the map YAML at ``path`` into a dict; unreadable, malformed or over budget is one error line."""
    import yaml

    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) else "not UTF-8 text"
        raise ScenarioError(f"{where}.file: cannot read {shown}: {reason or exc}") from None
    loader = _map_loader()
    try:
        _expanded_nodes(text, loader, where, shown)
        doc = yaml.load(text, Loader=loader)  # noqa: S506 (a safe loader)
    except yaml.YAMLError as exc:
        first = str(exc).splitlines()[0] if str(exc) else "malformed"
        raise ScenarioError(f"{where}.file: {shown}: malformed YAML: {first}") from None
    if not isinstance(doc, dict):
        raise ScenarioError(f"{where}.file: {shown}: expected a map_server YAML mapping, got {show(doc)}")
    return doc


def image_size(path: Path) -> tuple[int, int] | None:
    """Width and height [pixels] from a PNG or PGM/PPM/PBM header, or None for another format.

    Read from the first bytes alone, so that the size is known before anything is decoded.
    """
    with open(path, "rb") as f:
        head = f.read(1024)
    if head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR":
        w, h = struct.unpack(">II", head[16:24])
        return int(w), int(h)
    m = _PNM_HEADER.match(head)
    if m:
        return int(m.group(1)), int(m.group(2))
    return None


def _check_pixels(t: Table, image_name: str, image_path: Path, w: int, h: int) -> None:
    if w * h > MAX_MAP_PIXELS:
        t.fail(t.key("image"), f"{show_path(image_path)} is {w} x {h} = {w * h:.3g} pixels, "
               f"at most {MAX_MAP_PIXELS:.3g}", image_name)


def shade(img) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel channel means and opacity of a Pillow image.

    Returns
    -------
    rgb_mean, trinary_mean : ndarray, shape (H, W), float in [0, 255]
        Mean of the colour channels; mean of all channels including alpha (map_server's
        trinary mode averages alpha in).
    opaque : ndarray of bool, shape (H, W)
    """
    mode = img.mode
    if mode in ("I;16", "I;16B", "I;16L", "I"):
        # 16-bit greyscale PGM: map_server's image loaders reduce it to 8 bits
        a = np.asarray(img, dtype=np.float64)
        g = a / 257.0 if a.max(initial=0) > 255 else a
        return g, g, np.ones(g.shape, dtype=bool)
    if mode in ("1", "P", "PA", "CMYK", "YCbCr", "LAB", "HSV", "F"):
        img = img.convert("RGBA" if ("A" in mode or "transparency" in img.info) else "RGB")
        mode = img.mode
    a = np.asarray(img, dtype=np.float64)
    if a.ndim == 2:
        return a, a, np.ones(a.shape, dtype=bool)
    has_alpha = mode in ("LA", "RGBA")
    colour = a[..., :-1] if has_alpha else a
    rgb = colour.mean(axis=2)
    if not has_alpha:
        return rgb, rgb, np.ones(rgb.shape, dtype=bool)
    return rgb, a.mean(axis=2), a[..., -1] >= 255.0


def classify(img, mode: str, negate: bool, occupied_thresh: float,
             free_thresh: float) -> tuple[np.ndarray, np.ndarray]:
    """Occupied and unknown cells of a map image, each shape (H, W) bool, row 0 at the top.

    A cell is occupied if p > occupied_thresh, free if p < free_thresh (and opaque in
    ``scale`` mode), unknown otherwise (``raw``: also a value above 100).
    """
    rgb, tri, opaque = shade(img)
    if mode == "raw":
        percent = np.round(rgb)
        known = percent <= 100.0
        p = percent / 100.0
        occupied = known & (p > occupied_thresh)
        free = known & (p < free_thresh)
        return occupied, ~(occupied | free)
    value = tri if mode == "trinary" else rgb
    p = value / 255.0 if negate else (255.0 - value) / 255.0
    occupied = p > occupied_thresh
    free = p < free_thresh
    if mode == "scale":
        free &= opaque
        occupied &= opaque
    return occupied, ~(occupied | free)


def _cells(path: Path, where: str, shown: str):
    """:func:`read_cells`, plus the YAML table (for error lines) and the image path."""
    from PIL import Image, UnidentifiedImageError

    t = Table(read_yaml(path, where, shown), f"{where}.file: {shown}")
    image_name = t.string("image")
    resolution = t.number("resolution", low=0.0, low_open=True)
    origin = t.vector("origin", 3, what="[x, y, yaw]")
    negate = t.raw("negate", 0)
    if negate not in (0, 1) or isinstance(negate, float):
        t.fail(t.key("negate"), "expected 0 or 1", negate)
    occupied_thresh = t.number("occupied_thresh", 0.65, low=0.0, high=1.0)
    free_thresh = t.number("free_thresh", 0.196, low=0.0, high=1.0)
    if free_thresh > occupied_thresh:
        t.fail(t.key("free_thresh"), f"expected free_thresh <= occupied_thresh ({occupied_thresh:g})", free_thresh)
    mode = t.string("mode", "trinary", choices=MODES)
    t.done()
    if abs(origin[2]) > 1e-9:
        t.fail(t.key("origin"), "expected yaw 0 (rotated maps are not supported: rotate the map image)",
               list(origin))

    image_path = Path(image_name)
    if not image_path.is_absolute():
        image_path = path.parent / image_path  # map_server: relative to the YAML file
    try:
        regular = stat.S_ISREG(image_path.stat().st_mode)  # a FIFO would block the read
        size = image_size(image_path) if regular else None
    except FileNotFoundError:
        t.fail(t.key("image"), f"cannot read the map image {show_path(image_path)}: no such file", image_name)
    except OSError as exc:
        t.fail(t.key("image"), f"cannot read the map image {show_path(image_path)}: {exc.strerror or exc}",
               image_name)
    if not regular:
        t.fail(t.key("image"), f"expected a map image file, {show_path(image_path)} is not a regular file",
               image_name)
    if size is not None:
        _check_pixels(t, image_name, image_path, *size)
    try:
        with warnings.catch_warnings():
            # A big site map is not a decompression bomb; Pillow's warning would be stray output.
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            with Image.open(image_path) as img:
                _check_pixels(t, image_name, image_path, *img.size)  # header only: before decoding
                img.load()  # decode now: a truncated file fails here, not later
                occ_img, unk_img = classify(img, mode, bool(negate), occupied_thresh, free_thresh)
    except Image.DecompressionBombError:  # a format whose header we do not read: Pillow's own check
        t.fail(t.key("image"), f"{show_path(image_path)} has more than {2 * Image.MAX_IMAGE_PIXELS:.3g} pixels, "
               f"at most {MAX_MAP_PIXELS:.3g}", image_name)
    except FileNotFoundError:
        t.fail(t.key("image"), f"cannot read the map image {show_path(image_path)}: no such file", image_name)
    except UnidentifiedImageError:
        t.fail(t.key("image"), f"expected a PGM or PNG image, cannot read {show_path(image_path)}", image_name)
    except (OSError, ValueError, SyntaxError, struct.error) as exc:
        # Pillow: "image file is truncated", a header whose size does not match the data, ...
        t.fail(t.key("image"), f"cannot read the map image {show_path(image_path)} ({exc})", image_name)
    h, w = occ_img.shape
    if h == 0 or w == 0:
        t.fail(t.key("image"), f"expected a non-empty image, {image_path} is {w} x {h}", image_name)
    # image row 0 is the top of the map; the grid's row 0 its bottom
    return occ_img[::-1], unk_img[::-1], float(resolution), (float(origin[0]), float(origin[1])), t, image_path


def read_cells(path: str | Path, *, where: str | None = None,
               shown: str | None = None) -> tuple[np.ndarray, np.ndarray, float, tuple[float, float]]:
    """Read a ROS map_server map's cells.

    Returns
    -------
    occupied, unknown : ndarray of bool, shape (H, W)
        Occupied and unknown cells, row 0 at the **bottom** (y up): cell (r, c) covers
        [ox + c · res, ox + (c + 1) · res] x [oy + r · res, oy + (r + 1) · res].
    resolution : float
        Cell size [m].
    origin : (float, float)
        (ox, oy), the lower-left corner of the map [m].

    Raises
    ------
    ScenarioError
        Missing or unreadable YAML or image, bad keys, origin yaw ≠ 0.
    """
    path = Path(path)
    shown = shown or str(path)
    where = where or f"{shown}: floorplan"
    occ, unk, resolution, origin, _, _ = _cells(path, where, shown)
    return occ, unk, resolution, origin


def read_rosmap(path: str | Path, *, simplify: float | None = None, where: str | None = None,
                shown: str | None = None) -> FloorPlanData:
    """Read obstacle polygons from a ROS map_server map.

    Parameters
    ----------
    path : path
        The map YAML (``image``, ``resolution``, ``origin``, ``negate``, ``occupied_thresh``,
        ``free_thresh``, optional ``mode``); the image path is relative to the YAML file.
    simplify : float, optional
        Polygon simplification tolerance [m]; default: the map resolution (it removes the
        cell staircase of walls not aligned with the grid).
    where, shown : str, optional
        Key-path prefix and file name for error messages.

    Returns
    -------
    FloorPlanData
        Obstacles (occupied cells) and unknown areas (unknown cells within the known cells'
        bounding box) in metres in the map frame; extent = the whole map (origin .. origin +
        size · resolution); known = the bounding box of the known (free or occupied) cells.

    Raises
    ------
    ScenarioError
        Missing or unreadable YAML or image, bad keys, origin yaw ≠ 0.
    """
    path = Path(path)
    shown = shown or str(path)
    where = where or f"{shown}: floorplan"
    occ, unk, resolution, (ox, oy), t, image_path = _cells(path, where, shown)
    h, w = occ.shape
    image_name = t.data["image"]
    rows, cols = np.nonzero(~unk)
    if not len(rows):
        t.fail(t.key("image"), f"expected some known cells, every cell of {show_path(image_path)} is unknown",
               image_name)
    r0, r1, c0, c1 = int(rows.min()), int(rows.max()) + 1, int(cols.min()), int(cols.max()) + 1
    tol = resolution if simplify is None else simplify

    def polygons(cells: np.ndarray) -> list[dict]:
        polys = trace(cells[r0:r1, c0:c1])
        # Cell units -> metres: x = ox + column · resolution, y = oy + row · resolution.
        polys = shapely.transform(np.asarray(polys, dtype=object),
                                  lambda c: (c + (c0, r0)) * resolution + (ox, oy))
        return geometry.obstacle_dicts(shapely.GeometryCollection(list(polys)), tol)

    extent = (ox, oy, ox + w * resolution, oy + h * resolution)
    known = tuple(round(v, geometry.DECIMALS) for v in (ox + c0 * resolution, oy + r0 * resolution,
                                                       ox + c1 * resolution, oy + r1 * resolution))
    if not all(math.isfinite(v) for v in extent):
        t.fail(t.key("origin"), "expected a finite map extent", [ox, oy, 0.0])
    return FloorPlanData(obstacles=polygons(occ), markers=[], extent=extent, unit_factor=1.0, units="m",
                        simplify=tol, images=(image_path.resolve(),), unknown=polygons(unk), known=known,
                        walls=False, resolution=float(resolution))
