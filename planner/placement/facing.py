"""Which way a candidate site faces: sites on faces become flat reflectors.

A site on an obstacle's face faces out of the face (the outward normal of the boundary edge it
lies on: for a circle, of the circumscribed polygon's face); a site on the workspace wall faces
into the workspace; a site on no face (an explicit ``placement.candidates`` point in the open)
stays a post. With ``placement.marker_kind = "post"`` every site is a post.
"""

from __future__ import annotations

import math

import numpy as np

from scenarios.schema import Marker, MarkerKind, Scenario

#: A site counts as on an edge within this distance of it [m].
ON_FACE = 1e-6


def _edges(ring: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return ring, np.roll(ring, -1, axis=0)


def _on_edge(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from point p (2,) to segments a-b (E, 2) [m], shape (E,)."""
    d = b - a
    ll = np.maximum((d * d).sum(axis=1), 1e-300)
    t = np.clip(((p - a) * d).sum(axis=1) / ll, 0.0, 1.0)
    return np.hypot(*(a + t[:, None] * d - p).T)


def site_facings(scenario: Scenario, sites: np.ndarray) -> list[float | None]:
    """Facing [rad] of each candidate site, None for a post (see module doc).

    Parameters
    ----------
    scenario : Scenario
        Workspace and obstacles (and ``placement.marker_kind``).
    sites : ndarray, shape (S, 2)
        Candidate sites [m].

    Returns
    -------
    list of float or None, length S
        The outward (obstacle) or inward (wall) normal's direction [rad], or None.
    """
    sites = np.asarray(sites, float).reshape(-1, 2)
    if scenario.placement.marker_kind is MarkerKind.POST:
        return [None] * len(sites)
    x0, y0, x1, y1 = scenario.workspace.bounds
    wall = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])  # counter-clockwise: inward = left
    rings = [(wall, None)]
    rings += [(r, ob) for ob in scenario.obstacles for r in ob.rings()]
    out: list[float | None] = []
    for p in sites:
        facing = None
        for ring, ob in rings:
            a, b = _edges(ring)
            dist = _on_edge(p, a, b)
            e = int(np.argmin(dist))
            if dist[e] > ON_FACE:
                continue
            d = b[e] - a[e]
            n = np.array([-d[1], d[0]]) / math.hypot(*d)  # left normal
            if ob is not None and ob.contains(p + 1e-4 * n):
                n = -n  # out of the obstacle, whichever way its ring runs
            facing = math.atan2(n[1], n[0])
            break
        out.append(facing)
    return out


def site_marker(mid: str, site, facing: float | None) -> Marker:
    """Make a marker at ``site`` (x, y) [m]: flat facing ``facing`` [rad], or a post when None."""
    pos = (float(site[0]), float(site[1]))
    if facing is None:
        return Marker(mid, pos)
    return Marker(mid, pos, float(facing), MarkerKind.FLAT)
