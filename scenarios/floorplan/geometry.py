"""Planar geometry shared by the floor-plan readers: even-odd filling, walls, obstacle dicts.

Everything here works in metres on shapely geometries; the readers convert drawing units
before they call in. The output is the scenario's TOML form of an obstacle, so the loader
validates floor-plan obstacles exactly like hand-written ones.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
import shapely
from shapely.geometry import LinearRing, MultiPolygon, Polygon
from shapely.geometry.base import BaseGeometry
from shapely.geometry.polygon import orient

# Coordinates written into the scenario are rounded to this many decimals (1 nm): enough for
# any drawing, and it keeps float noise like 0.30000000000000004 out of printed scenarios.
DECIMALS = 9


def even_odd(rings: Sequence[np.ndarray]) -> BaseGeometry:
    """Fill closed outlines by the even-odd rule.

    A point is inside when it lies inside an odd number of ``rings``: a wall drawn as an
    outer and an inner outline is a ring, a rack drawn inside a room outline is solid
    again. Identical outlines drawn twice count once (CAD users often trace a boundary
    twice, e.g. one polyline per layer, and would otherwise cancel it).

    Parameters
    ----------
    rings : sequence of ndarray, each shape (n, 2) [m]
        Closed outlines (the closing vertex may be repeated or not); n >= 3.

    Returns
    -------
    shapely geometry
        The filled area (possibly empty).
    """
    unique: dict[frozenset, np.ndarray] = {}
    for r in rings:
        r = np.asarray(r, dtype=float)
        if len(r) >= 2 and np.allclose(r[0], r[-1]):
            r = r[:-1]
        if len(r) < 3:
            continue
        unique.setdefault(frozenset(map(tuple, np.round(r, 6))), r)
    polys = [shapely.make_valid(Polygon(r)) for r in unique.values()]
    polys = [p for p in polys if p.area > 0.0]
    if not polys:
        return Polygon()
    if len(polys) == 1:
        return polys[0]
    # Node all outlines against each other; every face of the arrangement is then inside a
    # fixed set of outlines, and its parity decides. Faces are tested at an interior point.
    lines = shapely.union_all([LinearRing(r) for r in unique.values()])
    faces = list(shapely.get_parts(shapely.polygonize(shapely.get_parts(lines))))
    if not faces:
        return Polygon()
    points = shapely.point_on_surface(faces)
    tree = shapely.STRtree(polys)
    point_idx, _ = tree.query(points, predicate="within")
    counts = np.bincount(point_idx, minlength=len(faces))
    kept = [f for f, c in zip(faces, counts, strict=True) if c % 2 == 1]
    return shapely.union_all(kept) if kept else Polygon()


def walls(lines: Iterable[np.ndarray], thickness: float) -> BaseGeometry:
    """Thicken open centre lines into walls.

    Square caps and mitred joins: two wall lines that meet at a corner close it, like the
    walls of a CAD drawing drawn as centre lines.

    Parameters
    ----------
    lines : iterable of ndarray, each shape (n, 2) [m]
        Open polylines (n >= 2).
    thickness : float
        Wall thickness [m], > 0.
    """
    geoms = [shapely.LineString(p) for p in lines if len(p) >= 2]
    geoms = [g for g in geoms if g.length > 0.0]
    if not geoms:
        return Polygon()
    half = 0.5 * thickness
    return shapely.union_all(shapely.buffer(geoms, half, cap_style="square", join_style="mitre"))


def polygons_of(geom: BaseGeometry) -> list[Polygon]:
    """Return the polygons of ``geom`` (a polygon, a multipolygon or a collection), non-empty only."""
    out = []
    for g in shapely.get_parts(geom):
        if isinstance(g, Polygon) and not g.is_empty:
            out.append(g)
        elif isinstance(g, MultiPolygon):
            out.extend(p for p in g.geoms if not p.is_empty)
    return out


def obstacle_dicts(geom: BaseGeometry, simplify: float) -> list[dict]:
    """Polygon obstacles in the scenario's TOML form, simplified within ``simplify`` [m].

    Returns
    -------
    list of dict
        ``{"polygon": [[x, y], ...]}`` with the exterior counter-clockwise and without the
        closing vertex, plus ``"holes": [[[x, y], ...], ...]`` (clockwise) when it has any.
    """
    polys = np.asarray(polygons_of(geom), dtype=object)
    if simplify > 0.0 and len(polys):
        polys = shapely.simplify(polys, simplify, preserve_topology=True)
    polys = np.asarray([p for g in polys for p in polygons_of(g)], dtype=object)
    if len(polys) == 0:
        return []
    polys = polys[shapely.area(polys) > 0.0]
    polys = np.asarray([_apart(p) for p in polys], dtype=object)
    # Vectorised for traced maps with thousands of polygons: exteriors counter-clockwise,
    # holes clockwise, coordinates split per ring without a Python call per vertex.
    polys = np.asarray([orient(p, 1.0) for p in polys], dtype=object)
    shells = _split_rings(shapely.get_exterior_ring(polys))
    n_holes = shapely.get_num_interior_rings(polys)
    out = []
    for p, shell, nh in zip(polys, shells, n_holes.tolist(), strict=True):
        d: dict = {"polygon": shell}
        if nh:
            d["holes"] = _split_rings(np.asarray(p.interiors, dtype=object))
        out.append(d)
    return out


def _apart(poly: Polygon) -> Polygon:
    """Shrink holes that touch the exterior or each other (at a point) by 1 µm.

    A valid shapely polygon may have such holes; a scenario's holes must lie strictly inside
    and apart (the obstacle loader's rule), and a 1 µm gap changes nothing for a robot.
    """
    if not poly.interiors:
        return poly
    holes = [Polygon(h) for h in poly.interiors]
    shell = Polygon(poly.exterior)
    merged = shapely.union_all(holes)
    touching = not all(shell.contains_properly(h) for h in holes) or len(polygons_of(merged)) != len(holes) \
        or any(a.intersects(b) for i, a in enumerate(holes) for b in holes[i + 1:])
    if not touching:
        return poly
    shrunk = [q for h in holes for q in polygons_of(h.buffer(-1e-6, join_style="mitre")) if q.area > 0.0]
    return Polygon(poly.exterior, [q.exterior for q in shrunk])


def _split_rings(rings: np.ndarray) -> list[list[list[float]]]:
    """Vertex lists of closed rings, without the closing vertex, rounded to :data:`DECIMALS`."""
    xy, idx = shapely.get_coordinates(rings, return_index=True)
    xy = np.round(xy, DECIMALS)
    counts = np.bincount(idx, minlength=len(rings))
    parts = np.split(xy, np.cumsum(counts)[:-1])
    return [part[:-1].tolist() for part in parts]


def circle_dict(center: Sequence[float], radius: float) -> dict:
    """Return a circle obstacle in the scenario's TOML form; ``center`` (x, y) [m], ``radius`` [m]."""
    return {"center": [round(float(center[0]), DECIMALS), round(float(center[1]), DECIMALS)],
            "radius": round(float(radius), DECIMALS)}


def bounds(geoms: Iterable[BaseGeometry], points: np.ndarray) -> tuple[float, float, float, float] | None:
    """Bounding box (xmin, ymin, xmax, ymax) [m] of ``geoms`` and ``points`` (shape (n, 2)).

    Returns ``None`` when there is nothing at all.
    """
    boxes = [g.bounds for g in geoms if not g.is_empty]
    if len(points):
        p = np.asarray(points, dtype=float)
        boxes.append((p[:, 0].min(), p[:, 1].min(), p[:, 0].max(), p[:, 1].max()))
    if not boxes:
        return None
    b = np.array(boxes)
    return (float(b[:, 0].min()), float(b[:, 1].min()), float(b[:, 2].max()), float(b[:, 3].max()))
