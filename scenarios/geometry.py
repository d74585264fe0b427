"""Plane geometry of obstacles: simple-polygon checks, circles as polygons, convex pieces.

Every obstacle is handed to the planner and the physics as a set of **convex pieces** (convex
polygons, counter-clockwise, no repeated or collinear vertices) whose union is the obstacle:

- a box is one 4-gon;
- a circle is the regular polygon *circumscribed* about it whose sagitta (the largest gap
  between polygon and circle, at its vertices) is at most :data:`CIRCLE_SAGITTA`, so the
  polygon covers the circle and every test made on it is conservative;
- a concave polygon (with holes or not) is triangulated by ``shapely``'s constrained Delaunay
  triangulation, and the triangles are merged into larger convex pieces by Hertel and
  Mehlhorn's rule (drop a diagonal while both of its end angles stay convex), which keeps at
  most four times the fewest convex pieces and costs kernels a fraction of the triangles.
"""

from __future__ import annotations

import math

import numpy as np
import shapely
from shapely.geometry import Polygon

#: Largest gap between a circle and the polygon that stands for it [m].
CIRCLE_SAGITTA = 1e-3

#: Relative tolerance of the turn tests (cross products scaled by the edge lengths).
_TURN_TOL = 1e-12


def circle_vertices(center: tuple[float, float], radius: float,
                    sagitta: float = CIRCLE_SAGITTA) -> np.ndarray:
    """Vertices of the regular polygon circumscribed about a circle, counter-clockwise.

    Parameters
    ----------
    center : (float, float)
        Circle centre [m].
    radius : float
        Circle radius [m], > 0.
    sagitta : float
        Largest allowed distance between a polygon vertex and the circle [m].

    Returns
    -------
    ndarray, shape (n, 2)
        The polygon [m]; its edges touch the circle, its vertices lie ``radius / cos(pi / n)``
        from the centre, with n >= 8 the fewest for which that exceeds ``radius`` by at most
        ``sagitta``.
    """
    n = max(8, math.ceil(math.pi / math.acos(radius / (radius + sagitta))))
    big = radius / math.cos(math.pi / n)
    a = 2.0 * math.pi * np.arange(n) / n
    return np.column_stack([center[0] + big * np.cos(a), center[1] + big * np.sin(a)])


