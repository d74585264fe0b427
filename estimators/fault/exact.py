"""The exact fault area of a fix: every position consistent with its measurements.

A range ``r_i`` with error bound ``rho_i`` confines the robot to the annulus
``{p : | |p - M_i| - r_i | <= rho_i}``; a world bearing ``beta_i`` (direction robot -> marker)
with bound ``xi`` confines it to the wedge with apex ``M_i`` and directions
``beta_i + pi +- xi``. The fault area is the intersection (`docs/design.md` §1), polygonised with shapely.

Robot-frame bearings
--------------------
A bearing measured in the robot frame needs the heading to become a world direction, and a
heading from elsewhere (a filter's) is not bounded. The heading-free set needs none: ``p`` is
consistent with robot-frame bearings ``beta_i`` (bounds ``xi_i``) iff some heading ``theta``
has ``|wrap(a_i(p) - theta - beta_i)| <= xi_i`` for every ``i`` (``a_i(p)`` the direction from
``p`` to ``M_i``): the arcs ``a_i(p) - beta_i +- xi_i`` of the circle share a point. Every
pair of them must meet, ``|wrap((a_i - a_j)(p) - (beta_i - beta_j))| <= xi_i + xi_j``: the region
between two circular arcs through ``M_i`` and ``M_j`` (inscribed-angle theorem,
:func:`estimators.fault.pieces.bearing_pair_piece`). The fault area intersects these pairwise
regions with the annuli. It is the heading-free set exactly when ``3 * 2 max xi_i < 2 pi``
(pairwise-meeting arcs no longer than ``L`` lie in one arc of length ``3 L`` around any of them,
where Helly's theorem on the line applies); otherwise it contains it. The true position is in
it whenever every bearing error is within its bound, whatever the heading.

Polygonisation
--------------
Annuli can be metres wide while the fault area is millimetres, so no annulus is polygonised
whole. The intersection is taken inside a square *window* around a seed point (the weighted
least-squares solution from the prior), first sized from the linearised region and grown
until the selected component no longer touches the window's edge (then it is a whole
component of the exact set). Inside the window each annulus is an annular sector covering
the window's angular span as seen from the marker.

Every arc is replaced by a polygonal line that lies *outside* the exact set, at most
``tolerance`` from its circle: the outer circle by a circumscribed polyline, the inner
circle by an inscribed one (wedges are polygons already; of a bearing pair's two circles,
the one whose disk is kept is circumscribed, the one whose disk is removed inscribed). So the
polygon *contains* the exact fault area and lies inside the exact fault area of the bounds
``rho_i + tolerance`` (with robot-frame bearings: and each pair's arcs moved outwards by at
most ``tolerance``: the angle ``a_i - a_j`` by at most ``tolerance (1/|p - M_i| + 1/|p - M_j|)``).
The default tolerance is ``1e-3 * min(rho)``. For two ranges meeting at angle alpha this
overestimates the area by a relative ``<= tolerance (1/rho_1 + 1/rho_2) <= 2e-3`` and moves
each corner by ``<= 2 tolerance / sin(alpha)``.

Two ranges
----------
Without bearings, the component on the prior's side is built in closed form
(:mod:`estimators.fault.annuli`: corners at the circle intersections, the same containment and
tolerance) whenever it is a curvilinear quadrilateral safely away from the marker line;
otherwise, and for everything else, by the windowed clipping above (pieces in
:mod:`estimators.fault.pieces`).

Empty sets
----------
Inconsistent measurements (no position satisfies all bounds, possible with gaussian noise)
give a :class:`FaultArea` with an empty polygon, ``area = 0``, ``diameter = nan`` and a
``nan`` centroid; no exception.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
import shapely
from shapely.geometry import Polygon

from estimators.fault.annuli import max_pairwise_distance, ring_contains, two_annuli_region
from estimators.fault.pieces import annulus_piece, bearing_pair_piece, wedge_piece
from estimators.lsq import solve_position
from estimators.measurements import (
    collinear_markers,
    marker_line_side,
    range_jacobian,
    ranges,
    reflect_across_marker_line,
    world_bearing,
    world_bearing_jacobian,
)
from jit import compiled

DEFAULT_TOLERANCE_FRACTION = 1e-3
"""Default polygonisation tolerance as a fraction of the smallest range bound rho."""

_GROWTH = 4.0          # window growth factor when the component touches the window edge
_MAX_WINDOWS = 12      # 4**12 ~ 1.7e7: from micrometres to kilometres
_HULL_ABOVE = 64       # vertex count above which the diameter goes through the convex hull


@dataclass(frozen=True)
class FaultArea:
    """A (polygonised) fault area.

    Attributes
    ----------
    ring : ndarray, shape (n + 1, 2)
        Closed exterior ring of the polygon [m]; shape (0, 2) when empty.
    area : float
        Area of ``polygon`` [m^2]; 0 when empty.
    diameter : float
        Largest distance between two points of the area [m] (max pairwise distance of the
        convex-hull vertices); nan when empty.
    centroid : ndarray, shape (2,)
        Centroid of ``polygon`` [m]; nan when empty.
    tolerance : float
        Polygonisation tolerance [m]: largest distance of a polygon edge beyond its circle.
    polygon : shapely.geometry.Polygon
        Outer approximation of the exact set (empty when the measurements are inconsistent):
        contains it, and is contained in the exact set of the bounds ``rho + tolerance``. Built
        on first use from ``ring`` for the closed form (an episode makes hundreds of fault areas
        and only needs their rings).
    """

    ring: np.ndarray
    area: float
    diameter: float
    centroid: np.ndarray
    tolerance: float
    shape: Polygon | None = field(default=None, repr=False, compare=False)
    """The shapely polygon when one was built (it may have holes); else made from ``ring``."""

    @functools.cached_property
    def polygon(self) -> Polygon:
        if self.shape is not None:
            return self.shape
        return shapely.polygons(self.ring) if len(self.ring) else Polygon()

    @property
    def is_empty(self) -> bool:
        """True when no position is consistent with the measurements."""
        return len(self.ring) == 0

    def contains(self, point: np.ndarray) -> bool:
        """Tell whether ``point`` (2,) [m] lies in the polygon (boundary included)."""
        if self.is_empty:
            return False
        if self.shape is not None and len(self.shape.interiors):
            return bool(shapely.intersects_xy(self.shape, point[0], point[1]))
        return bool(ring_contains(self.ring, float(point[0]), float(point[1])))


def _empty(tol: float) -> FaultArea:
    return FaultArea(np.zeros((0, 2)), 0.0, math.nan, np.full(2, math.nan), tol)


def _from_polygon(poly: Polygon, tol: float) -> FaultArea:
    ring = shapely.get_coordinates(poly.exterior)
    xy = shapely.get_coordinates(shapely.convex_hull(poly)) if len(ring) > _HULL_ABOVE else ring
    c = poly.centroid
    return FaultArea(ring, float(poly.area), float(max_pairwise_distance(xy)), np.array([c.x, c.y]), tol,
                     shape=poly)


def _local_region(markers, meas, rho, bearings, xi, center, half, tol, pairs=()):
    """Intersection of the pieces that constrain the window; None when empty.

    Every piece is exact (up to ``tol``) only inside the window; the caller checks that the
    selected component lies inside it. Returns the window itself when nothing constrains it.
    """
    pieces = []
    for i in range(markers.shape[0]):
        piece = annulus_piece(markers[i], meas[i], rho[i], center, half, tol)
        if isinstance(piece, str):
            return None
        if piece is not None:
            pieces.append(piece)
        if bearings is not None:
            piece = wedge_piece(markers[i], bearings[i], xi, center, half)
            if piece is not None:
                pieces.append(piece)
    for i, j, gamma, delta in pairs:
        piece = bearing_pair_piece(markers[i], markers[j], gamma, delta, center, half, tol)
        if isinstance(piece, str):
            return None
        if piece is not None:
            pieces.append(piece)
    if not pieces:
        return shapely.box(center[0] - half, center[1] - half, center[0] + half, center[1] + half)
    geom = pieces[0]
    for piece in pieces[1:]:
        geom = shapely.intersection(geom, piece)
        if geom.is_empty:
            return None
    return geom


_POLYGON = 3   # shapely.GeometryType.POLYGON


def _pick(geom, prior):
    """Return the polygon part of ``geom`` containing ``prior``, else the nearest; None if none."""
    if geom is None or geom.is_empty:
        return None
    if shapely.get_type_id(geom) == _POLYGON:
        return geom if geom.area > 0.0 else None
    parts = [g for g in shapely.get_parts(geom) if isinstance(g, Polygon) and g.area > 0.0]
    if not parts:
        return None
    if len(parts) == 1:
        return parts[0]
    inside = shapely.intersects_xy(parts, prior[0], prior[1])
    if np.any(inside):
        return parts[int(np.argmax(inside))]
    return parts[int(np.argmin(shapely.distance(parts, shapely.points(prior))))]


def _initial_half_width(markers, seed, rho, bearings, xi):
    """Half-width [m] of a window that holds the linearised fault area around ``seed``.

    In the linearisation every point q of the region satisfies sum_j (h_j.(q-s))^2/b_j^2 <= n
    relative to the weighted least-squares point s, hence |q - s|^2 <= n * lambda_max(P)
    with P = (H^T W H)^-1; twice that radius leaves room for the curvature.
    """
    jac = range_jacobian(seed, markers) / rho[:, None]
    if bearings is not None:
        jac = np.vstack([jac, world_bearing_jacobian(seed, markers) / xi])
    (a, b), (_, c) = (jac.T @ jac).tolist()
    eig_min = 0.5 * (a + c) - math.hypot(0.5 * (a - c), b)
    n = jac.shape[0]
    if eig_min <= 1e-12 * (a + c):
        return math.inf
    return 2.0 * math.sqrt(n / eig_min)


def _component(markers, meas, rho, bearings, xi, seed, prior, tol, pairs=()):
    """Find the fault-area component nearest ``prior`` in growing windows around ``seed``."""
    dist = ranges(seed, markers)
    # A window holding a whole outer disk makes the clip inactive: no need to grow past it.
    half_cap = float(np.min(dist + meas + rho)) * 1.01
    half = min(max(_initial_half_width(markers, seed, rho, bearings, xi), 20.0 * tol), half_cap)
    for _ in range(_MAX_WINDOWS):
        comp = _pick(_local_region(markers, meas, rho, bearings, xi, seed, half, tol, pairs), prior)
        if half >= half_cap:
            return comp
        if comp is not None:
            # Inside the window's interior, the component's edges are all annulus/wedge/arc edges:
            # it is a whole component of the exact set.
            inner = half * (1.0 - 1e-9)
            bx0, by0, bx1, by1 = comp.bounds
            if (bx0 > seed[0] - inner and by0 > seed[1] - inner
                    and bx1 < seed[0] + inner and by1 < seed[1] + inner):
                return comp
        half = min(half * _GROWTH, half_cap)
    return comp


def _mirror_polygon(poly, markers):
    """Reflect ``poly`` across the line through the (collinear) markers."""
    shell = reflect_across_marker_line(shapely.get_coordinates(poly.exterior), markers)[::-1]
    holes = [reflect_across_marker_line(shapely.get_coordinates(r), markers)[::-1] for r in poly.interiors]
    return shapely.polygons(shell, holes=holes or None)


@compiled.njit(cache=True)
def _input_summary(markers, meas, rho):
    """Sum of every input (finite iff all are, barring overflow), min rho, min(range + rho)."""
    total, rho_min, reach_min = 0.0, math.inf, math.inf
    for i in range(rho.shape[0]):
        total += markers[i, 0] + markers[i, 1] + meas[i] + rho[i]
        rho_min = min(rho_min, rho[i])
        reach_min = min(reach_min, meas[i] + rho[i])
    return total, rho_min, reach_min


def _validate(markers, meas, rho, bearings, xi, relative=None, relative_error=None):
    """Raise ValueError on bad inputs; return (min rho, min(range + rho))."""
    k = markers.shape[0]
    if k == 0 or meas.shape != (k,) or rho.shape != (k,):
        raise ValueError(f"fault area: ranges {meas.shape} and rho {rho.shape} must be ({k},), k >= 1")
    total, rho_min, reach_min = _input_summary(markers, meas, rho)
    if not math.isfinite(total):
        raise ValueError(f"fault area: non-finite input: markers {markers.tolist()}, ranges {meas.tolist()}, "
                         f"rho {rho.tolist()}")
    if not rho_min > 0.0:
        raise ValueError(f"fault area: rho must be > 0, got {rho.tolist()}")
    if bearings is not None:
        if bearings.shape != (k,):
            raise ValueError(f"fault area: bearings {bearings.shape} must be ({k},)")
        if not xi > 0.0:
            raise ValueError(f"fault area: bearing_error must be > 0 with bearings, got {xi}")
    if relative is not None:
        if bearings is not None:
            raise ValueError("fault area: world and robot-frame bearings together")
        if relative.shape != (k,) or relative_error.shape != (k,):
            raise ValueError(f"fault area: robot-frame bearings {relative.shape} and their bounds "
                             f"{relative_error.shape} must be ({k},)")
        if not (np.all(np.isfinite(relative)) and np.all(relative_error > 0.0)):
            raise ValueError(f"fault area: robot-frame bearings {relative.tolist()} must be finite, their "
                             f"bounds {relative_error.tolist()} > 0")
    return rho_min, reach_min


def exact_fault_area(markers: np.ndarray, ranges: np.ndarray, rho: np.ndarray, prior: np.ndarray,
                     bearings: np.ndarray | None = None, bearing_error: float = 0.0,
                     tolerance: float | None = None, robot_bearings: np.ndarray | None = None,
                     robot_bearing_error: np.ndarray | None = None) -> FaultArea:
    """Exact (polygonised) fault area of one fix.

    Parameters
    ----------
    markers : ndarray, shape (k, 2)
        Marker positions [m].
    ranges : ndarray, shape (k,)
        Measured ranges [m].
    rho : ndarray, shape (k,)
        Range error bounds [m], > 0.
    prior : ndarray, shape (2,)
        A position guess [m]. The component returned is the one around the weighted
        least-squares point found from ``prior`` (the one containing ``prior`` when several
        meet there); for ranges to collinear markers (always with two) the exact set is
        mirror-symmetric and the twin on ``prior``'s side of the marker line is returned.
    bearings : ndarray, shape (k,), optional
        Measured absolute (world-frame) directions from the robot to the markers [rad].
    bearing_error : float
        Bound xi of the bearing errors [rad]; must be > 0 when ``bearings`` are given.
    tolerance : float, optional
        Polygonisation tolerance [m]; default ``1e-3 * min(rho)``.
    robot_bearings : ndarray, shape (k,), optional
        Measured directions to the markers in one robot frame [rad] (not with ``bearings``):
        they constrain the position through their differences only, no heading needed (module
        docstring, "Robot-frame bearings").
    robot_bearing_error : float or ndarray, shape (k,), optional
        Bound of each robot-frame bearing's error [rad], > 0; required with ``robot_bearings``.

    Returns
    -------
    FaultArea
        Empty (area 0, diameter nan) when the measurements are inconsistent.
    """
    markers = np.asarray(markers, dtype=float).reshape(-1, 2)
    meas = np.asarray(ranges, dtype=float)
    rho = np.asarray(rho, dtype=float)
    prior = np.asarray(prior, dtype=float)
    bearings = None if bearings is None else np.asarray(bearings, dtype=float)
    xi = float(bearing_error)
    relative = None if robot_bearings is None else np.asarray(robot_bearings, dtype=float)
    relative_error = (None if relative is None
                      else np.broadcast_to(np.asarray(robot_bearing_error, dtype=float), relative.shape))
    rho_min, reach_min = _validate(markers, meas, rho, bearings, xi, relative, relative_error)
    tol = DEFAULT_TOLERANCE_FRACTION * rho_min if tolerance is None else float(tolerance)
    if reach_min < 0.0:       # no point is at a negative distance
        return _empty(tol)
    if bearings is None and relative is None and markers.shape[0] == 2:
        fast = _two_ranges(markers, meas, rho, prior, tol)
        if fast is not None:
            return fast
    pairs = () if relative is None else _bearing_pairs(relative, relative_error)
    return _general(markers, meas, rho, prior, bearings, xi, tol, pairs)


def _bearing_pairs(relative, relative_error):
    """``(i, j, beta_i - beta_j, xi_i + xi_j)`` for every pair of robot-frame bearings."""
    b, e = relative.tolist(), relative_error.tolist()
    return tuple((i, j, b[i] - b[j], e[i] + e[j]) for i in range(len(b)) for j in range(i + 1, len(b)))


def _two_ranges(markers, meas, rho, prior, tol):
    """Return the closed form (:mod:`estimators.fault.annuli`) of the component on prior's side, or None.

    That is the component the general path returns (it mirrors what it finds to that side).
    """
    region = two_annuli_region(markers, meas, rho, prior, tol)
    if region is None:
        return None
    return FaultArea(region.ring, region.area, region.diameter, region.centroid, tol)


def _general(markers, meas, rho, prior, bearings, xi, tol, pairs=()):
    """Windowed shapely construction of :func:`exact_fault_area` (any measurements)."""
    std = rho if bearings is None else np.concatenate([rho, np.full(len(rho), xi)])
    seed = solve_position(markers, meas, std, prior, world_bearings=bearings).position
    comp = _component(markers, meas, rho, bearings, xi, seed, prior, tol, pairs)
    # (robot-frame bearings tell the mirror twins apart: the pair angle changes sign across)
    if comp is not None and bearings is None and not pairs and collinear_markers(markers):
        # Ranges to collinear markers: the exact set is symmetric about the marker line, so a
        # component on one side has a mirror twin on the other. Reflection is an isometry and
        # points on the prior's side are nearer to it: take the twin if the prior is across.
        comp_side = marker_line_side(shapely.get_coordinates(comp.exterior), markers)
        across = marker_line_side(prior, markers) * comp_side
        if np.all(across < 0.0):        # (a component straddling the line is its own twin)
            comp = _mirror_polygon(comp, markers)
    return _empty(tol) if comp is None else _from_polygon(comp, tol)


def fault_area_of_point(markers: np.ndarray, position: np.ndarray, rho: np.ndarray,
                        bearing_error: float = 0.0, tolerance: float | None = None) -> FaultArea:
    """Fault area of noise-free measurements taken at ``position`` (the planner's exact PEF).

    Parameters
    ----------
    markers : ndarray, shape (k, 2)
        Marker positions [m].
    position : ndarray, shape (2,)
        True robot position [m].
    rho : ndarray, shape (k,)
        Range error bounds [m], > 0 (usually ``range_bound(sensor, ranges)``).
    bearing_error : float
        Bearing bound xi [rad]; 0 means ranges only.
    tolerance : float, optional
        Polygonisation tolerance [m]; default ``1e-3 * min(rho)``.

    Returns
    -------
    FaultArea
        The component containing ``position``.
    """
    markers = np.asarray(markers, dtype=float).reshape(-1, 2)
    position = np.asarray(position, dtype=float)
    rho = np.asarray(rho, dtype=float)
    meas = ranges(position, markers)
    xi = float(bearing_error)
    bearings = world_bearing(position, markers) if xi > 0.0 else None
    rho_min, _ = _validate(markers, meas, rho, bearings, xi)
    tol = DEFAULT_TOLERANCE_FRACTION * rho_min if tolerance is None else float(tolerance)
    if bearings is None and markers.shape[0] == 2:
        # the closed form's component on the position's side is the one holding it
        fast = _two_ranges(markers, meas, rho, position, tol)
        if fast is not None:
            return fast
    comp = _component(markers, meas, rho, bearings, xi, position, position, tol)
    return _empty(tol) if comp is None else _from_polygon(comp, tol)
