"""Obstacles: boxes, simple polygons with holes, circles, and their convex pieces.

One class, :class:`Obstacle`, serves every shape so that code which only needs "where is
solid" asks for :meth:`Obstacle.geometry` (a shapely polygon) or :meth:`Obstacle.pieces`
(convex polygons, see :mod:`scenarios.geometry`) and never for the kind. Construct with
:meth:`Obstacle.box` (or ``Obstacle(center, size, yaw)``), :meth:`Obstacle.circle` and
:meth:`Obstacle.from_polygon`; :mod:`scenarios.obstacle_table` reads them from a file.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import shapely
from shapely.geometry import Polygon

from scenarios.geometry import circle_vertices, convex_pieces

Point = tuple[float, float]


@dataclass(frozen=True)
class Obstacle:
    """A solid obstacle.

    Attributes
    ----------
    center : (float, float)
        Box or circle centre [m]; for a polygon the centroid of its area.
    size : (float, float)
        Box: (length along its x, width) [m]; (0, 0) for other kinds.
    yaw : float
        Box rotation [rad].
    radius : float
        Circle radius [m]; 0 for other kinds.
    polygon : tuple of (float, float)
        Polygon outer ring as given (either orientation, not closed) [m]; empty for other kinds.
    holes : tuple of tuple of (float, float)
        Polygon holes, each a ring like ``polygon`` [m].
    """

    center: Point = (0.0, 0.0)
    size: Point = (0.0, 0.0)
    yaw: float = 0.0
    radius: float = 0.0
    polygon: tuple[Point, ...] = ()
    holes: tuple[tuple[Point, ...], ...] = field(default=())

    # --- construction ---------------------------------------------------------------------

    @classmethod
    def box(cls, center: Point, size: Point, yaw: float = 0.0) -> Obstacle:
        """Make a box: ``center`` [m], ``size`` (length, width) [m], ``yaw`` [rad]."""
        return cls(center=tuple(map(float, center)), size=tuple(map(float, size)), yaw=float(yaw))

    @classmethod
    def circle(cls, center: Point, radius: float) -> Obstacle:
        """Make a circle (a round pillar): ``center`` [m], ``radius`` [m]."""
        return cls(center=tuple(map(float, center)), radius=float(radius))

    @classmethod
    def from_polygon(cls, shell, holes=()) -> Obstacle:
        """Make a simple polygon, optionally with holes; rings as (n, 2) sequences [m], either orientation."""
        ring = tuple((float(x), float(y)) for x, y in shell)
        hs = tuple(tuple((float(x), float(y)) for x, y in h) for h in holes)
        c = Polygon(ring, hs).centroid
        return cls(center=(float(c.x), float(c.y)), polygon=ring, holes=hs)

    @property
    def kind(self) -> str:
        """``"polygon"``, ``"circle"`` or ``"box"``."""
        if self.polygon:
            return "polygon"
        return "circle" if self.radius > 0.0 else "box"

    # --- shape ----------------------------------------------------------------------------

    def corners(self) -> np.ndarray:
        """Box corners, shape (4, 2) [m], counter-clockwise; a ``ValueError`` for other kinds."""
        if self.kind != "box":
            raise ValueError(f"a {self.kind} obstacle has no box corners; use pieces()")
        hx, hy = self.size[0] / 2.0, self.size[1] / 2.0
        local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        rot = np.array([[c, -s], [s, c]])
        return local @ rot.T + np.asarray(self.center)

    @cached_property
    def _geometry(self) -> Polygon:
        if self.kind == "box":
            g = Polygon(self.corners())
        elif self.kind == "circle":
            g = Polygon(circle_vertices(self.center, self.radius))
        else:
            g = shapely.normalize(Polygon(self.polygon, self.holes))
        shapely.prepare(g)
        return g

    def geometry(self) -> Polygon:
        """Return the solid region as a shapely polygon [m] (prepared, do not modify).

        A circle is its circumscribed polygon (:func:`scenarios.geometry.circle_vertices`), the
        same shape every planner, physics and figure uses.
        """
        return self._geometry

    @cached_property
    def _pieces(self) -> tuple[np.ndarray, ...]:
        if self.kind == "box":
            return (self.corners(),)
        return tuple(convex_pieces(self._geometry))

    def pieces(self) -> tuple[np.ndarray, ...]:
        """Convex pieces whose union is :meth:`geometry`, each (n_i, 2) counter-clockwise [m]."""
        return self._pieces

    def rings(self) -> list[np.ndarray]:
        """Boundary rings, outer one first then the holes, each (n_i, 2) not closed [m]."""
        g = self._geometry
        return [np.asarray(r.coords)[:-1] for r in (g.exterior, *g.interiors)]

    def bounds(self) -> tuple[float, float, float, float]:
        """Bounding box (xmin, ymin, xmax, ymax) [m]."""
        return tuple(float(v) for v in self._geometry.bounds)

    def contains(self, p: Point | np.ndarray, margin: float = 0.0) -> bool:
        """Tell whether point ``p`` lies inside the obstacle grown by ``margin`` [m] (boundary in).

        A box grows on every side (square corners, as always); other shapes grow by distance
        (round corners). A negative margin shrinks the obstacle: the point must be inside and
        at least ``-margin`` from its boundary. A circle is tested as the true circle (not its
        polygon), so that markers on a pillar's surface count as outside it.
        """
        if self.kind == "box":  # scalar arithmetic: a scenario checks every marker against every box
            c, s = math.cos(self.yaw), math.sin(self.yaw)
            dx, dy = float(p[0]) - self.center[0], float(p[1]) - self.center[1]
            return (abs(c * dx + s * dy) <= self.size[0] / 2 + margin
                    and abs(-s * dx + c * dy) <= self.size[1] / 2 + margin)
        return bool(self.contains_points(np.asarray(p, float)[None, :2], margin)[0])

    def contains_points(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """:meth:`contains` for many points: ``points`` (N, 2) [m], result (N,) bool."""
        q = np.asarray(points, float).reshape(-1, 2)
        if self.kind == "box":
            c, s = math.cos(self.yaw), math.sin(self.yaw)
            dx, dy = q[:, 0] - self.center[0], q[:, 1] - self.center[1]
            lx, ly = c * dx + s * dy, -s * dx + c * dy
            return (np.abs(lx) <= self.size[0] / 2 + margin) & (np.abs(ly) <= self.size[1] / 2 + margin)
        if self.kind == "circle":
            # The true circle: a reflector on a pillar's surface is outside it.
            return np.hypot(q[:, 0] - self.center[0], q[:, 1] - self.center[1]) <= self.radius + margin
        g = self._geometry
        pts = shapely.points(q)
        if margin >= 0.0:
            return shapely.distance(g, pts) <= margin
        return shapely.contains(g, pts) & (shapely.distance(g.boundary, pts) >= -margin)

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Distance from each point to the obstacle, 0 inside; ``points`` (N, 2), result (N,) [m]."""
        p = np.asarray(points, float).reshape(-1, 2)
        return shapely.distance(self._geometry, shapely.points(p))

    def to_dict(self) -> dict:
        """Return the ``[[obstacles]]`` table that reads back as this obstacle (for writing TOML)."""
        if self.kind == "polygon":
            d: dict = {"polygon": [list(v) for v in self.polygon]}
            if self.holes:
                d["holes"] = [[list(v) for v in h] for h in self.holes]
            return d
        if self.kind == "circle":
            return {"center": list(self.center), "radius": self.radius}
        return {"center": list(self.center), "size": list(self.size), "yaw_deg": math.degrees(self.yaw)}


