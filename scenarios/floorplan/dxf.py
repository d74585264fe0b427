"""Obstacles and reflectors from a DXF drawing (ezdxf).

Read from the obstacle layers: LINE, ARC and open LWPOLYLINE/POLYLINE/SPLINE/ELLIPSE become
walls of ``wall_thickness`` (an open LWPOLYLINE with a constant width: a wall that wide);
closed polylines are filled, nested ones by the even-odd rule (an outer and an inner outline
make a ring wall); HATCH (and MPOLYGON) boundaries, SOLID and TRACE, closed splines and
ellipses are filled; CIRCLE is a circle obstacle. INSERT (block
references, MINSERT grids, nested, rotated, scaled) is expanded; an entity on layer "0"
inside a block takes the layer of its INSERT, as in CAD. Everything else (text, dimensions,
other layers) is ignored. Arcs and bulges are flattened within the simplification tolerance.

Reflectors come from ``marker_layer``: a POINT, a CIRCLE's centre or an INSERT's insertion
point; the id from the INSERT's ``ID`` attribute, else ``R1``, ``R2``, ... in drawing order;
an INSERT's rotation is kept as ``facing_deg``.
"""

from __future__ import annotations

import contextlib
import logging
import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import shapely

from scenarios.errors import ScenarioError
from scenarios.fields import show
from scenarios.floorplan import geometry
from scenarios.floorplan.spec import INSUNITS, UNITS, FloorPlanData

MAX_BLOCK_DEPTH = 16  # deeper nesting is a block that references itself
_OBSTACLE_TYPES = {"LINE", "ARC", "CIRCLE", "LWPOLYLINE", "POLYLINE", "SPLINE", "ELLIPSE",
                   "HATCH", "MPOLYGON", "SOLID", "TRACE"}


@contextlib.contextmanager
def quiet_ezdxf() -> Iterator[None]:
    """Keep ezdxf's log warnings about a sloppy file off the terminal while reading it.

    Without a handler of its own, Python prints a library's warnings to stderr; bad input
    must give one line (the error), never library chatter.
    """
    log = logging.getLogger("ezdxf")
    level = log.level
    log.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        log.setLevel(level)


def open_dxf(path: Path, where: str, shown: str):
    """Read the drawing at ``path``; a missing, unreadable or non-DXF file is one error line."""
    import ezdxf
    from ezdxf import recover

    if path.suffix.lower() == ".dwg":
        raise ScenarioError(f"{where}.file: expected a DXF drawing (save or convert the DWG as DXF), "
                            f"got {show(shown)}")
    with quiet_ezdxf():
        try:
            return ezdxf.readfile(path)
        except OSError as exc:
            if exc.errno is not None:  # the file system's error; else ezdxf's "not a DXF file"
                raise ScenarioError(f"{where}.file: cannot read {shown}: {exc.strerror or exc}") from None
            raise ScenarioError(f"{where}.file: expected a DXF drawing, cannot read {shown}: it is not one") from None
        except (ezdxf.DXFError, UnicodeDecodeError, ValueError):
            pass
        try:
            # Drawings written by other tools are often a little off the standard.
            doc, _auditor = recover.readfile(path)
            return doc
        except (OSError, ezdxf.DXFError, UnicodeDecodeError, ValueError) as exc:
            raise ScenarioError(f"{where}.file: expected a DXF drawing, cannot read {shown}: {exc}") from None


def unit_factor(doc, units: str | None, where: str, shown: str) -> tuple[str, float]:
    """Return the drawing unit's name and metres per unit: ``units`` if given, else ``$INSUNITS``."""
    if units is not None:
        return units, UNITS[units]
    code = doc.header.get("$INSUNITS", 0)
    name = INSUNITS.get(code)
    if name is None:
        what = "unitless" if code == 0 else "not a length unit pefsim knows"
        raise ScenarioError(f"{where}.units: expected the drawing's units ({shown} has $INSUNITS = {code}, "
                            f"{what}): set floorplan.units to one of {', '.join(UNITS)}")
    return name, UNITS[name]


@dataclass
class _Found:
    """Geometry collected from the drawing, in drawing units (WCS)."""

    rings: list[np.ndarray] = field(default_factory=list)      # closed outlines, even-odd
    lines: list[np.ndarray] = field(default_factory=list)      # open centre lines -> walls
    wide: list[tuple[np.ndarray, float]] = field(default_factory=list)  # polylines with a width
    filled: list[list[np.ndarray]] = field(default_factory=list)  # each: rings filled even-odd
    circles: list[tuple[float, float, float]] = field(default_factory=list)  # x, y, r
    markers: list[tuple[float, float, float | None, str | None]] = field(default_factory=list)


