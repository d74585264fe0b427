"""Convex obstacle pieces as half-planes, and the kernels that test points and segments on them.

Every obstacle reaches the kernels as convex pieces (:meth:`scenarios.Scenario.obstacle_pieces`).
A piece with vertices ``v_0 .. v_{n-1}`` counter-clockwise is the set where
``nx_k x + ny_k y <= c_k`` for every edge k (unit outward normals), which is all these kernels
need: a point is solid when it meets every edge's inequality (boundary included); a segment
blocks the line of sight when some part of it meets every ``< e_k`` (Cyrus-Beck clipping, the
convex generalisation of the box's Liang-Barsky); and the shadow of a piece seen from a marker
is the cone over its silhouette beyond the edges turned to the marker.

For line of sight each edge is moved by ``s``: a face of the obstacle inwards
(``e_k = c_k - s``), so that a segment ending on a face or grazing it is not blocked; a cut
between two pieces of one obstacle *outwards* (``e_k = c_k + s``), so that neighbouring pieces
overlap and a segment running exactly along a cut, inside the obstacle, is still blocked.
A circle's faces move in by its polygon's ``inset`` as well: line of sight then sees the
inscribed polygon (vertices on the circle), free space and clearance the circumscribed one,
each within 1 mm of the circle and each on the safe side for markers on the pillar.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from jit import compiled
from scenarios.obstacles import ConvexPieces


@dataclass(frozen=True)
class PieceArrays:
    """Convex pieces prepared for the kernels.

    Attributes
    ----------
    vertices : ndarray, shape (P, V, 2)
        Corners of each piece, counter-clockwise [m] (padded as in ``ConvexPieces``).
    planes : ndarray, shape (P, V, 3)
        ``(nx, ny, c)`` of each edge: unit outward normal and offset [m]; rows past
        ``count[p]`` are unused.
    sight : ndarray, shape (P, V)
        Offsets ``e`` of the edges for line of sight [m]: ``c - shrink - inset`` on faces,
        ``c + shrink`` on cuts.
    shrunk : ndarray, shape (P, V, 2)
        Corners of the line-of-sight piece (where consecutive ``sight`` lines meet) [m], for
        the shadow's silhouette.
    count : ndarray of int64, shape (P,)
        Edges (= vertices) of each piece.
    bbox : ndarray, shape (P, 4)
        ``(xmin, ymin, xmax, ymax)`` of each piece [m].
    sight_bbox : ndarray, shape (P, 4)
        The same of each line-of-sight piece (corners ``shrunk``) [m]: a cut moved out pokes
        past ``bbox``, so line-of-sight tests must not reject segments by ``bbox``.
    blocks : ndarray of bool, shape (P,)
        The piece keeps an interior when shrunk (a sliver thinner than ``2 shrink`` does not,
        and blocks no line of sight, as a box that thin never did).
    shrink : float
        The inward shift of ``shrunk`` [m].
    """

    vertices: np.ndarray
    planes: np.ndarray
    sight: np.ndarray
    shrunk: np.ndarray
    count: np.ndarray
    bbox: np.ndarray
    sight_bbox: np.ndarray
    blocks: np.ndarray
    shrink: float


def piece_arrays(pieces: ConvexPieces, shrink: float, grow: float = 0.0) -> PieceArrays:
    """Turn padded convex pieces into edge half-planes, shrunk corners and bounding boxes.

    Parameters
    ----------
    pieces : scenarios.ConvexPieces
        Counter-clockwise convex polygons, ``vertices`` shape (P, V, 2) [m].
    shrink : float
        Shift of the edges for line-of-sight tests [m] (faces in, cuts out).
    grow : float
        Then every edge, faces and cuts alike, moves *out* by this much [m] (>= 0): the
        pieces a line of sight must clear by ``grow`` (:mod:`planner.pef.sight`).

    Returns
    -------
    PieceArrays
    """
    v = np.asarray(pieces.vertices, float).reshape(-1, max(pieces.vertices.shape[1], 3), 2)
    count = np.ascontiguousarray(pieces.count, dtype=np.int64)
    p_n, v_n = v.shape[:2]
    planes = np.zeros((p_n, v_n, 3))
    sight = np.zeros((p_n, v_n))
    shrunk = np.zeros((p_n, v_n, 2))
    bbox = np.zeros((p_n, 4))
    sight_bbox = np.zeros((p_n, 4))
    blocks = np.zeros(p_n, dtype=np.bool_)
    for p in range(p_n):
        n = int(count[p])
        q = v[p, :n]
        e = np.roll(q, -1, axis=0) - q
        length = np.hypot(e[:, 0], e[:, 1])
        normal = np.column_stack([e[:, 1], -e[:, 0]]) / length[:, None]   # outward for CCW
        planes[p, :n, :2] = normal
        planes[p, :n, 2] = np.einsum("ij,ij->i", normal, q)
        shift = np.where(pieces.inner[p, :n], shrink, -shrink - pieces.inset[p, :n]) + grow
        sight[p, :n] = planes[p, :n, 2] + shift
        # Corner k joins edges k-1 and k; with their lines moved by d_{k-1} and d_k along the
        # normals it moves by the delta solving n_{k-1}.delta = d_{k-1}, n_k.delta = d_k.
        prev_n, prev_d = np.roll(normal, 1, axis=0), np.roll(shift, 1)
        det = prev_n[:, 0] * normal[:, 1] - prev_n[:, 1] * normal[:, 0]   # sin of the turn, > 0
        dx = (prev_d * normal[:, 1] - shift * prev_n[:, 1]) / det
        dy = (shift * prev_n[:, 0] - prev_d * normal[:, 0]) / det
        shrunk[p, :n] = q + np.column_stack([dx, dy])
        # The moved piece is a piece when every moved edge still runs the way its edge does.
        se = np.roll(shrunk[p, :n], -1, axis=0) - shrunk[p, :n]
        blocks[p] = bool(np.all(np.einsum("ij,ij->i", se, e) > 0.0))
        if not blocks[p] or np.min(np.abs(det)) < _STRAIGHT:
            # A straight corner (a cut continuing a face, a redundant vertex) has no corner of
            # its two moved lines, or one far off; when they move apart an edge vanishes. Take
            # the corners of the half-planes' intersection instead.
            shrunk[p, :n], blocks[p] = _clipped_corners(normal, sight[p, :n], q)
        shrunk[p, n:] = shrunk[p, n - 1]
        sight[p, n:] = sight[p, n - 1]
        bbox[p] = (*q.min(axis=0), *q.max(axis=0))
        sight_bbox[p] = (*shrunk[p, :n].min(axis=0), *shrunk[p, :n].max(axis=0))
    return PieceArrays(np.ascontiguousarray(v), planes, sight, shrunk, count, bbox, sight_bbox, blocks,
                       float(shrink))


#: A corner whose edges turn by less than this (sine) is straight for :func:`piece_arrays`.
_STRAIGHT = 1e-3


def _clipped_corners(normal: np.ndarray, offset: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, bool]:
    """Corners of the convex polygon ``normal[k] . x <= offset[k]``, one per edge, and whether it has an interior.

    Corner k is where edge k starts on the polygon; an edge that another makes redundant
    (zero length) starts where the next edge that remains does, so that corner k is also
    the end of edge k - 1, as :func:`shadow_halfplanes` reads them. ``q`` (n, 2): the
    piece's vertices, returned when nothing remains.
    """
    n = len(offset)
    direction = np.column_stack([-normal[:, 1], normal[:, 0]])       # along each edge, counter-clockwise
    origin = normal * offset[:, None]                                # a point on each moved line
    start = np.empty((n, 2))
    alive = np.zeros(n, dtype=bool)
    for k in range(n):
        den = normal @ direction[k]
        num = offset - normal @ origin[k]
        others = np.arange(n) != k
        if np.any(others & (den == 0.0) & (num <= 0.0)):
            continue  # a parallel edge lies inside this one: it is redundant
        lo = np.max(num[others & (den < 0.0)] / den[others & (den < 0.0)], initial=-np.inf)
        hi = np.min(num[others & (den > 0.0)] / den[others & (den > 0.0)], initial=np.inf)
        if lo < hi and np.isfinite(lo):
            alive[k] = True
            start[k] = origin[k] + lo * direction[k]
    if alive.sum() < 3:
        return q.copy(), False
    for k in range(n - 1, -1, -1):  # a vanished edge starts where the next remaining one does
        if not alive[k]:
            j = k + 1
            while not alive[j % n]:
                j += 1
            start[k] = start[j % n]
    return start, True


@compiled.njit(cache=True)
def inside_closed(px, py, planes, count, p):
    """Tell whether point (px, py) lies in piece ``p``, boundary included."""
    for k in range(count[p]):
        if planes[p, k, 0] * px + planes[p, k, 1] * py > planes[p, k, 2]:
            return False
    return True


@compiled.njit(cache=True)
def segment_enters(ax, ay, bx, by, planes, sight, count, p):
    """Tell whether segment a-b meets the open line-of-sight piece ``p`` (offsets ``sight``; Cyrus-Beck)."""
    dx, dy = bx - ax, by - ay
    t0, t1 = 0.0, 1.0
    for k in range(count[p]):
        nx, ny = planes[p, k, 0], planes[p, k, 1]
        num = sight[p, k] - (nx * ax + ny * ay)   # inside: t * den < num
        den = nx * dx + ny * dy
        if den == 0.0:
            if num <= 0.0:
                return False
        elif den > 0.0:
            t = num / den
            if t < t1:
                t1 = t
        else:
            t = num / den
            if t > t0:
                t0 = t
        if t0 >= t1:
            return False
    return t0 < t1


@compiled.njit(cache=True)
def shadow_halfplanes(mx, my, planes, sight, shrunk, count, p, out):
    """Half-planes ``a x + b y + c < 0`` whose intersection is the shadow of piece ``p`` from a marker.

    The shadow is the set of points whose segment to the marker (mx, my) enters the open
    line-of-sight piece (offsets ``sight``, corners ``shrunk``): the open cone from the marker
    over the silhouette, on the inner side of every edge turned to the marker. ``out`` has
    shape (>= count[p] + 2, 3).

    Returns the number of rows written; -1 when the marker is inside the line-of-sight piece
    or on its boundary (it is hidden from everywhere). Callers skip pieces that do not block.
    """
    n = count[p]
    nrow = 0
    first = -1
    last = -1
    for k in range(n):
        nx, ny, c = planes[p, k, 0], planes[p, k, 1], sight[p, k]
        if nx * mx + ny * my - c > 0.0:       # the marker sees edge k from outside
            out[nrow, 0], out[nrow, 1], out[nrow, 2] = nx, ny, -c
            nrow += 1
            k0 = (k + n - 1) % n
            if not (planes[p, k0, 0] * mx + planes[p, k0, 1] * my - sight[p, k0] > 0.0):
                first = k                      # the facing chain starts at corner k ...
            k1 = (k + 1) % n
            if not (planes[p, k1, 0] * mx + planes[p, k1, 1] * my - sight[p, k1] > 0.0):
                last = k1                      # ... and ends at corner k + 1
    if nrow == 0 or first < 0 or last < 0:
        return -1
    ax, ay = shrunk[p, first, 0] - mx, shrunk[p, first, 1] - my   # cross(A, q - m) < 0
    out[nrow, 0], out[nrow, 1], out[nrow, 2] = -ay, ax, ay * mx - ax * my
    nrow += 1
    bx, by = shrunk[p, last, 0] - mx, shrunk[p, last, 1] - my     # cross(B, q - m) > 0
    out[nrow, 0], out[nrow, 1], out[nrow, 2] = by, -bx, -(by * mx - bx * my)
    nrow += 1
    return nrow


@compiled.njit(cache=True, nogil=True)
def signed_distance_min(px, py, vertices, count, bbox, out):
    """Lower ``out[n]`` to the signed distance from point n to the nearest piece [m].

    Outside a piece the distance to it; inside, minus the distance to its nearest edge (the
    box's signed distance for a box; inside an obstacle cut into pieces it is negative but
    may be shallower than the depth in the whole obstacle). Pieces whose bounding box is
    farther than ``out[n]`` already is are skipped.
    """
    for n in range(px.size):
        x, y = px[n], py[n]
        best = out[n]
        for p in range(count.size):
            gx = max(bbox[p, 0] - x, 0.0, x - bbox[p, 2])
            gy = max(bbox[p, 1] - y, 0.0, y - bbox[p, 3])
            if gx * gx + gy * gy >= best * best and best > 0.0:
                continue
            inside = True
            d2 = np.inf
            m = count[p]
            for k in range(m):
                ax, ay = vertices[p, k, 0], vertices[p, k, 1]
                k1 = k + 1 if k + 1 < m else 0
                ex, ey = vertices[p, k1, 0] - ax, vertices[p, k1, 1] - ay
                wx, wy = x - ax, y - ay
                if ex * wy - ey * wx < 0.0:
                    inside = False
                t = (wx * ex + wy * ey) / (ex * ex + ey * ey)
                t = min(max(t, 0.0), 1.0)
                qx, qy = wx - t * ex, wy - t * ey
                q2 = qx * qx + qy * qy
                if q2 < d2:
                    d2 = q2
            d = -np.sqrt(d2) if inside else np.sqrt(d2)
            if d < best:
                best = d
        out[n] = best
