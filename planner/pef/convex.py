"""Convex obstacle pieces as half-planes, and the kernels that test points and segments on them.

Every obstacle reaches the kernels as convex pieces (:meth:`scenarios.Scenario.obstacle_pieces`).
A piece with vertices ``v_0 .. v_{n-1}`` counter-clockwise is the set where
``nx_k x + ny_k y <= c_k`` for every edge k (unit outward normals), which is all these kernels
need: a point is solid when it meets every edge's inequality (boundary included); a segment
enters the interior shrunk by ``s`` when some part of it meets every ``< c_k - s``
(Cyrus-Beck clipping, the convex generalisation of the box's Liang-Barsky); and the shadow of a
piece seen from a marker is the cone over its silhouette beyond the edges turned to the marker.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from scenarios.obstacles import ConvexPieces


@dataclass(frozen=True)
class PieceArrays:
    """Convex pieces prepared for the kernels.

    Attributes
    ----------
    planes : ndarray, shape (P, V, 3)
        ``(nx, ny, c)`` of each edge: unit outward normal and offset [m]; rows past
        ``count[p]`` are unused.
    shrunk : ndarray, shape (P, V, 2)
        Vertices of each piece with every edge moved inwards by ``shrink`` [m] (the corners
        of the shrunk piece, for the shadow's silhouette).
    count : ndarray of int64, shape (P,)
        Edges (= vertices) of each piece.
    bbox : ndarray, shape (P, 4)
        ``(xmin, ymin, xmax, ymax)`` of each piece [m].
    blocks : ndarray of bool, shape (P,)
        The piece keeps an interior when shrunk (a sliver thinner than ``2 shrink`` does not,
        and blocks no line of sight, as a box that thin never did).
    shrink : float
        The inward shift of ``shrunk`` [m].
    """

    planes: np.ndarray
    shrunk: np.ndarray
    count: np.ndarray
    bbox: np.ndarray
    blocks: np.ndarray
    shrink: float


def piece_arrays(pieces: ConvexPieces, shrink: float) -> PieceArrays:
    """Turn padded convex pieces into edge half-planes, shrunk corners and bounding boxes.

    Parameters
    ----------
    pieces : scenarios.ConvexPieces
        Counter-clockwise convex polygons, ``vertices`` shape (P, V, 2) [m].
    shrink : float
        Inward shift of the edges for line-of-sight tests [m].

    Returns
    -------
    PieceArrays
    """
    v = np.asarray(pieces.vertices, float).reshape(-1, max(pieces.vertices.shape[1], 3), 2)
    count = np.ascontiguousarray(pieces.count, dtype=np.int64)
    p_n, v_n = v.shape[:2]
    planes = np.zeros((p_n, v_n, 3))
    shrunk = np.zeros((p_n, v_n, 2))
    bbox = np.zeros((p_n, 4))
    blocks = np.zeros(p_n, dtype=np.bool_)
    for p in range(p_n):
        n = int(count[p])
        q = v[p, :n]
        e = np.roll(q, -1, axis=0) - q
        length = np.hypot(e[:, 0], e[:, 1])
        normal = np.column_stack([e[:, 1], -e[:, 0]]) / length[:, None]   # outward for CCW
        planes[p, :n, :2] = normal
        planes[p, :n, 2] = np.einsum("ij,ij->i", normal, q)
        # Corner k joins edges k-1 and k: moving both lines in by s moves the corner along
        # the bisector by s / cos(half the turn), i.e. by s (n_{k-1} + n_k) / (1 + n_{k-1}.n_k).
        prev = np.roll(normal, 1, axis=0)
        shrunk[p, :n] = q - shrink * (prev + normal) / (1.0 + np.einsum("ij,ij->i", prev, normal))[:, None]
        shrunk[p, n:] = shrunk[p, n - 1]
        bbox[p] = (*q.min(axis=0), *q.max(axis=0))
        # Shrinking keeps the piece when every shrunk edge still runs the way its edge does.
        se = np.roll(shrunk[p, :n], -1, axis=0) - shrunk[p, :n]
        blocks[p] = bool(np.all(np.einsum("ij,ij->i", se, e) > 0.0))
    return PieceArrays(planes, shrunk, count, bbox, blocks, float(shrink))


@numba.njit(cache=True)
def inside_closed(px, py, planes, count, p):
    """Tell whether point (px, py) lies in piece ``p``, boundary included."""
    for k in range(count[p]):
        if planes[p, k, 0] * px + planes[p, k, 1] * py > planes[p, k, 2]:
            return False
    return True


@numba.njit(cache=True)
def segment_enters(ax, ay, bx, by, planes, count, p, shrink):
    """Tell whether segment a-b meets the open interior of piece ``p`` shrunk by ``shrink`` (Cyrus-Beck)."""
    dx, dy = bx - ax, by - ay
    t0, t1 = 0.0, 1.0
    for k in range(count[p]):
        nx, ny = planes[p, k, 0], planes[p, k, 1]
        num = planes[p, k, 2] - shrink - (nx * ax + ny * ay)   # inside: t * den < num
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


@numba.njit(cache=True)
def shadow_halfplanes(mx, my, planes, shrunk, count, p, shrink, out):
    """Half-planes ``a x + b y + c < 0`` whose intersection is the shadow of piece ``p`` from a marker.

    The shadow is the set of points whose segment to the marker (mx, my) enters the piece's
    interior shrunk by ``shrink``: the open cone from the marker over the silhouette, on the
    inner side of every edge turned to the marker. ``out`` has shape (>= count[p] + 2, 3).

    Returns the number of rows written; -1 when the marker is inside the shrunk piece or on
    its boundary (it is hidden from everywhere). Callers skip pieces that do not ``block``.
    """
    n = count[p]
    nrow = 0
    first = -1
    last = -1
    for k in range(n):
        nx, ny, c = planes[p, k, 0], planes[p, k, 1], planes[p, k, 2] - shrink
        if nx * mx + ny * my - c > 0.0:       # the marker sees edge k from outside
            out[nrow, 0], out[nrow, 1], out[nrow, 2] = nx, ny, -c
            nrow += 1
            k0 = (k + n - 1) % n
            if not (planes[p, k0, 0] * mx + planes[p, k0, 1] * my - (planes[p, k0, 2] - shrink) > 0.0):
                first = k                      # the facing chain starts at corner k ...
            k1 = (k + 1) % n
            if not (planes[p, k1, 0] * mx + planes[p, k1, 1] * my - (planes[p, k1, 2] - shrink) > 0.0):
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
