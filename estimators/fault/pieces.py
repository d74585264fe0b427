"""Polygons of single constraints over a square window, for :mod:`estimators.fault.exact`.

A range's annulus becomes an annular sector covering the window's angular span as seen from
its marker (or the whole annulus when the marker is inside the window's circumcircle); a
bearing's wedge becomes a fan reaching beyond the window; a pair of robot-frame bearings
becomes the region between two circular arcs through its markers (:func:`bearing_pair_piece`).
Arcs are replaced by polylines on the far side from the constraint set (outer circles
circumscribed, inner ones inscribed), within ``tol`` of the circle, so every piece contains
its constraint inside the window.
"""

from __future__ import annotations

import math

import numpy as np
import shapely

from estimators.fault.annuli import arc_steps
from jit import compiled


@compiled.njit(cache=True)
def _sector_ring(mx, my, r_out, r_in, phi0, phi1, tol):
    """Build the closed ring (n, 2) of the annular sector phi0..phi1 [rad], radii r_in..r_out.

    The outer arc is circumscribed, the inner one inscribed (``r_in <= 0``: apex at the
    centre), so the ring contains the exact sector and stays within ``tol`` of it.
    """
    span = phi1 - phi0
    n_out, rad_out = arc_steps(r_out, span, tol, True)
    if r_in > 0.0:
        n_in, rad_in = arc_steps(r_in, span, tol, False)
        m_in = n_in + 1
    else:
        n_in, rad_in, m_in = 1, 0.0, 1
    if n_out < 0 or n_in < 0:
        raise ValueError("fault area: polygonisation tolerance too small for the arc radius")
    ring = np.empty((n_out + 1 + m_in + 1, 2))
    for j in range(n_out + 1):
        phi = phi0 + span * j / n_out
        ring[j, 0] = mx + rad_out * math.cos(phi)
        ring[j, 1] = my + rad_out * math.sin(phi)
    for j in range(m_in):
        phi = phi1 - span * j / n_in
        ring[n_out + 1 + j, 0] = mx + rad_in * math.cos(phi)
        ring[n_out + 1 + j, 1] = my + rad_in * math.sin(phi)
    ring[-1] = ring[0]
    return ring


def _circle(mx, my, radius, tol, outside):
    """Open ring (n, 2) within ``tol`` of a whole circle, circumscribed if ``outside``."""
    n, rad = arc_steps(radius, 2.0 * math.pi, tol, outside)
    if n < 0:
        raise ValueError(f"fault area: polygonisation tolerance {tol} too small for radius {radius}")
    n = max(n, 8)
    if outside:
        rad = radius / math.cos(math.pi / n)
    phi = (2.0 * math.pi / n) * np.arange(n)
    return np.column_stack([mx + rad * np.cos(phi), my + rad * np.sin(phi)])


def annulus_piece(marker, r, rho, center, half, tol):
    """Polygon holding the annulus inside the window; None if it does not constrain it.

    Returns the string "empty" when the annulus misses the window.
    """
    reach = half * math.sqrt(2.0)          # circumradius of the window
    mx, my = float(marker[0]), float(marker[1])
    dist = math.hypot(center[0] - mx, center[1] - my)
    r_out, r_in = r + rho, r - rho
    if r_out < dist - reach or r_in > dist + reach:
        return "empty"
    if r_in <= dist - reach and r_out >= dist + reach:
        return None
    if dist > reach:
        phi_c = math.atan2(center[1] - my, center[0] - mx)
        delta = math.asin(reach / dist)
        return shapely.polygons(_sector_ring(mx, my, r_out, r_in, phi_c - delta, phi_c + delta, tol))
    outer = _circle(mx, my, r_out, tol, True)
    return shapely.polygons(outer, holes=[_circle(mx, my, r_in, tol, False)] if r_in > 0.0 else None)


def wedge_piece(marker, beta, xi, center, half):
    """Polygon holding the wedge apex ``marker``, directions beta + pi +- xi, over the window."""
    if xi >= math.pi:
        return None
    mx, my = float(marker[0]), float(marker[1])
    far = math.hypot(abs(center[0] - mx) + half, abs(center[1] - my) + half)
    n = max(1, math.ceil(2.0 * xi / (math.pi / 4.0)))
    step = 2.0 * xi / n
    length = 2.0 * far / math.cos(step / 2.0)   # the far chords stay beyond the window
    phi = beta + math.pi - xi + step * np.arange(n + 1)
    ring = np.empty((n + 2, 2))
    ring[0] = mx, my
    ring[1:, 0] = mx + length * np.cos(phi)
    ring[1:, 1] = my + length * np.sin(phi)
    return shapely.polygons(ring)


MAX_ARC_RADIUS = 1e9
"""Radius [m] above which a bearing pair's arc is not polygonised: its half of the constraint
is dropped (the piece then still contains the constraint). Only a bearing difference within
``d / 2e9`` rad of 0 or pi comes near it."""