def _segments_cross(p: np.ndarray, q: np.ndarray, r: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Tell whether closed segments p-q and r-s intersect (touching and collinear overlap included); vectorised."""
    def orient(a, b, c):
        v = (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1]) - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0])
        return np.sign(v)

    def on_seg(a, b, c):  # c collinear with a-b: within its bounding box
        return ((np.minimum(a[..., 0], b[..., 0]) <= c[..., 0]) & (c[..., 0] <= np.maximum(a[..., 0], b[..., 0]))
                & (np.minimum(a[..., 1], b[..., 1]) <= c[..., 1]) & (c[..., 1] <= np.maximum(a[..., 1], b[..., 1])))

    o1, o2, o3, o4 = orient(p, q, r), orient(p, q, s), orient(r, s, p), orient(r, s, q)
    proper = (o1 * o2 < 0) & (o3 * o4 < 0)
    touch = (((o1 == 0) & on_seg(p, q, r)) | ((o2 == 0) & on_seg(p, q, s))
             | ((o3 == 0) & on_seg(r, s, p)) | ((o4 == 0) & on_seg(r, s, q)))
    return proper | touch


def first_crossing(ring: np.ndarray) -> tuple[int, int] | None:
    """Find the first pair of edges of a closed ring that meet other than at a shared vertex.

    Parameters
    ----------
    ring : ndarray, shape (n, 2)
        Vertices, not repeated at the end; edge i joins vertex i to vertex (i + 1) mod n.

    Returns
    -------
    (int, int) or None
        Edge indices (i < j) of the first offending pair, None for a simple ring.
    """
    v = np.asarray(ring, float)
    n = len(v)
    if shapely.is_simple(shapely.linearrings(np.vstack([v, v[:1]]))):
        return None
    a, b = v, np.roll(v, -1, axis=0)
    for i in range(n):
        # Edges i-1 and i+1 share a vertex with i: they may only meet there, which a
        # collinear fold back would break; test them for overlap beyond the shared point.
        j = np.arange(i + 1, n)
        hit = _segments_cross(a[i], b[i], a[j], b[j])
        adjacent = (j == i + 1) | ((i == 0) & (j == n - 1))
        if adjacent.any():
            # Adjacent edges meet at their shared vertex; they cross only if they fold back.
            for k in np.flatnonzero(adjacent):
                jj = j[k]
                shared = b[i] if jj == i + 1 else a[i]
                other_i = a[i] if jj == i + 1 else b[i]
                other_j = b[jj] if jj == i + 1 else a[jj]
                u, w = other_i - shared, other_j - shared
                cross = u[0] * w[1] - u[1] * w[0]
                hit[k] = abs(cross) <= _TURN_TOL * np.hypot(*u) * np.hypot(*w) and u @ w > 0
        if hit.any():
            return i, int(j[np.flatnonzero(hit)[0]])
    return 0, 0  # shapely disagrees with the pairwise test only in degenerate cases


def _strip_collinear(ring: np.ndarray) -> np.ndarray:
    """Drop vertices where the ring does not turn (and repeated ones)."""
    v = np.asarray(ring, float)
    keep = []
    n = len(v)
    for i in range(n):
        u, w = v[i] - v[i - 1], v[(i + 1) % n] - v[i]
        cross = u[0] * w[1] - u[1] * w[0]
        if abs(cross) > _TURN_TOL * max(np.hypot(*u) * np.hypot(*w), 1e-300):
            keep.append(i)
    return v[keep]


def _ccw(ring: np.ndarray) -> np.ndarray:
    x, y = ring[:, 0], ring[:, 1]
    area2 = float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))
    return ring if area2 > 0 else ring[::-1]


def _turn_ok(u: np.ndarray, v: np.ndarray, w: np.ndarray) -> bool:
    """Tell whether the corner u-v-w turns left or goes straight (a convex corner of a CCW polygon)."""
    a, b = v - u, w - v
    cross = a[0] * b[1] - a[1] * b[0]
    return cross >= -_TURN_TOL * np.hypot(*a) * np.hypot(*b)


def convex_pieces(polygon: Polygon) -> list[np.ndarray]:
    """Split a polygon (holes allowed) into few convex pieces.

    Parameters
    ----------
    polygon : shapely.geometry.Polygon
        A valid polygon [m].

    Returns
    -------
    list of ndarray, each shape (n_i, 2)
        Convex pieces, counter-clockwise, without collinear vertices [m]; their union is the
        polygon and their interiors are disjoint.
    """
    shell = _strip_collinear(np.asarray(polygon.exterior.coords)[:-1])
    if not polygon.interiors and _is_convex(_ccw(shell)):
        return [_ccw(shell)]
    tris = shapely.get_parts(shapely.constrained_delaunay_triangles(polygon))
    index: dict[tuple[float, float], int] = {}
    points: list[tuple[float, float]] = []
    pieces: list[list[int] | None] = []
    for t in tris:
        c = np.asarray(t.exterior.coords)[:-1]
        ids = []
        for x, y in _ccw(c):
            key = (float(x), float(y))
            if key not in index:
                index[key] = len(points)
                points.append(key)
            ids.append(index[key])
        pieces.append(ids)
    pts = np.array(points)
    owner: dict[tuple[int, int], int] = {}
    for k, ids in enumerate(pieces):
        for i in range(len(ids)):
            owner[(ids[i], ids[(i + 1) % len(ids)])] = k
    # Diagonals (edges shared by two pieces), longest first: dropping long ones first tends
    # to leave fewer, fatter pieces.
    diagonals = sorted({(a, b) for (a, b) in owner if (b, a) in owner and a < b},
                       key=lambda e: -float(np.hypot(*(pts[e[0]] - pts[e[1]]))))
    for a, b in diagonals:
        i, j = owner.get((a, b)), owner.get((b, a))
        if i is None or j is None or i == j:
            continue
        pi, pj = pieces[i], pieces[j]
        # pi runs ... a, b ...; pj runs ... b, a ...; the merge walks pi from b round to a,
        # then pj from a round to b, without repeating a and b.
        walk_i = [pi[(pi.index(b) + k) % len(pi)] for k in range(len(pi))]      # b ... a
        walk_j = [pj[(pj.index(a) + k) % len(pj)] for k in range(1, len(pj) - 1)]  # after a ... before b
        merged = walk_i + walk_j
        m = len(merged)
        ka, kb = merged.index(a), merged.index(b)
        if not (_turn_ok(pts[merged[ka - 1]], pts[merged[ka]], pts[merged[(ka + 1) % m]])
                and _turn_ok(pts[merged[kb - 1]], pts[merged[kb]], pts[merged[(kb + 1) % m]])):
            continue
        pieces[i], pieces[j] = merged, None
        for k in range(m):
            owner[(merged[k], merged[(k + 1) % m])] = i
        owner.pop((a, b), None)
        owner.pop((b, a), None)
    return [_strip_collinear(pts[ids]) for ids in pieces if ids is not None]


def _is_convex(ring: np.ndarray) -> bool:
    n = len(ring)
    return n >= 3 and all(_turn_ok(ring[i - 1], ring[i], ring[(i + 1) % n]) for i in range(n))
