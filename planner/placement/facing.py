"""Which way a candidate site faces: sites on faces become flat reflectors.

A site on an obstacle's face faces out of the face (the outward normal of the boundary edge it
lies on: for a circle, of the circumscribed polygon's face); a site on the workspace wall faces
into the workspace (when ``workspace.walls``); a site on no face (an explicit
``placement.candidates`` point in the open) stays a post. With ``placement.marker_kind =
"post"`` every site is a post.

On a ROS map the faces are traced cells, simplified within a cell: a wall a few degrees off
the grid keeps one-cell jogs whose short edges point anywhere, and the simplified outline
itself may tilt by a cell over a metre. There a face's direction is the normal of a line
fitted to the map's own cell boundary around the site: the principal axis of the midpoints of
the occupied cells' faces within :data:`FIT_RADIUS` that look the site's way (their outward
normal within 90 degrees of the simplified edge's), oriented out of the obstacle; where those
points make no line (a pillar smaller than the disc) the edge's own normal stays.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from scenarios.floorplan import FloorPlanKind
from scenarios.schema import Marker, MarkerKind, Scenario

#: A site counts as on an edge within this distance of it [m].
ON_FACE = 1e-6

#: Radius of the disc of cell faces a traced face's line is fitted to [m]: ten cells of a
#: 5 cm map each way, a few steps of any staircase.
FIT_RADIUS = 0.5

#: Largest ratio of the fitted points' minor to major variance that still counts as a line
#: (a straight face: about 0; a half circle: 0.19; a whole ring: 1).
FIT_LINE = 0.3


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
    fp = scenario.floorplan
    faces = _cell_faces(str(fp.file), fp.file.stat().st_mtime_ns) \
        if fp is not None and fp.kind is FloorPlanKind.ROSMAP else None
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
            if faces is not None and ob is not None:
                n = _fitted_normal(faces, p, n)
            out.append(math.atan2(n[1], n[0]))
    return out


@functools.lru_cache(maxsize=4)
def _cell_faces(file: str, stamp: int):
    """Return midpoints [m] and outward normals of the faces between a ROS map's occupied and other cells.

    ``stamp``: the YAML's modification time, so an edited map is read again. Returns a KD-tree
    of the midpoints (F, 2) and the normals (F, 2) (unit, axis-aligned).
    """
    from scipy.spatial import cKDTree

    from scenarios.floorplan.rosmap import read_cells

    occ, _, res, (ox, oy) = read_cells(file)
    r, c = np.nonzero(occ[:, 1:] != occ[:, :-1])          # between columns c and c + 1
    vert = np.column_stack([ox + (c + 1) * res, oy + (r + 0.5) * res])
    vn = np.column_stack([np.where(occ[r, c], 1.0, -1.0), np.zeros(len(r))])
    r, c = np.nonzero(occ[1:, :] != occ[:-1, :])          # between rows r and r + 1
    horiz = np.column_stack([ox + (c + 0.5) * res, oy + (r + 1) * res])
    hn = np.column_stack([np.zeros(len(r)), np.where(occ[r, c], 1.0, -1.0)])
    return cKDTree(np.vstack([vert, horiz])), np.vstack([vn, hn])


def _fitted_normal(faces, p: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Return the normal of the line fitted to the cell faces around ``p`` (2,) that look ``n``'s way.

    ``faces``: :func:`_cell_faces`; ``n`` (2,), the simplified edge's outward unit normal, gives
    the side, and is returned as it is where the faces make no line.
    """
    tree, normals = faces
    idx = np.asarray(tree.query_ball_point(p, FIT_RADIUS), dtype=np.int64)
    if len(idx):
        idx = idx[normals[idx] @ n > 0.0]
    if len(idx) < 3:
        return n
    q = tree.data[idx] - tree.data[idx].mean(axis=0)
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
