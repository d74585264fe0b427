"""Obstacles and reflectors from a DXF drawing (ezdxf).

Read from the obstacle layers: LINE, ARC and open LWPOLYLINE/POLYLINE/SPLINE/ELLIPSE become
walls of ``wall_thickness`` (an open LWPOLYLINE or POLYLINE drawn with widths: a wall of its
largest width, constant or per vertex); closed polylines are filled, nested ones by the
even-odd rule (an outer and an inner outline make a ring wall); HATCH (and MPOLYGON)
boundaries, SOLID and TRACE, closed splines and ellipses are filled; CIRCLE is a circle
obstacle; 3DFACE, polyface and polygon meshes (POLYLINE) are their 2D footprint, each face
filled (a vertical face, whose footprint is a segment, a wall of ``wall_thickness``). INSERT
(block references, MINSERT grids, nested, rotated, scaled) is expanded; an entity on layer "0"
inside a block takes the layer of its INSERT, as in CAD. Other layers are ignored; nothing of
the obstacle layers is dropped without a word: other entity types there (TEXT, DIMENSION, ...)
and INSERTs of external references (xrefs, whose geometry is in another file) are counted in
one :class:`~scenarios.errors.ScenarioWarning` line. Arcs and bulges are flattened within the
simplification tolerance.

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

from scenarios.errors import ScenarioError, ScenarioWarning
from scenarios.fields import MAX_COORD, show
from scenarios.floorplan import geometry
from scenarios.floorplan.spec import INSUNITS, UNITS, FloorPlanData
from scenarios.limits import MAX_DXF_ENTITIES, MAX_FIT_POINTS, MAX_SPLINE_FIT_POINTS, MIN_LENGTH

_OBSTACLE_TYPES = {"LINE", "ARC", "CIRCLE", "LWPOLYLINE", "POLYLINE", "SPLINE", "ELLIPSE",
                   "HATCH", "MPOLYGON", "SOLID", "TRACE", "3DFACE"}


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
    _check_complete(path, where, shown)
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


def _check_complete(path: Path, where: str, shown: str) -> None:
    """Refuse a drawing cut short: every DXF (text or binary) ends with its ``EOF`` marker.

    ezdxf's recovery reads what is there, so a drawing cut in half would otherwise be read as a
    drawing without the half that holds, say, the obstacle layer.
    """
    try:
        with path.open("rb") as f:
            head = f.read(4096)
            size = f.seek(0, 2)
            f.seek(max(size - 64, 0))
            tail = f.read()
    except OSError as exc:
        raise ScenarioError(f"{where}.file: cannot read {shown}: {exc.strerror or exc}") from None
    looks_dxf = b"SECTION" in head or head.startswith(b"AutoCAD Binary DXF")  # else ezdxf says what it is
    if looks_dxf and b"EOF" not in tail:
        raise ScenarioError(f"{where}.file: {shown}: the drawing is truncated: its {size} bytes end before the "
                            f"end-of-file marker (0 / EOF); save it again or copy it whole")


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


def _numbers(value) -> Iterator[float]:
    """Every number in ``value``: a number, a vector, or a (nested) sequence of them."""
    if value is None or isinstance(value, str):
        return
    if isinstance(value, (int, float, np.number)):
        yield float(value)
        return
    try:
        items = iter(value)
    except TypeError:
        return
    for v in items:
        yield from _numbers(v)


# What a DXF entity's geometry is made of: its numeric attributes, per type (the OCS ``extrusion``
# of every planar entity is checked with them), and the attribute holding its points.
_NUMERIC = {
    "LINE": ("start", "end"), "POINT": ("location",), "CIRCLE": ("center", "radius"),
    "ARC": ("center", "radius", "start_angle", "end_angle"),
    "ELLIPSE": ("center", "major_axis", "ratio", "start_param", "end_param"),
    "LWPOLYLINE": ("const_width", "elevation"), "SOLID": ("vtx0", "vtx1", "vtx2", "vtx3"),
    "TRACE": ("vtx0", "vtx1", "vtx2", "vtx3"), "3DFACE": ("vtx0", "vtx1", "vtx2", "vtx3"),
    "INSERT": ("insert", "xscale", "yscale", "zscale", "rotation", "row_spacing", "column_spacing"),
}
_EDGE_PARTS = ("start", "end", "center", "radius", "start_angle", "end_angle", "major_axis", "ratio",
               "control_points", "fit_points", "knot_values", "weights", "vertices")


class _Reader:
    """Walks the drawing's entities (blocks expanded, without recursion) and collects the geometry.

    Every entity is checked before ezdxf builds or flattens anything from it: finite numbers,
    coordinates within :data:`~scenarios.fields.MAX_COORD` metres; an error names the entity
    (type, handle, layer, and the block and INSERT it came through).
    """

    def __init__(self, obstacle_layers: set[str], marker_layer: str | None, flat: float, factor: float,
                 where: str, shown: str) -> None:
        self.obstacle_layers = obstacle_layers
        self.marker_layer = marker_layer
        self.flat = flat  # flattening distance [drawing units]
        self.bound = MAX_COORD / factor  # largest coordinate magnitude [drawing units]
        self.shortest = MIN_LENGTH / factor  # the loader's floor of a size [drawing units]
        self.where, self.shown = where, shown
        self.found = _Found()
        self.fit_points = 0  # SPLINE fit points read so far (blocks expanded)
        self.unread: dict[str, int] = {}  # entity type on an obstacle layer -> count, not read
        self.xrefs: dict[str, int] = {}  # block name of an external reference -> INSERTs of it

    # --- errors ---------------------------------------------------------------------------

    def fail(self, name: str, what: str) -> None:
        raise ScenarioError(f"{self.where}.file: {self.shown}: {name}: {what}")

    @staticmethod
    def name(e, layer: str, via: str) -> str:
        handle = e.dxf.get("handle")
        own = f"{e.dxftype()} #{handle}" if handle else e.dxftype()
        return f"{own} on layer {show(layer)}" + (f" in {via}" if via else "")

    def check(self, e, kind: str, name: str) -> None:
        """Refuse non-finite numbers and coordinates beyond the bound in ``e`` before ezdxf uses them."""
        values = [e.dxf.get(a) for a in _NUMERIC.get(kind, ())]
        ext = e.dxf.get("extrusion") if e.dxf.is_supported("extrusion") else None  # 3DFACE has none
        values.append(ext)
        if kind == "LWPOLYLINE":
            values.append(list(e.get_points("xyseb")))
        elif kind == "POLYLINE":
            values.append([[v.dxf.get(a) for a in ("location", "bulge", "start_width", "end_width")]
                           for v in e.vertices])
            values.append([e.dxf.get("default_start_width"), e.dxf.get("default_end_width")])
        elif kind == "SPLINE":
            n = e.fit_point_count()
            if n > MAX_SPLINE_FIT_POINTS:  # ezdxf interpolates them by a dense n x n solve
                self.fail(name, f"expected at most {MAX_SPLINE_FIT_POINTS} fit points a spline, found {n}")
            self.fit_points += n
            if self.fit_points > MAX_FIT_POINTS:
                self.fail(name, f"expected at most {MAX_FIT_POINTS} spline fit points in the drawing, found more "
                                f"({self.fit_points} up to this one)")
            values += [list(e.control_points), list(e.fit_points), list(e.knots), list(e.weights)]
        elif kind in ("HATCH", "MPOLYGON"):
            for bp in e.paths:
                values.append(getattr(bp, "vertices", None))
                values += [getattr(edge, part, None) for edge in getattr(bp, "edges", ()) for part in _EDGE_PARTS]
        numbers = np.fromiter(_numbers(values), dtype=float)
        if not np.isfinite(numbers).all():
            self.fail(name, "expected finite coordinates, sizes and angles, found nan or inf")
        if numbers.size and np.abs(numbers).max() > self.bound:
            self.fail(name, f"expected coordinates and sizes of magnitude at most {MAX_COORD:g} m, "
                            f"found {np.abs(numbers).max():.3g} drawing units")
        if ext is not None and not any(ext):
            self.fail(name, "expected a non-zero extrusion (OCS) vector, found (0, 0, 0)")
        if kind in ("CIRCLE", "ARC") and not e.dxf.radius >= self.shortest:
            self.fail(name, f"expected a radius of at least {MIN_LENGTH:g} m, found {e.dxf.radius:g} drawing units")
        if kind == "ELLIPSE" and not (any(e.dxf.major_axis) and 0.0 < e.dxf.ratio <= 1.0):
            self.fail(name, "expected a non-zero major axis and an axis ratio in (0, 1]")
        if kind == "SPLINE" and e.control_point_count() < 2 and e.fit_point_count() < 2:
            self.fail(name, "expected a spline with at least 2 control or fit points")
        if kind == "INSERT":
            if any(float(e.dxf.get(a, 1.0)) == 0.0 for a in ("xscale", "yscale", "zscale")):
                self.fail(name, "expected non-zero scale factors")

    def points(self, pts: np.ndarray, name: str) -> np.ndarray:
        """``pts`` after flattening, checked (a transform may still have carried them out of bounds)."""
        if not np.isfinite(pts).all() or (pts.size and np.abs(pts).max() > self.bound):
            self.fail(name, f"expected coordinates of magnitude at most {MAX_COORD:g} m after its block's "
                            f"transformation, found {np.abs(pts).max():.3g} drawing units")
        return pts

    # --- the walk ------------------------------------------------------------------------

    def walk(self, entities: Iterable) -> None:
        """Collect the geometry of ``entities`` (model space), following blocks to any depth."""
        # (entities, layer of the INSERT they came from, where they came from, that INSERT's name)
        stack: list[tuple[Iterator, str | None, str, str]] = [(iter(entities), None, "", "")]
        while stack:
            it, parent_layer, via, owner = stack[-1]
            try:
                with quiet_ezdxf():
                    e = next(it, None)
            except (ArithmeticError, ValueError, IndexError, TypeError, AttributeError) as exc:
                self.fail(owner, f"cannot expand its block ({type(exc).__name__}: {exc})")
            except Exception as exc:  # ezdxf's DXFError family, raised while expanding
                if not _is_dxf_error(exc):
                    raise
                self.fail(owner, f"cannot expand its block ({exc})")
            if e is None:
                stack.pop()
                continue
            layer = e.dxf.get("layer", "0")
            if layer == "0" and parent_layer is not None:
                layer = parent_layer  # CAD semantics: block content on layer 0 takes the INSERT's layer
            key = layer.upper()  # DXF layer names are case-insensitive
            kind = e.dxftype()
            name = self.name(e, layer, via)
            if kind == "INSERT":
                self.check(e, kind, name)
                if key == self.marker_layer:
                    self.marker_insert(e)
                    continue
                block = e.dxf.get("name", "")
                layout = e.block()
                if layout is None:
                    self.fail(name, f"expected a block defined in the drawing, found none named {show(block)}")
                if layout.block is not None and (layout.block.is_xref or layout.block.is_xref_overlay):
                    self.xrefs[block] = self.xrefs.get(block, 0) + max(int(e.mcount), 1)
                    continue  # its geometry is in another file
                inner = f"block {show(block)} of " + (via.split(" of ", 1)[1] if " of " in via else name)
                stack.append((_expand(e), layer, inner, name))
                continue
            obstacle = key in self.obstacle_layers and kind in _OBSTACLE_TYPES
            marker = key == self.marker_layer and kind in ("POINT", "CIRCLE")
            if not (obstacle or marker):
                if key in self.obstacle_layers and key != self.marker_layer:
                    self.unread[kind] = self.unread.get(kind, 0) + 1
                continue
            self.check(e, kind, name)
            try:
                if obstacle:
                    self.obstacle(e, kind, name)
                if marker:
                    p = e.dxf.location if kind == "POINT" else e.ocs().to_wcs(e.dxf.center)
                    self.found.markers.append((p.x, p.y, None, None))
            except ScenarioError:
                raise
            except (ArithmeticError, ValueError, IndexError, TypeError, AttributeError) as exc:
                self.fail(name, f"cannot read its geometry ({type(exc).__name__}: {exc})")
            except Exception as exc:
                if not _is_dxf_error(exc):
                    raise
                self.fail(name, f"cannot read its geometry ({exc})")

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

    def flatten(self, path, name: str) -> np.ndarray:
        # the path's own vertices first: flattening a path with a vertex at nan or 1e300 never ends
        self.points(_xy(path.control_vertices()), name)
        return self.points(_xy(path.flattening(self.flat)), name)

    def obstacle(self, e, kind: str, name: str) -> None:
        from ezdxf import path as dxfpath

        f = self.found
        if kind == "CIRCLE":
            c = e.ocs().to_wcs(e.dxf.center)
            self.points(_xy([c]), name)
            f.circles.append((c.x, c.y, abs(float(e.dxf.radius))))
        elif kind == "LINE":
            f.lines.append(self.points(_xy([e.dxf.start, e.dxf.end]), name))
        elif kind in ("HATCH", "MPOLYGON"):
            f.filled.append([self.flatten(p, name) for p in dxfpath.from_hatch(e)])
        elif kind in ("SOLID", "TRACE"):
            f.filled.append([self.flatten(dxfpath.make_path(e), name)])
        elif kind == "3DFACE":
            self.faces([[e.dxf.get(f"vtx{i}") for i in range(4)]], name)
        elif kind == "POLYLINE" and (e.is_polygon_mesh or e.is_poly_face_mesh):
            from ezdxf.render import MeshBuilder

            mesh = MeshBuilder.from_polyface(e)
            self.faces([[mesh.vertices[i] for i in face] for face in mesh.faces], name)
        else:
            pts = self.flatten(dxfpath.make_path(e), name)
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
            width = _largest_width(e, kind)
            if not closed and width > 0.0:
                f.wide.append((pts, width))  # a wall drawn as a wide polyline keeps its (largest) width
            elif not closed:
                f.lines.append(pts)
            elif kind in ("LWPOLYLINE", "POLYLINE"):
                f.rings.append(pts)
            else:
                f.filled.append([pts])


    def faces(self, faces: list[list], name: str) -> None:
        """Collect the 2D footprint of 3D ``faces`` (each a list of WCS vertices): filled, or a wall if vertical."""
        for face in faces:
            pts = self.points(_xy([v for v in face if v is not None]), name)
            if len(pts) < 2:
                continue
            ring = shapely.Polygon(pts) if len(pts) >= 3 else None
            if ring is not None and ring.is_valid and ring.area > self.shortest * max(np.ptp(pts, axis=0).max(), 0.0):
                self.found.filled.append([pts])
            else:  # seen edge-on from above (a vertical wall): the segment it spans
                ends = pts[np.argsort(pts @ (pts[-1] - pts[0] if np.any(pts[-1] != pts[0]) else np.ones(2)))]
                segment = np.array([ends[0], ends[-1]])
                if np.ptp(segment, axis=0).max() > 0.0:
                    self.found.lines.append(segment)

    def warn_unread(self) -> None:
        """Say in one warning line what of the obstacle layers was not read (types, xrefs), with counts."""
        parts = []
        if self.unread:
            kinds = ", ".join(f"{n} {k}" for k, n in sorted(self.unread.items(), key=lambda kv: (-kv[1], kv[0])))
            parts.append(f"entities not read as obstacles on the obstacle layers: {kinds}")
        if self.xrefs:
            blocks = ", ".join(f"{n} of {show(b)}" for b, n in sorted(self.xrefs.items()))
            parts.append(f"INSERTs of external references (xref) not read, their geometry is in another file "
                         f"(bind them in CAD to read them): {blocks}")
        if parts:
            import warnings

            warnings.warn(f"{self.where}.file: {self.shown}: " + "; ".join(parts), ScenarioWarning, stacklevel=2)


def _largest_width(e, kind: str) -> float:
    """Return the largest width a (LW)POLYLINE is drawn with: constant, default or per vertex (0: none)."""
    if kind == "LWPOLYLINE":
        widths = [float(e.dxf.get("const_width", 0.0))]
        widths += [w for p in e.get_points("se") for w in p]
    elif kind == "POLYLINE" and not e.is_3d_polyline:
        widths = [float(e.dxf.get(a, 0.0)) for a in ("default_start_width", "default_end_width")]
        widths += [float(v.dxf.get(a, 0.0)) for v in e.vertices for a in ("start_width", "end_width")]
    else:
        return 0.0
    return max(abs(w) for w in widths)


def _expand(insert) -> Iterator:
    """Yield the entities of an INSERT's block, transformed, one grid cell of a MINSERT after another."""
    for ins in (insert.multi_insert() if insert.mcount > 1 else (insert,)):
        yield from ins.virtual_entities()