def _xy(points: Iterable) -> np.ndarray:
    return np.array([(p[0], p[1]) for p in points], dtype=float).reshape(-1, 2)


class _Reader:
    def __init__(self, obstacle_layers: set[str], marker_layer: str | None, flat: float) -> None:
        self.obstacle_layers = obstacle_layers
        self.marker_layer = marker_layer
        self.flat = flat  # flattening distance [drawing units]
        self.found = _Found()

    def walk(self, entities: Iterable, parent_layer: str | None, depth: int) -> None:
        for e in entities:
            layer = e.dxf.get("layer", "0")
            if layer == "0" and parent_layer is not None:
                layer = parent_layer  # CAD semantics: block content on layer 0 takes the INSERT's layer
            key = layer.upper()  # DXF layer names are case-insensitive
            kind = e.dxftype()
            if kind == "INSERT":
                if key == self.marker_layer:
                    self.marker_insert(e)
                elif depth < MAX_BLOCK_DEPTH:
                    for ins in (e.multi_insert() if e.mcount > 1 else (e,)):
                        with quiet_ezdxf():
                            subs = list(ins.virtual_entities())
                        self.walk(subs, layer, depth + 1)
                continue
            if key in self.obstacle_layers and kind in _OBSTACLE_TYPES:
                self.obstacle(e, kind)
            if key == self.marker_layer:
                if kind == "POINT":
                    p = e.dxf.location
                    self.found.markers.append((p.x, p.y, None, None))
                elif kind == "CIRCLE":
                    p = e.ocs().to_wcs(e.dxf.center)
                    self.found.markers.append((p.x, p.y, None, None))

    def marker_insert(self, e) -> None:
        p = e.ocs().to_wcs(e.dxf.insert)
        mid = None
        for a in e.attribs:
            if a.dxf.tag.upper() == "ID" and a.dxf.text.strip():
                mid = a.dxf.text.strip()
        if mid is None:
            const = e.get_attrib("ID", search_const=True)
            if const is not None and const.dxf.text.strip():
                mid = const.dxf.text.strip()
        facing = float(e.dxf.rotation) % 360.0
        self.found.markers.append((p.x, p.y, facing, mid))

    def flatten(self, path) -> np.ndarray:
        return _xy(path.flattening(self.flat))

    def obstacle(self, e, kind: str) -> None:
        from ezdxf import path as dxfpath

        f = self.found
        if kind == "CIRCLE":
            c = e.ocs().to_wcs(e.dxf.center)
            f.circles.append((c.x, c.y, abs(float(e.dxf.radius))))
        elif kind == "LINE":
            f.lines.append(_xy([e.dxf.start, e.dxf.end]))
        elif kind in ("HATCH", "MPOLYGON"):
            f.filled.append([self.flatten(p) for p in dxfpath.from_hatch(e)])
        elif kind in ("SOLID", "TRACE"):
            f.filled.append([self.flatten(dxfpath.make_path(e))])
        else:
            if kind == "POLYLINE" and (e.is_polygon_mesh or e.is_poly_face_mesh):
                return
            pts = self.flatten(dxfpath.make_path(e))
            if len(pts) < 2:
                return
            if kind == "LWPOLYLINE":
                closed = e.closed
            elif kind == "POLYLINE":
                closed = e.is_closed
            elif kind == "SPLINE":
                closed = e.closed
            elif kind == "ELLIPSE":
                closed = math.isclose(abs(e.dxf.end_param - e.dxf.start_param), math.tau, abs_tol=1e-9)
            else:  # ARC
                closed = False
            # An outline whose last vertex is its first is closed, whatever its flag says.
            closed = closed or (len(pts) > 3 and np.allclose(pts[0], pts[-1]))
            width = float(e.dxf.get("const_width", 0.0)) if kind == "LWPOLYLINE" else 0.0
            if not closed and width > 0.0:
                f.wide.append((pts, width))  # a wall drawn as a wide polyline keeps its width
            elif not closed:
                f.lines.append(pts)
            elif kind in ("LWPOLYLINE", "POLYLINE"):
                f.rings.append(pts)
            else:
                f.filled.append([pts])


def drawing_layers(doc) -> dict[str, str]:
    """Return the drawing's layers, upper-case name -> name as written (table and model space)."""
    names = {layer.dxf.name.upper(): layer.dxf.name for layer in doc.layers}
    for e in doc.modelspace():
        name = e.dxf.get("layer", "0")
        names.setdefault(name.upper(), name)
    return names


