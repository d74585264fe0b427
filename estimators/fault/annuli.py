"""Closed-form polygon of two intersecting annuli: the fault area of a two-range fix.

Two ranges ``r_i`` with bounds ``rho_i`` to markers ``M_1``, ``M_2`` (distance ``d``) confine the
robot to ``{p : a_i <= |p - M_i| <= b_i}`` with ``a_i = r_i - rho_i``, ``b_i = r_i + rho_i``. On
one side of the marker line, ``p -> (u, v) = (|p - M_1|, |p - M_2|)`` maps the open half-plane
one-to-one onto the open convex domain ``D = {|u - v| < d < u + v}``. When the rectangle
``R = [a_1, b_1] x [a_2, b_2]`` lies inside ``D`` (its four corners do, ``D`` being convex),
the fault area on that side is the image of ``R``: a curvilinear quadrilateral whose corners
are the circle-circle intersections ``X(u, v)`` and whose edges are arcs of the four circles,
each spanning less than pi. Its mirror image across the marker line is the other component.

Polygonisation, with the containment guarantee of :mod:`estimators.fault.exact`: an outer arc
(radius ``b``, the region inside) becomes the circumscribed polyline from corner to corner
(tangent at the corners and at equally spaced angles between, vertices at radius
``b / cos(h / 2)`` where consecutive tangents meet), an inner arc (radius ``a``, the region
outside) the inscribed chord polyline. Each polyline lies on the far side of its arc from the
region and shares its endpoints, so the lune between them misses the region's interior and
the winding number about every interior point stays 1: a *simple* polygon built this way
contains the exact set. It lies within ``tol`` of its arcs (segment counts as in
:func:`arc_steps`), hence inside the exact set of the bounds ``rho + tol``. Simplicity is
checked (all segment pairs); when it fails, or ``R`` is not safely inside ``D`` (near-tangent
circles, a region touching the marker line, an empty or one-sided intersection), or the
polygon would need more than :data:`MAX_VERTICES` vertices, the caller takes the general
(shapely) path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from jit import compiled

MAX_VERTICES = 256
"""Vertex limit of the closed-form polygon (the simplicity check is quadratic in it)."""

_EPS = 2.220446049250313e-16
_OK, _OUTSIDE_DOMAIN, _TOO_MANY, _NOT_SIMPLE = 0, 1, 2, 3   # kernel status codes


@dataclass(frozen=True)
class AnnuliRegion:
    """The polygonised component of two annuli on one side of the marker line.

    Attributes
    ----------
    ring : ndarray, shape (n + 1, 2)
        Closed polygon ring [m] (last vertex = first); the four corners are exact vertices.
    area : float
        Polygon area [m^2].
    centroid : ndarray, shape (2,)
        Polygon centroid [m].
    diameter : float
        Largest vertex-to-vertex distance [m].
    """

    ring: np.ndarray
    area: float
    centroid: np.ndarray
    diameter: float


@compiled.njit(cache=True)
def max_pairwise_distance(xy):
    """Largest distance [m] between two rows of ``xy`` (n, 2)."""
    best = 0.0
    for i in range(xy.shape[0]):
        for j in range(i + 1, xy.shape[0]):
            dx = xy[i, 0] - xy[j, 0]
            dy = xy[i, 1] - xy[j, 1]
            best = max(best, dx * dx + dy * dy)
    return math.sqrt(best)


@compiled.njit(cache=True)
def arc_steps(radius, span, tol, outside):
    """Segment count and vertex radius of a polyline within ``tol`` of an arc of ``span`` [rad].

    ``outside``: circumscribed (vertices at the returned radius > ``radius``), else inscribed.
    The count is ``-1`` when ``tol`` is below what the angle step can resolve.
    """
    if outside:
        step_max = 2.0 * math.acos(radius / (radius + tol))
    else:
        step_max = 2.0 * math.acos(max(1.0 - tol / radius, -1.0))
    if not step_max > 0.0:
        return -1, radius
    n_float = math.ceil(span / step_max - 1e-12)
    if n_float > 1e9:
        return -1, radius
    n = max(1, int(n_float))
    rad = radius / math.cos(0.5 * span / n) if outside else radius
    return n, rad


@compiled.njit(cache=True)
def _corner(u, v, d):
    """Intersection (x, h) of circles |p| = u and |p - (d, 0)| = v with h >= 0; h = -1 if none.

    The height comes from Heron's formula in product form (accurate near tangency); the
    second value is the smallest triangle-inequality slack.
    """
    f1, f2, f3 = u + v - d, d - u + v, d + u - v
    slack = min(f1, f2, f3)
    if not slack > 0.0:
        return 0.0, -1.0, slack
    x = ((u - v) * (u + v) + d * d) / (2.0 * d)
    h = math.sqrt((u + v + d) * f1 * f2 * f3) / (2.0 * d)
    return x, h, slack


@compiled.njit(cache=True)
def _orient(ax, ay, bx, by, cx, cy):
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


@compiled.njit(cache=True)
def _sign(x):
    return (x > 0.0) - (x < 0.0)


@compiled.njit(cache=True)
def is_simple_ring(ring):
    """Tell whether the closed ring (n + 1, 2) is a simple polygon (no self-contact).

    Non-adjacent edges may not meet at all (touching counts); adjacent edges may not fold
    back onto each other. Collinear cases are judged conservatively (reported as contact).
    """
    n = ring.shape[0] - 1
    if n < 3:
        return False
    for i in range(n):
        ax, ay, bx, by = ring[i, 0], ring[i, 1], ring[i + 1, 0], ring[i + 1, 1]
        # adjacent edge i, i+1: a fold-back is collinear with a negative dot product
        j = (i + 1) % n
        cx, cy = ring[j + 1, 0], ring[j + 1, 1]
        if (_orient(ax, ay, bx, by, cx, cy) == 0.0
                and (bx - ax) * (cx - bx) + (by - ay) * (cy - by) <= 0.0):
            return False
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue
            cx, cy, dx, dy = ring[j, 0], ring[j, 1], ring[j + 1, 0], ring[j + 1, 1]
            if (max(ax, bx) < min(cx, dx) or max(cx, dx) < min(ax, bx)
                    or max(ay, by) < min(cy, dy) or max(cy, dy) < min(ay, by)):
                continue
            o1 = _sign(_orient(ax, ay, bx, by, cx, cy))
            o2 = _sign(_orient(ax, ay, bx, by, dx, dy))
            o3 = _sign(_orient(cx, cy, dx, dy, ax, ay))
            o4 = _sign(_orient(cx, cy, dx, dy, bx, by))
            if o1 * o2 <= 0 and o3 * o4 <= 0:
                return False
    return True


@compiled.njit(cache=True)
def ring_contains(ring, x, y):
    """Tell whether point (x, y) lies in the polygon of the closed ring (n + 1, 2), boundary included.

    Crossing number with the half-open rule; a point on an edge (exact orientation test) counts
    as inside, like shapely's ``intersects``.
    """
    inside = False
    for i in range(ring.shape[0] - 1):
        ax, ay, bx, by = ring[i, 0], ring[i, 1], ring[i + 1, 0], ring[i + 1, 1]
        if (_orient(ax, ay, bx, by, x, y) == 0.0 and min(ax, bx) <= x <= max(ax, bx)
                and min(ay, by) <= y <= max(ay, by)):
            return True
        if (ay > y) != (by > y) and x < ax + (y - ay) * (bx - ax) / (by - ay):
            inside = not inside
    return inside


@compiled.njit(cache=True)
def _fill_arc(ring, pos, cx, radius, phi_s, phi_e, n, rad, outside, chords):
    """Write the n - 1 (inscribed) or n (circumscribed) interior vertices of one arc polyline."""
    step = (phi_e - phi_s) / n
    if outside and not chords:
        for j in range(n):
            phi = phi_s + (j + 0.5) * step
            ring[pos, 0] = cx + rad * math.cos(phi)
            ring[pos, 1] = rad * math.sin(phi)
            pos += 1
    else:
        for j in range(1, n):
            phi = phi_s + j * step
            ring[pos, 0] = cx + radius * math.cos(phi)
            ring[pos, 1] = radius * math.sin(phi)
            pos += 1
    return pos


@compiled.njit(cache=True)
def _quadrilateral(d, a1, b1, a2, b2, tol, outer_chords):
    """Ring (n + 1, 2) of the upper component in the frame M_1 = (0, 0), M_2 = (d, 0).

    Returns (status, ring); the ring is empty unless status is _OK. ``outer_chords`` replaces
    the circumscribed outer polylines by chords (a wrong construction, for negative controls).
    """
    empty = np.empty((0, 2))
    if not (a1 > 0.0 and a2 > 0.0 and d > 0.0):
        return _OUTSIDE_DOMAIN, empty
    us = (a1, b1, b1, a1)          # corners in ring order: C00, C10, C11, C01
    vs = (a2, a2, b2, b2)
    xs, hs = np.empty(4), np.empty(4)
    for c in range(4):
        x, h, slack = _corner(us[c], vs[c], d)
        # Rounding of x and h (Heron's factors carry eps * (u + v + d) each) must stay far
        # below tol, and the region must keep off the marker line by more than the
        # polygonisation (else the shapely path may merge the mirror twins into one).
        size = us[c] + vs[c] + d
        err = 8.0 * _EPS * (size * size / d + (size * h / slack if slack > 0.0 else math.inf))
        if not (h > 4.0 * tol and err < 1e-3 * tol):
            return _OUTSIDE_DOMAIN, empty
        xs[c], hs[c] = x, h
    # edges: (circle centre x, radius, from corner, to corner, outside)
    centres = (d, 0.0, d, 0.0)
    radii = (a2, b1, b2, a1)
    outs = (False, True, True, False)
    counts, rads, phis, phie = np.empty(4, np.int64), np.empty(4), np.empty(4), np.empty(4)
    total = 4
    for e in range(4):
        c0, c1 = e, (e + 1) % 4
        phis[e] = math.atan2(hs[c0], xs[c0] - centres[e])
        phie[e] = math.atan2(hs[c1], xs[c1] - centres[e])
        n, rad = arc_steps(radii[e], abs(phie[e] - phis[e]), tol, outs[e])
        if n < 0:
            return _TOO_MANY, empty
        counts[e], rads[e] = n, rad
        total += n if (outs[e] and not outer_chords) else n - 1
        if total > MAX_VERTICES:
            return _TOO_MANY, empty
    ring = np.empty((total + 1, 2))
    pos = 0
    for e in range(4):
        ring[pos, 0], ring[pos, 1] = xs[e], hs[e]
        pos = _fill_arc(ring, pos + 1, centres[e], radii[e], phis[e], phie[e], counts[e], rads[e],
                        outs[e], outer_chords)
    ring[pos] = ring[0]
    return _OK, ring


@compiled.njit(cache=True)
def _area_centroid(ring):
    """Signed area and centroid of a closed ring, about its first vertex (no cancellation)."""
    x0, y0 = ring[0, 0], ring[0, 1]
    a2 = sx = sy = 0.0
    for i in range(1, ring.shape[0] - 2):
        ax, ay = ring[i, 0] - x0, ring[i, 1] - y0
        bx, by = ring[i + 1, 0] - x0, ring[i + 1, 1] - y0
        cross = ax * by - ay * bx
        a2 += cross
        sx += (ax + bx) * cross
        sy += (ay + by) * cross
    return 0.5 * a2, x0 + sx / (3.0 * a2), y0 + sy / (3.0 * a2)


@compiled.njit(cache=True)
def _region(markers, ranges, rho, prior, tol, outer_chords):
    """Kernel of :func:`two_annuli_region`: (status, world ring, area, cx, cy, diameter)."""
    m1x, m1y, m2x, m2y = markers[0, 0], markers[0, 1], markers[1, 0], markers[1, 1]
    ex, ey = m2x - m1x, m2y - m1y
    cross = ex * (prior[1] - m1y) - ey * (prior[0] - m1x)
    side = float((cross > 0.0) - (cross < 0.0))       # as marker_side(prior, markers)
    d = math.hypot(ex, ey)
    if side == 0.0:
        return _OUTSIDE_DOMAIN, np.empty((0, 2)), 0.0, 0.0, 0.0, 0.0
    status, ring = _quadrilateral(d, ranges[0] - rho[0], ranges[0] + rho[0], ranges[1] - rho[1],
                                  ranges[1] + rho[1], tol, outer_chords)
    if status != _OK:
        return status, ring, 0.0, 0.0, 0.0, 0.0
    # Work about the first corner: coordinates of millimetre polygons stay exact.
    bx, by = ring[0, 0], ring[0, 1]
    for i in range(ring.shape[0]):
        ring[i, 0] -= bx
        ring[i, 1] -= by
    if not is_simple_ring(ring):
        return _NOT_SIMPLE, ring, 0.0, 0.0, 0.0, 0.0
    area, cx, cy = _area_centroid(ring)
    diameter = max_pairwise_distance(ring[:-1])
    # local (along, across) -> world: M_1 + along e + across side n, n = e turned left
    ex, ey = ex / d, ey / d
    nx, ny = -side * ey, side * ex
    ox, oy = m1x + bx * ex + by * nx, m1y + bx * ey + by * ny
    world = np.empty_like(ring)
    for i in range(ring.shape[0]):
        world[i, 0] = ox + ring[i, 0] * ex + ring[i, 1] * nx
        world[i, 1] = oy + ring[i, 0] * ey + ring[i, 1] * ny
    return _OK, world, abs(area), ox + cx * ex + cy * nx, oy + cx * ey + cy * ny, diameter


def marker_side(point: np.ndarray, markers: np.ndarray) -> float:
    """Side of the line from ``markers[0]`` to ``markers[1]`` of ``point``: +1 left, -1 right, 0 on.

    The sign of :func:`estimators.measurements.marker_line_side` for two markers, in plain
    floats (that one serves any number of collinear markers).
    """
    (ax, ay), (bx, by) = markers.tolist()
    px, py = float(point[0]), float(point[1])
    cross = (bx - ax) * (py - ay) - (by - ay) * (px - ax)
    return float((cross > 0.0) - (cross < 0.0))


def two_annuli_region(markers: np.ndarray, ranges: np.ndarray, rho: np.ndarray, prior: np.ndarray,
                      tol: float, _outer_chords: bool = False) -> AnnuliRegion | None:
    """Polygonised component of two annuli on ``prior``'s side of the marker line, if simple.

    Parameters
    ----------
    markers : ndarray, shape (2, 2), float64
        Marker positions [m].
    ranges : ndarray, shape (2,), float64
        Measured ranges [m].
    rho : ndarray, shape (2,), float64
        Range error bounds [m], > 0 (any margin included).
    prior : ndarray, shape (2,), float64
        Chooses the side of the line through the markers [m].
    tol : float
        Polygonisation tolerance [m], > 0.
    _outer_chords : bool
        Negative controls only: inscribe the outer arcs too (loses the containment).

    Returns
    -------
    AnnuliRegion or None
        None when the closed form does not apply (``prior`` on the marker line, the annuli
        rectangle not safely inside the domain, too many vertices, or a non-simple polygon):
        use the general construction of :mod:`estimators.fault.exact` then.
    """
    status, ring, area, cx, cy, diameter = _region(markers, ranges, rho, prior, float(tol), bool(_outer_chords))
    if status != _OK:
        return None
    return AnnuliRegion(ring=ring, area=area, centroid=np.array([cx, cy]), diameter=diameter)