@dataclass(frozen=True, eq=False)
class ConvexPieces:
    """The convex pieces of a set of obstacles, padded into arrays for kernels.

    Attributes
    ----------
    vertices : ndarray, shape (P, V, 2)
        Piece p's vertices counter-clockwise in ``vertices[p, :count[p]]`` [m]; the rest
        repeats its last vertex (a zero-length edge), so loops over all V stay harmless.
    count : ndarray of int64, shape (P,)
        Vertex count of each piece (>= 3).
    owner : ndarray of int64, shape (P,)
        Index of the obstacle each piece belongs to.
    inner : ndarray of bool, shape (P, V)
        ``inner[p, k]``: edge k (from vertex k to k + 1) lies inside its obstacle, a cut
        between two of its pieces, not on the obstacle's boundary.
    inset : ndarray, shape (P, V)
        How far face k lies outside the true obstacle [m]: for a circle's circumscribed
        polygon ``r (1 - cos(pi / n))`` on every face (moved in by that much its polygon is
        the inscribed one, whose vertices lie on the circle), 0 elsewhere. Line of sight uses
        it, so that a marker on a pillar's surface is seen from its side.

    Compared and hashed by identity, so that kernels' preparations can be cached per object.
    """

    vertices: np.ndarray
    count: np.ndarray
    owner: np.ndarray
    inner: np.ndarray
    inset: np.ndarray

    def __len__(self) -> int:
        return int(self.count.size)


def pack_pieces(obstacles) -> ConvexPieces:
    """Pack the convex pieces of ``obstacles`` (a sequence of :class:`Obstacle`) for kernels."""
    pieces = [(k, p) for k, ob in enumerate(obstacles) for p in ob.pieces()]
    nv = max((len(p) for _, p in pieces), default=3)
    verts = np.zeros((len(pieces), nv, 2))
    count = np.zeros(len(pieces), dtype=np.int64)
    owner = np.zeros(len(pieces), dtype=np.int64)
    inner = np.zeros((len(pieces), nv), dtype=np.bool_)
    inset = np.zeros((len(pieces), nv))
    for i, (k, p) in enumerate(pieces):
        verts[i, :len(p)] = p
        verts[i, len(p):] = p[-1]
        count[i], owner[i] = len(p), k
        if obstacles[k].kind == "circle":
            inset[i, :len(p)] = obstacles[k].radius * (1.0 - math.cos(math.pi / len(p)))
        if len(obstacles[k].pieces()) > 1:
            # A cut's midpoint lies well inside the obstacle, a face's on its boundary.
            mid = 0.5 * (p + np.roll(p, -1, axis=0))
            scale = float(np.ptp(p, axis=0).max())
            inner[i, :len(p)] = shapely.distance(obstacles[k].geometry().boundary, shapely.points(mid)) > 1e-9 * scale
    return ConvexPieces(verts, count, owner, inner, inset)