def read_dxf(path: str | Path, *, obstacle_layers: Iterable[str], marker_layer: str | None = None,
             units: str | None = None, wall_thickness: float = 0.2, simplify: float = 0.02,
             where: str | None = None, shown: str | None = None) -> FloorPlanData:
    """Read obstacles and reflectors from a DXF drawing.

    Parameters
    ----------
    path : path
        The drawing.
    obstacle_layers : iterable of str
        Layers whose entities are obstacles (case-insensitive, as in CAD).
    marker_layer : str, optional
        Layer of the reflectors.
    units : str, optional
        Drawing unit (a key of :data:`~scenarios.floorplan.spec.UNITS`); default the
        drawing's ``$INSUNITS``.
    wall_thickness : float
        Thickness of walls drawn as open lines [m], > 0.
    simplify : float
        Tolerance [m], >= 0: the obstacles stay within it of the drawing (half of it
        flattens arcs and bulges, half simplifies the polygons).
    where : str, optional
        Prefix of error messages' key paths, e.g. ``"hall.toml: floorplan"``.
    shown : str, optional
        The drawing's name in messages (default: ``path``).

    Returns
    -------
    FloorPlanData
        Obstacles and markers in metres, in the drawing's frame.

    Raises
    ------
    ScenarioError
        Missing or unreadable file, unknown layer, no units, nothing on the layers,
        duplicate reflector ids.
    """
    path = Path(path)
    shown = shown or str(path)
    where = where or f"{shown}: floorplan"
    doc = open_dxf(path, where, shown)
    unit_name, factor = unit_factor(doc, units, where, shown)
    layers = drawing_layers(doc)
    obstacle_layers = list(obstacle_layers)

    def check_layer(key: str, name: str) -> str:
        if name.upper() not in layers:
            raise ScenarioError(f"{where}.{key}: expected a layer of {shown} "
                                f"({', '.join(sorted(layers.values()))}), got {show(name)}")
        return name.upper()

    obst = {check_layer("obstacle_layers", n) for n in obstacle_layers}
    mark = check_layer("marker_layer", marker_layer) if marker_layer is not None else None
    # Half the tolerance flattens arcs (at least to 1 mm), half simplifies the polygons, so
    # the result stays within ``simplify`` of the drawing.
    flat = max(0.5 * simplify, 1e-3) / factor
    reader = _Reader(obst, mark, flat)
    reader.walk(doc.modelspace(), None, 0)
    found = reader.found

    rings = [r * factor for r in found.rings]
    closed = geometry.even_odd(rings)
    walls = shapely.union_all([geometry.walls([ln * factor for ln in found.lines], wall_thickness),
                               *(geometry.walls([ln * factor], w * factor) for ln, w in found.wide)])
    filled = [geometry.even_odd([r * factor for r in group]) for group in found.filled]
    area = shapely.union_all([closed, walls, *filled])
    obstacles = geometry.obstacle_dicts(area, 0.5 * simplify)
    circles = [(x * factor, y * factor, r * factor) for x, y, r in found.circles if r > 0.0]
    obstacles += [geometry.circle_dict((x, y), r) for x, y, r in circles]
    if not obstacles:
        raise ScenarioError(f"{where}.obstacle_layers: expected lines, polylines, circles, arcs, hatches or "
                            f"blocks on these layers of {shown}, found none, got {show(obstacle_layers)}")
    markers = _markers(found.markers, factor, where, shown, marker_layer)
    pts = np.array([m["position"] for m in markers], dtype=float).reshape(-1, 2)
    disks = [shapely.Point(x, y).buffer(r, quad_segs=2) for x, y, r in circles]
    extent = geometry.bounds([area, *disks], pts)
    return FloorPlanData(obstacles=obstacles, markers=markers, extent=extent, unit_factor=factor,
                         units=unit_name, simplify=simplify)


def _markers(raw, factor: float, where: str, shown: str, layer: str | None) -> list[dict]:
    if layer is not None and not raw:
        raise ScenarioError(f"{where}.marker_layer: expected POINTs, CIRCLEs or INSERTs on this layer of "
                            f"{shown}, found none, got {show(layer)}")
    given = [m[3] for m in raw if m[3] is not None]
    seen: set[str] = set()
    for mid in given:
        if mid in seen:
            raise ScenarioError(f"{where}.marker_layer: expected unique reflector IDs in {shown}, "
                                f"got {show(mid)} twice")
        seen.add(mid)
    n = 0
    out = []
    for x, y, facing, mid in raw:
        if mid is None:
            # Generated ids never take one the drawing gives to another reflector.
            n += 1
            while f"R{n}" in seen:
                n += 1
            mid = f"R{n}"
        m: dict = {"id": mid, "position": [round(x * factor, geometry.DECIMALS), round(y * factor, geometry.DECIMALS)]}
        if facing is not None:
            m["facing_deg"] = round(facing, 9)
        out.append(m)
    return out
