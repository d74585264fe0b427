"""Reading one ``[[obstacles]]`` table: a box, a polygon (with holes) or a circle.

The keys decide the kind:

- box: ``center = [x, y]``, ``size = [length, width]``, optional ``yaw_deg``;
- circle: ``center = [x, y]``, ``radius``;
- polygon: ``polygon = [[x, y], ...]`` (a simple polygon, at least 3 vertices, either
  orientation, optionally closed by repeating the first vertex), optional
  ``holes = [[[x, y], ...], ...]`` (simple polygons strictly inside it, apart from each other).

Floor-plan importers build the same dicts and pass them through :func:`read_obstacle`, so
their obstacles are checked and reported like a file's.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import shapely
from shapely.geometry import Polygon

from scenarios.fields import Table
from scenarios.geometry import first_crossing
from scenarios.limits import MAX_RING_VERTICES, MIN_LENGTH
from scenarios.obstacles import Obstacle

_KINDS = "center + size [+ yaw_deg] (a box), center + radius (a circle) or polygon [+ holes]"


def read_obstacle(t: Table) -> Obstacle:
    """Validate one obstacle table and build the :class:`Obstacle`; errors name file and key."""
    if t.has("polygon"):
        for k in ("center", "size", "yaw_deg", "radius"):
            if t.has(k):
                t.fail(t.key(k), f"not a key of a polygon obstacle (expected {_KINDS})", t.data[k])
        shell = _ring(t, t.key("polygon"), t.raw("polygon"))
        holes = []
        raw_holes = t.raw("holes", [])
        if not isinstance(raw_holes, list):
            t.fail(t.key("holes"), "expected a list of rings [[[x, y], ...], ...]", raw_holes)
        outer = Polygon(shell)
        for i, h in enumerate(raw_holes):
            key = f"{t.key('holes')}[{i}]"
            ring = _ring(t, key, h)
            hole = Polygon(ring)
            if not outer.contains_properly(hole):
                t.fail(key, "expected a hole strictly inside the polygon", h)
            for j, other in enumerate(holes):
                if not Polygon(other).disjoint(hole):
                    t.fail(key, f"expected holes apart from each other (meets holes[{j}])", h)
            holes.append(ring)
        t.done()
        return Obstacle.from_polygon(shell, holes)
    if t.has("holes"):
        t.fail(t.key("holes"), "holes need a polygon (expected polygon = [[x, y], ...])", t.data["holes"])
    if t.has("radius"):
        for k in ("size", "yaw_deg"):
            if t.has(k):
                t.fail(t.key(k), f"not a key of a circle obstacle (expected {_KINDS})", t.data[k])
        ob = Obstacle.circle(t.vector("center", 2, what="[x, y]"),
                             t.number("radius", low=MIN_LENGTH, high=1000.0,  # a pillar, not a planet:
                                      what="a radius in metres"))  # its polygon has ~pi sqrt(r / 2 mm) sides
        t.done()
        return ob
    if not t.has("center") or not t.has("size"):
        t.fail(t.path, f"expected {_KINDS}", t.data)
    size = t.vector("size", 2, what="[length, width] in metres", positive=True)
    if min(size) < MIN_LENGTH:
        t.fail(t.key("size"), f"expected [length, width] in metres of at least {MIN_LENGTH:g}", list(size))
    ob = Obstacle.box(t.vector("center", 2, what="[x, y]"), size, math.radians(t.number("yaw_deg", 0.0)))
    t.done()
    return ob


def _ring(t: Table, key: str, value: Any) -> np.ndarray:
    """Read a simple ring of at least 3 distinct vertices with positive area, shape (n, 2) [m]."""
    what = "a list of at least 3 [x, y] vertices"
    if isinstance(value, list) and len(value) > MAX_RING_VERTICES:
        t.fail(key, f"expected at most {MAX_RING_VERTICES} vertices, got {len(value)}")
    ok = isinstance(value, list) and all(
        isinstance(v, list) and len(v) == 2
        and all(isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) for c in v)
        for v in value)
    if not ok:
        t.fail(key, f"expected {what}", value)
    ring = np.array(value, float).reshape(-1, 2)
    if len(ring) > 1 and np.array_equal(ring[0], ring[-1]):
        ring = ring[:-1]  # closed by repeating the first vertex
    if len(ring) < 3:
        t.fail(key, f"expected {what}", value)
    same = np.flatnonzero(np.all(ring == np.roll(ring, -1, axis=0), axis=1))
    if same.size:
        i = int(same[0])
        t.fail(key, f"expected distinct consecutive vertices (vertices {i} and {(i + 1) % len(ring)} coincide)",
               value)
    edge = np.hypot(*(np.roll(ring, -1, axis=0) - ring).T)
    if edge.min() < MIN_LENGTH:
        i = int(edge.argmin())
        t.fail(key, f"expected edges of at least {MIN_LENGTH:g} m (vertices {i} and {(i + 1) % len(ring)} are "
               f"{edge[i]:.3g} m apart)", value)
    crossing = first_crossing(ring)
    if crossing is not None:
        t.fail(key, f"expected a simple polygon (edges {crossing[0]} and {crossing[1]} cross)", value)
    if not shapely.area(Polygon(ring)) > 0.0:
        t.fail(key, "expected a polygon with positive area", value)
    return ring