def _count(n: int) -> str:
    return f"more than {MAX_DXF_ENTITIES}" if n > MAX_DXF_ENTITIES else str(n)


def _is_dxf_error(exc: Exception) -> bool:
    import ezdxf

    return isinstance(exc, ezdxf.DXFError)


def expanded_size(doc, entities: Iterable, where: str, shown: str) -> int:
    """Count the entities of ``entities`` with every block expanded, before anything is expanded.

    A block's size is the sum over its entities of 1, plus for an INSERT the count of its grid
    (MINSERT rows x columns) times its block's size; block sizes are computed once each,
    iteratively (no recursion however deep the nesting).

    Raises
    ------
    ScenarioError
        More than :data:`~scenarios.limits.MAX_DXF_ENTITIES` entities (naming the INSERT that
        brings the most), or a block that inserts itself (directly or through others).
    """
    sizes: dict[str, int] = {}
    cap = MAX_DXF_ENTITIES + 1  # sizes saturate here: enough to refuse, and no huge numbers

    def inserts(entities) -> list:
        return [e for e in entities if e.dxftype() == "INSERT"]

    def size_of(block_name: str) -> int:
        """Return the block's expanded size, with an explicit stack over its nested blocks."""
        key = block_name.upper()
        if key in sizes:
            return sizes[key]
        visiting: list[str] = []
        stack = [key]
        while stack:
            b = stack[-1]
            if b in sizes:
                stack.pop()
                continue
            layout = doc.blocks.get(b)
            if layout is None:  # a missing block: the walk names the INSERT
                sizes[b] = 0
                stack.pop()
                continue
            pending = [i.dxf.get("name", "").upper() for i in inserts(layout)]
            pending = [n for n in pending if n not in sizes]
            if b not in visiting:
                visiting.append(b)
            cycle = next((n for n in pending if n in visiting), None)
            if cycle is not None:
                raise ScenarioError(f"{where}.file: {shown}: block {show(cycle)} inserts itself (through "
                                    f"{' > '.join(visiting[visiting.index(cycle):] + [cycle])}): it expands "
                                    f"without end, at most {MAX_DXF_ENTITIES} entities")
            if pending:
                stack.extend(pending)
                continue
            total = 0
            for e in layout:
                total += 1
                if e.dxftype() == "INSERT":
                    total += max(int(e.mcount), 1) * sizes.get(e.dxf.get("name", "").upper(), 0)
                if total >= cap:
                    total = cap
                    break
            sizes[b] = total
            visiting.remove(b)
            stack.pop()
        return sizes[key]

    total, worst, worst_n = 0, None, -1
    for e in entities:
        n = 1
        if e.dxftype() == "INSERT":
            n += max(int(e.mcount), 1) * size_of(e.dxf.get("name", ""))
            if n > worst_n:
                worst, worst_n = e, n
        total += n
        if total > MAX_DXF_ENTITIES:
            what = (f"INSERT #{worst.dxf.get('handle')} on layer {show(worst.dxf.get('layer', '0'))} of block "
                    f"{show(worst.dxf.get('name', ''))} expands to {_count(worst_n)} entities; "
                    if worst is not None else "")
            raise ScenarioError(f"{where}.file: {shown}: {what}the drawing has more than {MAX_DXF_ENTITIES} "
                                f"entities with its blocks expanded, at most {MAX_DXF_ENTITIES}")
    return total


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
    msp = doc.modelspace()
    expanded_size(doc, msp, where, shown)  # the budget, before anything is expanded
    reader = _Reader(obst, mark, flat, factor, where, shown)
    reader.walk(msp)
    reader.warn_unread()
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
    generated = frozenset(m["id"] for m, raw in zip(markers, found.markers, strict=True) if raw[3] is None)
    pts = np.array([m["position"] for m in markers], dtype=float).reshape(-1, 2)
    disks = [shapely.Point(x, y).buffer(r, quad_segs=2) for x, y, r in circles]
    extent = geometry.bounds([area, *disks], pts)
    return FloorPlanData(obstacles=obstacles, markers=markers, extent=extent, unit_factor=factor,
                         units=unit_name, simplify=simplify, generated_ids=generated)


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