def _disk_outer(cx, cy, radius, center, half, tol):
    """Polygon containing the closed disk's part in the window; None: the window lies inside it.

    Returns the string "empty" when the disk misses the window. The arc is circumscribed.
    """
    reach = half * math.sqrt(2.0)
    dist = math.hypot(center[0] - cx, center[1] - cy)
    if dist - reach > radius:
        return "empty"
    if dist + reach <= radius or radius > MAX_ARC_RADIUS:
        return None
    if dist > reach:
        phi_c = math.atan2(center[1] - cy, center[0] - cx)
        delta = math.asin(reach / dist)
        return shapely.polygons(_sector_ring(cx, cy, radius, 0.0, phi_c - delta, phi_c + delta, tol))
    return shapely.polygons(_circle(cx, cy, radius, tol, True))


def _disk_inner(cx, cy, radius, center, half, tol):
    """Polygon inside the open disk, covering its part in the window but for ``tol``; None if none.

    Returns the string "all" when the window lies inside the disk. The arc is inscribed.
    """
    reach = half * math.sqrt(2.0)
    dist = math.hypot(center[0] - cx, center[1] - cy)
    if dist - reach >= radius or radius > MAX_ARC_RADIUS:
        return None
    if dist + reach < radius:
        return "all"
    if dist > reach:
        phi_c = math.atan2(center[1] - cy, center[0] - cx)
        delta = math.asin(reach / dist)
        n, rad = arc_steps(radius, 2.0 * delta, tol, False)
        if n < 0:
            raise ValueError(f"fault area: polygonisation tolerance {tol} too small for radius {radius}")
        phi = phi_c - delta + (2.0 * delta / n) * np.arange(n + 1)
        ring = np.empty((n + 3, 2))
        ring[0] = ring[-1] = cx, cy
        ring[1:-1, 0] = cx + rad * np.cos(phi)
        ring[1:-1, 1] = cy + rad * np.sin(phi)
        return shapely.polygons(ring)
    return shapely.polygons(_circle(cx, cy, radius, tol, False))


def pair_circle(mi, mj, phi):
    """Centre (2,) [m] and radius [m] of the circle through ``mi`` and ``mj`` where ``a_i - a_j = phi``.

    ``a_i(p)`` is the direction from ``p`` to ``mi``. By the inscribed-angle theorem the circle
    is ``{a_i - a_j = phi} U {a_i - a_j = phi - pi}`` (mod 2 pi, one arc each side of the line
    through the markers), and the angle grows towards the chord: its open disk is
    ``D(phi) = {a_i - a_j in (phi, phi + pi)}`` when ``sin(phi) > 0``, and the open exterior
    is when ``sin(phi) < 0``. Radius ``inf`` when ``sin(phi) = 0`` (a half-plane).
    """
    dx, dy = mi[0] - mj[0], mi[1] - mj[1]
    d = math.hypot(dx, dy)
    s = math.sin(phi)
    if s == 0.0:
        return np.array([math.nan, math.nan]), math.inf
    t = 0.5 * math.cos(phi) / s            # along the left normal of mj -> mi, in units of d
    return np.array([0.5 * (mi[0] + mj[0]) - t * dy, 0.5 * (mi[1] + mj[1]) + t * dx]), 0.5 * d / abs(s)


def bearing_pair_piece(mi, mj, gamma, delta, center, half, tol):
    """Polygon holding ``{p : |wrap(a_i(p) - a_j(p) - gamma)| <= delta}`` over the window.

    ``a_i(p) - a_j(p)`` is the angle at ``p`` from marker ``mj`` to marker ``mi``; the robot
    measures it, heading-free, as the difference ``gamma`` of their robot-frame bearings, within
    the sum ``delta`` of their bounds. With ``delta < pi / 2`` the set is
    ``closure(D(gamma - delta)) minus D(gamma + delta)`` (:func:`pair_circle`): the region
    between two circular arcs through both markers, i.e. for each circle either its closed
    disk or the complement of its open disk. A disk kept is polygonised circumscribed, one
    removed inscribed, so the piece contains the set inside the window and lies within
    ``tol`` of it. Returns None when the pair does not constrain the window (also for
    ``delta >= pi / 2``: no piece is a superset) and the string "empty" when the set misses
    the window.
    """
    if not delta < 0.5 * math.pi:
        return None
    keep, remove = [], []
    for phi, lower in ((gamma - delta, True), (gamma + delta, False)):
        c, r = pair_circle(mi, mj, phi)
        if not math.isfinite(r):
            continue                      # a half-plane: dropped (a superset)
        # lower bound: inside the closed disk when sin > 0; upper bound: inside when sin < 0
        if (math.sin(phi) > 0.0) == lower:
            piece = _disk_outer(c[0], c[1], r, center, half, tol)
            if isinstance(piece, str):
                return "empty"
            if piece is not None:
                keep.append(piece)
        else:
            piece = _disk_inner(c[0], c[1], r, center, half, tol)
            if isinstance(piece, str):
                return "empty"
            if piece is not None:
                remove.append(piece)
    if not keep and not remove:
        return None
    geom = keep[0] if keep else shapely.box(center[0] - 2.0 * half, center[1] - 2.0 * half,
                                            center[0] + 2.0 * half, center[1] + 2.0 * half)
    for piece in keep[1:]:
        geom = shapely.intersection(geom, piece)
    for piece in remove:
        geom = shapely.difference(geom, piece)
    return "empty" if geom.is_empty else geom


# numba keys a cache on its own file only: flush the kernels above when a file they inline changed
compiled.keep_fresh(__name__)
