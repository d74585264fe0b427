"""Occupancy grid -> polygons, by tracing cell boundaries (fast for a 2000 x 2000 map).

Every corner of the boundary between obstacle and free cells is found with numpy; along a
grid line the boundary runs from one corner to the next corner on that line, so each
corner's successor is its neighbour in the corners sorted by row (or by column). The rings
are the cycles of that successor map: exteriors counter-clockwise, holes clockwise, all
disjoint, so assembling polygons only has to find each hole's smallest enclosing exterior.
"""

from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry import Polygon


def _fill_saddles(occ: np.ndarray) -> np.ndarray:
    """Make cells that touch only diagonally touch along an edge (obstacle side wins).

    A 2 x 2 window with obstacles on one diagonal and free cells on the other would make a
    boundary touch itself; the robot cannot pass such a zero-width gap anyway, so one free
    cell of the window becomes an obstacle (conservative), until no such window is left.
    """
    occ = occ.copy()
    while True:
        a, b = occ[:-1, :-1], occ[:-1, 1:]
        c, d = occ[1:, :-1], occ[1:, 1:]
        s1 = a & d & ~b & ~c   # obstacles on the main diagonal
        s2 = b & c & ~a & ~d   # obstacles on the anti-diagonal
        if not (s1.any() or s2.any()):
            return occ
        r, k = np.nonzero(s1)
        occ[r, k + 1] = True
        r, k = np.nonzero(s2)
        occ[r, k] = True


def trace(occ: np.ndarray) -> list[Polygon]:
    """Polygons covering the obstacle cells of a grid, in cell units.

    Parameters
    ----------
    occ : ndarray of bool, shape (H, W)
        Obstacle cells; row 0 is the bottom row (y up), cell (r, c) covers
        [c, c + 1] x [r, r + 1].

    Returns
    -------
    list of Polygon
        Disjoint polygons with holes (free cells enclosed by obstacles), vertices on the
        integer lattice, exteriors counter-clockwise.
    """
    occ = _fill_saddles(np.asarray(occ, dtype=bool))
    h, w = occ.shape
    p = np.zeros((h + 2, w + 2), dtype=bool)
    p[1:-1, 1:-1] = occ
    # The 2 x 2 cells around each lattice vertex (x, y), x in 0..W, y in 0..H.
    bl, br = p[:-1, :-1], p[:-1, 1:]
    tl, tr = p[1:, :-1], p[1:, 1:]
    n = bl.astype(np.int8) + br + tl + tr
    corner = (n == 1) | (n == 3)   # saddles are gone; n == 2 is a straight run
    ys, xs = np.nonzero(corner)
    if len(xs) == 0:
        return []
    c_bl, c_br, c_tl, c_tr = bl[ys, xs], br[ys, xs], tl[ys, xs], tr[ys, xs]
    one = n[ys, xs] == 1
    three = ~one
    # Outgoing direction with the obstacle on the left (exteriors run counter-clockwise),
    # 0 = +x, 1 = +y, 2 = -x, 3 = -y. One obstacle cell at the corner: lower-left -> -x,
    # lower-right -> -y, upper-right -> +x, upper-left -> +y. Three: by the free one,
    # lower-left -> -y, lower-right -> +x, upper-right -> +y, upper-left -> -x.
    dirs = np.empty(len(xs), dtype=np.int8)
    dirs[one & c_bl] = 2
    dirs[one & c_br] = 3
    dirs[one & c_tr] = 0
    dirs[one & c_tl] = 1
    dirs[three & ~c_bl] = 3
    dirs[three & ~c_br] = 0
    dirs[three & ~c_tr] = 1
    dirs[three & ~c_tl] = 2
    k = len(xs)
    succ = np.empty(k, dtype=np.int64)
    by_row = np.lexsort((xs, ys))      # corners along each horizontal grid line, left to right
    pos_row = np.empty(k, dtype=np.int64)
    pos_row[by_row] = np.arange(k)
    by_col = np.lexsort((ys, xs))      # along each vertical grid line, bottom to top
    pos_col = np.empty(k, dtype=np.int64)
    pos_col[by_col] = np.arange(k)
    i = np.arange(k)
    m = dirs == 0
    succ[m] = by_row[pos_row[i[m]] + 1]
    m = dirs == 2
    succ[m] = by_row[pos_row[i[m]] - 1]
    m = dirs == 1
    succ[m] = by_col[pos_col[i[m]] + 1]
    m = dirs == 3
    succ[m] = by_col[pos_col[i[m]] - 1]
    order, starts = _cycles(succ.tolist())
    x, y = xs[order].astype(float), ys[order].astype(float)
    # Shoelace per ring: each vertex pairs with the next one of its own ring.
    nxt = np.arange(1, len(order) + 1)
    ends = np.append(starts[1:], len(order))
    nxt[ends - 1] = starts
    area2 = np.add.reduceat(x * y[nxt] - y * x[nxt], starts)
    ring_id = np.repeat(np.arange(len(starts)), np.diff(np.append(starts, len(order))))
    rings = shapely.linearrings(np.column_stack([x, y]), indices=ring_id)
    return _assemble(rings, area2 > 0, np.column_stack([x[starts], y[starts]]))


def _cycles(succ: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Cycles of a permutation: the elements ring after ring, and where each ring starts."""
    seen = bytearray(len(succ))
    order: list[int] = []
    starts: list[int] = []
    for start in range(len(succ)):
        if seen[start]:
            continue
        starts.append(len(order))
        j = start
        while not seen[j]:
            seen[j] = 1
            order.append(j)
            j = succ[j]
    return np.array(order, dtype=np.int64), np.array(starts, dtype=np.int64)


def _assemble(rings: np.ndarray, is_shell: np.ndarray, first: np.ndarray) -> list[Polygon]:
    """Polygons from disjoint rings: each hole goes to its smallest enclosing shell.

    ``rings`` (n,) LinearRings, ``is_shell`` (n,) bool (counter-clockwise), ``first`` (n, 2)
    the first vertex of each ring.
    """
    shell_idx = np.flatnonzero(is_shell)
    hole_idx = np.flatnonzero(~is_shell)
    shells = shapely.polygons(rings[shell_idx])
    if len(hole_idx) == 0:
        return list(shells)
    # Rings are disjoint: a hole's first vertex lies strictly inside every shell that
    # encloses the hole; the smallest of them is the one it belongs to.
    tree = shapely.STRtree(shells)
    q_hole, q_shell = tree.query(shapely.points(first[hole_idx]), predicate="within")
    area = shapely.area(shells)
    # Sort candidate pairs by hole, then by shell area descending: the last pair per hole wins.
    o = np.lexsort((-area[q_shell], q_hole))
    owner = np.full(len(hole_idx), -1, dtype=np.int64)
    owner[q_hole[o]] = q_shell[o]
    keep = owner >= 0
    members = np.concatenate([shell_idx, hole_idx[keep]])
    target = np.concatenate([np.arange(len(shell_idx)), owner[keep]])
    o = np.argsort(target, kind="stable")  # shells come first within each target
    return list(shapely.polygons(rings[members[o]], indices=target[o]))
