"""Polygons of single constraints over a square window, for :mod:`estimators.fault.exact`.

A range's annulus becomes an annular sector covering the window's angular span as seen from
its marker (or the whole annulus when the marker is inside the window's circumcircle); a
bearing's wedge becomes a fan reaching beyond the window. Arcs are replaced by polylines on
the far side from the constraint set (outer circles circumscribed, inner ones inscribed),
within ``tol`` of the circle, so every piece contains its constraint inside the window.
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


# numba keys a cache on its own file only: flush the kernels above when a file they inline changed
compiled.keep_fresh(__name__)
