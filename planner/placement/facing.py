"""Which way a candidate site faces: sites on faces become flat reflectors.

A site on an obstacle's face faces out of the face (the outward normal of the boundary edge it
lies on: for a circle, of the circumscribed polygon's face); a site on the workspace wall faces
into the workspace (when ``workspace.walls``); a site on no face (an explicit
``placement.candidates`` point in the open) stays a post. With ``placement.marker_kind =
"post"`` every site is a post.

On a ROS map the faces are traced cells, simplified: a wall a few degrees off the grid keeps
one-cell jogs whose short edges point anywhere. There a face's direction is the normal of a
line fitted to the boundary around the site (the principal axis of the ring's points within
:data:`FIT_REACH` along it on either side), oriented out of the obstacle; where that stretch
has no clear axis (a pillar smaller than the stretch) the edge's own normal stays.
"""

from __future__ import annotations

import math

import numpy as np

from scenarios.floorplan import FloorPlanKind
from scenarios.schema import Marker, MarkerKind, Scenario

#: A site counts as on an edge within this distance of it [m].
ON_FACE = 1e-6

#: How far along a traced face, on either side of a site, the fitted line reaches [m]: a
#: quarter of a 1 m pillar's perimeter each way, several cells of any map.
FIT_REACH = 0.25

#: Largest ratio of the fitted stretch's minor to major variance that still counts as a line
#: (a straight stretch: 0; a half circle: 0.19; a whole ring: 1).
FIT_LINE = 0.3

#: Points sampled along the fitted stretch.
_FIT_SAMPLES = 41


def _distances(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from points p (N, 2) to segments a-b (E, 2) [m], shape (N, E)."""
    d = b - a
    ll = np.maximum((d * d).sum(axis=1), 1e-300)
    t = np.clip(((p[:, None, :] - a) * d).sum(axis=2) / ll, 0.0, 1.0)
    q = a + t[..., None] * d - p[:, None, :]
    return np.hypot(q[..., 0], q[..., 1])


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
        :func:`face_directions`, or every site None with ``placement.marker_kind = "post"``.
    """
    sites = np.asarray(sites, float).reshape(-1, 2)
    if scenario.placement.marker_kind is MarkerKind.POST:
        return [None] * len(sites)
    return face_directions(scenario, sites)


def face_directions(scenario: Scenario, sites: np.ndarray) -> list[float | None]:
    """Outward direction [rad] of the face each site lies on, None on no face (see module doc).

    A site takes the first ring (the workspace wall, then the obstacles' rings in order) that
    has an edge within :data:`ON_FACE` of it, and that ring's nearest edge.

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
    x0, y0, x1, y1 = scenario.workspace.bounds
    wall = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])  # counter-clockwise: inward = left
    rings = [(wall, None)] if scenario.workspace.walls else []
    rings += [(r, ob) for ob in scenario.obstacles for r in ob.rings()]
    if not rings:
        return [None] * len(sites)
    traced = scenario.floorplan is not None and scenario.floorplan.kind is FloorPlanKind.ROSMAP
    # every ring's edges in one array (ring by ring): the distances of a chunk of sites at once
    a = np.vstack([r for r, _ in rings])
    b = np.vstack([np.roll(r, -1, axis=0) for r, _ in rings])
    start = np.cumsum([0] + [len(r) for r, _ in rings])
    ring_of = np.repeat(np.arange(len(rings)), np.diff(start))
    out: list[float | None] = []
    for lo in range(0, len(sites), _CHUNK):
        dist = _distances(sites[lo:lo + _CHUNK], a, b)
        on = dist <= ON_FACE
        for i, p in enumerate(sites[lo:lo + _CHUNK]):
            hit = np.flatnonzero(on[i])
            if not hit.size:
                out.append(None)
                continue
            k = int(ring_of[hit[0]])
            ob = rings[k][1]
            e = start[k] + int(np.argmin(dist[i, start[k]:start[k + 1]]))
            d = b[e] - a[e]
            n = np.array([-d[1], d[0]]) / math.hypot(*d)  # left normal
            if ob is not None and ob.contains(p + 1e-4 * n):
                n = -n  # out of the obstacle, whichever way its ring runs
            if traced and ob is not None:
                n = _fitted_normal(rings[k][0], e - start[k], p, n)
            out.append(math.atan2(n[1], n[0]))
    return out


def _fitted_normal(ring: np.ndarray, edge: int, p: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Normal of the line fitted to ``ring`` (R, 2) around ``p`` on edge ``edge``, on ``n``'s side.

    The ring is sampled at :data:`_FIT_SAMPLES` points within :data:`FIT_REACH` [m] of ``p``
    along it (both ways, wrapping round); the normal is the minor principal axis of those
    points. ``n`` (2,), the edge's outward unit normal, gives the side, and is returned as it
    is when the stretch is no line (minor / major variance above :data:`FIT_LINE`).
    """
    closed = np.vstack([ring, ring[:1]])
    seg = np.hypot(*np.diff(closed, axis=0).T)
    s_at = np.concatenate([[0.0], np.cumsum(seg)])
    perimeter = float(s_at[-1])
    if perimeter <= 0.0:
        return n
    s0 = s_at[edge] + float(np.hypot(*(p - ring[edge])))
    s = np.mod(s0 + np.linspace(-FIT_REACH, FIT_REACH, _FIT_SAMPLES), perimeter)
    q = np.column_stack([np.interp(s, s_at, closed[:, 0]), np.interp(s, s_at, closed[:, 1])])
    q = q - q.mean(axis=0)
    val, vec = np.linalg.eigh(q.T @ q)  # ascending: vec[:, 0] is the minor axis
    if val[1] <= 0.0 or val[0] > FIT_LINE * val[1]:
        return n
    m = vec[:, 0]
    return m if float(m @ n) >= 0.0 else -m


#: Sites per chunk of :func:`site_facings` (a (chunk, edges) array of distances).
_CHUNK = 256


def site_marker(mid: str, site, facing: float | None) -> Marker:
    """Make a marker at ``site`` (x, y) [m]: flat facing ``facing`` [rad], or a post when None."""
    pos = (float(site[0]), float(site[1]))
    if facing is None:
        return Marker(mid, pos)
    return Marker(mid, pos, float(facing), MarkerKind.FLAT)
