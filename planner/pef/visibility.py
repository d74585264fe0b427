"""Which markers can be measured from which points: range limit and line of sight.

A marker is visible from a point when the point is in free space (inside the closed
workspace rectangle and not inside any box obstacle, boundary included), the range is at most
``max_range`` and the segment point-marker does not cross the *interior* of any box.

Markers sit on the walls or on obstacle faces. To let a marker on a face be seen from the open
side but not through its own box, line of sight is tested against every box *shrunk* by
:data:`BOX_SHRINK` (1 micrometre) on each side: a segment that ends on a face (or grazes an
edge) does not enter the shrunk box, one that passes through the box does. Free space uses
the boxes at full size.

Two paths give the same answer (a test checks it):

- :func:`visible_points`: arbitrary points, a segment/box clip (Liang-Barsky in the box frame)
  for every point, marker and box; O(N M B).
- :func:`visible_grid`: cell centres of a regular grid. The *shadow* of a box seen from a
  marker (the points whose segment to the marker enters the box) is a convex region: the
  cone from the marker over the box's silhouette, beyond the faces turned to the marker. It
  is an intersection of half-planes, so each grid row meets it in one interval, which is
  cleared in one sweep; cost O(M B ny) plus the cells cleared.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from planner.pef.threads import run_ranges
from scenarios.schema import Scenario

#: Boxes are shrunk by this much on each side for line-of-sight tests [m].
BOX_SHRINK = 1e-6


def box_params(corners: np.ndarray) -> np.ndarray:
    """Centre, axis and half-sizes of boxes given by their corners.

    Parameters
    ----------
    corners : ndarray, shape (B, 4, 2)
        Box corners, counter-clockwise [m] (``Scenario.obstacle_corners()``).

    Returns
    -------
    ndarray, shape (B, 6)
        Rows ``(cx, cy, ex, ey, hx, hy)``: centre [m], unit vector along the first edge, and
        half-lengths along that edge and across it [m].
    """
    c = np.asarray(corners, float).reshape(-1, 4, 2)
    centre = c.mean(axis=1)
    e1 = c[:, 1] - c[:, 0]
    e2 = c[:, 3] - c[:, 0]
    l1 = np.hypot(e1[:, 0], e1[:, 1])
    l2 = np.hypot(e2[:, 0], e2[:, 1])
    axis = e1 / np.where(l1 > 0, l1, 1.0)[:, None]
    return np.column_stack([centre, axis, l1 / 2.0, l2 / 2.0])


@numba.njit(cache=True)
def _local(px, py, box):
    dx, dy = px - box[0], py - box[1]
    return dx * box[2] + dy * box[3], -dx * box[3] + dy * box[2]


@numba.njit(cache=True)
def _is_free(px, py, width, height, boxes):
    if px < 0.0 or px > width or py < 0.0 or py > height:
        return False
    for b in range(boxes.shape[0]):
        lx, ly = _local(px, py, boxes[b])
        if abs(lx) <= boxes[b, 4] and abs(ly) <= boxes[b, 5]:
            return False
    return True


@numba.njit(cache=True)
def _clip(p0, d, h, t0, t1):
    """Clip the parameter interval [t0, t1] of ``p0 + t d`` to the slab ``|p| < h``."""
    if d == 0.0:
        if abs(p0) >= h:
            return 1.0, 0.0
        return t0, t1
    ta, tb = (-h - p0) / d, (h - p0) / d
    if ta > tb:
        ta, tb = tb, ta
    return max(t0, ta), min(t1, tb)


@numba.njit(cache=True)
def _segment_enters_box(ax, ay, bx, by, box, shrink):
    """Tell whether the segment a-b meets the open interior of ``box`` shrunk by ``shrink``."""
    hx, hy = box[4] - shrink, box[5] - shrink
    if hx <= 0.0 or hy <= 0.0:
        return False
    p0x, p0y = _local(ax, ay, box)
    p1x, p1y = _local(bx, by, box)
    t0, t1 = _clip(p0x, p1x - p0x, hx, 0.0, 1.0)
    if t0 >= t1:
        return False
    t0, t1 = _clip(p0y, p1y - p0y, hy, t0, t1)
    return t0 < t1


@numba.njit(cache=True, nogil=True)
def _visible_points_range(lo, hi, px, py, mx, my, max_range, width, height, boxes, shrink, vis, free):
    r2max = max_range * max_range
    for n in range(lo, hi):
        f = _is_free(px[n], py[n], width, height, boxes)
        free[n] = f
        for m in range(mx.size):
            ok = f
            if ok:
                dx, dy = px[n] - mx[m], py[n] - my[m]
                ok = dx * dx + dy * dy <= r2max
            if ok:
                for b in range(boxes.shape[0]):
                    if _segment_enters_box(px[n], py[n], mx[m], my[m], boxes[b], shrink):
                        ok = False
                        break
            vis[m, n] = ok


def visible_points(points: np.ndarray, markers: np.ndarray, corners: np.ndarray, max_range: float,
                   workspace_size: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Visibility of markers from arbitrary points.

    Parameters
    ----------
    points : ndarray, shape (N, 2)
        Query points [m].
    markers : ndarray, shape (M, 2)
        Marker positions [m].
    corners : ndarray, shape (B, 4, 2)
        Box obstacle corners [m].
    max_range : float
        Sensor range limit [m] (inclusive).
    workspace_size : (float, float)
        Width and height of the workspace [m]; points outside it are not free.

    Returns
    -------
    vis : ndarray of bool, shape (M, N)
        ``vis[m, n]``: marker m visible from point n (marker-major, the layout the PEF kernels
        read; transpose for (N, M)). False wherever the point is not free.
    free : ndarray of bool, shape (N,)
        Point in free space.
    """
    p = np.ascontiguousarray(np.asarray(points, float).reshape(-1, 2))
    mk = np.asarray(markers, float).reshape(-1, 2)
    boxes = np.ascontiguousarray(box_params(corners))
    vis = np.empty((mk.shape[0], p.shape[0]), dtype=np.bool_)
    free = np.empty(p.shape[0], dtype=np.bool_)
    run_ranges(_visible_points_range, p.shape[0],
               (np.ascontiguousarray(p[:, 0]), np.ascontiguousarray(p[:, 1]),
                np.ascontiguousarray(mk[:, 0]), np.ascontiguousarray(mk[:, 1]), float(max_range),
                float(workspace_size[0]), float(workspace_size[1]), boxes, BOX_SHRINK, vis, free),
               min_chunk=2048)
    return vis, free


# --- grid path ------------------------------------------------------------------------------

@numba.njit(cache=True)
def _shadow_halfplanes(mx, my, box, shrink, out):
    """Half-planes ``a x + b y + c < 0`` whose intersection is the shadow of ``box``.

    Returns the number of rows written to ``out`` (shape (6, 3)); -1 when the marker is inside
    the shrunk box (it is hidden from everywhere); 0 when the shrunk box is empty.
    """
    hx, hy = box[4] - shrink, box[5] - shrink
    if hx <= 0.0 or hy <= 0.0:
        return 0
    lx, ly = _local(mx, my, box)
    if abs(lx) < hx and abs(ly) < hy:
        return -1
    ex, ey = box[2], box[3]
    cx = np.empty(4)
    cy = np.empty(4)
    for k in range(4):
        sx = -1.0 if k == 0 or k == 3 else 1.0  # corners counter-clockwise from (-, -)
        sy = -1.0 if k < 2 else 1.0
        cx[k] = box[0] + sx * hx * ex - sy * hy * ey
        cy[k] = box[1] + sx * hx * ey + sy * hy * ex
    facing = np.zeros(4, dtype=np.bool_)
    nrow = 0
    for k in range(4):
        k1 = (k + 1) % 4
        nx, ny = cy[k1] - cy[k], -(cx[k1] - cx[k])  # outward normal of a CCW edge
        if nx * (mx - cx[k]) + ny * (my - cy[k]) > 0.0:
            facing[k] = True
            out[nrow, 0], out[nrow, 1] = nx, ny
            out[nrow, 2] = -(nx * cx[k] + ny * cy[k])
            nrow += 1
    # The facing edges form one chain, clockwise as seen from the marker, from a to b.
    a = -1
    b = -1
    for k in range(4):
        if facing[k] and not facing[(k + 3) % 4]:
            a = k
        if facing[k] and not facing[(k + 1) % 4]:
            b = (k + 1) % 4
    if a < 0:
        return -1  # on the boundary of the shrunk box: treat as inside
    ax, ay = cx[a] - mx, cy[a] - my  # cross(A, p - m) < 0
    out[nrow, 0], out[nrow, 1], out[nrow, 2] = -ay, ax, ay * mx - ax * my
    nrow += 1
    bx, by = cx[b] - mx, cy[b] - my  # cross(B, p - m) > 0
    out[nrow, 0], out[nrow, 1], out[nrow, 2] = by, -bx, -(by * mx - bx * my)
    nrow += 1
    return nrow


@numba.njit(cache=True)
def _first_above(x, v):
    """Smallest index i with x[i] > v (x ascending, uniform); x.size if none."""
    n = x.size
    if n == 1:
        return 0 if x[0] > v else 1
    i = int(math.floor((v - x[0]) / (x[1] - x[0]))) + 1
    if i < 0:
        i = 0
    if i > n:
        i = n
    while i < n and x[i] <= v:
        i += 1
    while i > 0 and x[i - 1] > v:
        i -= 1
    return i


@numba.njit(cache=True)
def _first_at_or_above(x, v):
    """Smallest index i with x[i] >= v (x ascending, uniform); x.size if none."""
    n = x.size
    if n == 1:
        return 0 if x[0] >= v else 1
    i = int(math.ceil((v - x[0]) / (x[1] - x[0])))
    if i < 0:
        i = 0
    if i > n:
        i = n
    while i < n and x[i] < v:
        i += 1
    while i > 0 and x[i - 1] >= v:
        i -= 1
    return i


@numba.njit(cache=True)
def _free_grid_kernel(x, y, width, height, boxes, free):
    for iy in range(y.size):
        for ix in range(x.size):
            free[iy, ix] = 0.0 <= x[ix] <= width and 0.0 <= y[iy] <= height
    for b in range(boxes.shape[0]):
        # Bounding rectangle of the box, then the exact test used by the points path.
        rx = abs(boxes[b, 4] * boxes[b, 2]) + abs(boxes[b, 5] * boxes[b, 3])
        ry = abs(boxes[b, 4] * boxes[b, 3]) + abs(boxes[b, 5] * boxes[b, 2])
        i0 = max(_first_at_or_above(x, boxes[b, 0] - rx) - 1, 0)
        i1 = min(_first_above(x, boxes[b, 0] + rx) + 1, x.size)
        j0 = max(_first_at_or_above(y, boxes[b, 1] - ry) - 1, 0)
        j1 = min(_first_above(y, boxes[b, 1] + ry) + 1, y.size)
        for iy in range(j0, j1):
            for ix in range(i0, i1):
                lx, ly = _local(x[ix], y[iy], boxes[b])
                if abs(lx) <= boxes[b, 4] and abs(ly) <= boxes[b, 5]:
                    free[iy, ix] = False


@numba.njit(cache=True)
def _visible_grid_marker(m, x, y, mx, my, max_range, boxes, shrink, free, vis):
    """Fill ``vis[m]``: in range and free, then clear each box's shadow row by row."""
    r2max = max_range * max_range
    nb = boxes.shape[0]
    hp = np.empty((nb, 6, 3))
    nhp = np.empty(nb, dtype=np.int64)
    hidden = False
    for b in range(nb):
        nhp[b] = _shadow_halfplanes(mx[m], my[m], boxes[b], shrink, hp[b])
        if nhp[b] < 0:
            hidden = True
    for iy in range(y.size):
        yy = y[iy]
        dy = yy - my[m]
        for ix in range(x.size):
            dx = x[ix] - mx[m]
            vis[m, iy, ix] = free[iy, ix] and (dx * dx + dy * dy <= r2max) and not hidden
        if hidden:
            continue
        for b in range(nb):
            if nhp[b] <= 0:
                continue
            lo, hi = -np.inf, np.inf
            empty = False
            for h in range(nhp[b]):
                a, bb, c = hp[b, h, 0], hp[b, h, 1], hp[b, h, 2]
                rhs = -(bb * yy + c)  # a x < rhs
                if a > 0.0:
                    lo_hi = rhs / a
                    if lo_hi < hi:
                        hi = lo_hi
                elif a < 0.0:
                    v = rhs / a
                    if v > lo:
                        lo = v
                elif rhs <= 0.0:
                    empty = True
                    break
            if empty or not lo < hi:
                continue
            i0 = _first_above(x, lo)
            i1 = _first_at_or_above(x, hi)
            for ix in range(i0, i1):
                vis[m, iy, ix] = False


@numba.njit(cache=True, nogil=True)
def _visible_grid_markers(m0, m1, x, y, mx, my, max_range, boxes, shrink, free, vis):
    for m in range(m0, m1):
        _visible_grid_marker(m, x, y, mx, my, max_range, boxes, shrink, free, vis)


def visible_grid(x: np.ndarray, y: np.ndarray, markers: np.ndarray, corners: np.ndarray,
                 max_range: float, workspace_size: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Visibility of markers from the cell centres of a regular grid.

    Parameters
    ----------
    x : ndarray, shape (nx,)
        Cell-centre x coordinates, ascending and uniformly spaced [m].
    y : ndarray, shape (ny,)
        Cell-centre y coordinates, ascending and uniformly spaced [m].
    markers, corners, max_range, workspace_size
        As in :func:`visible_points`.

    Returns
    -------
    vis : ndarray of bool, shape (M, ny, nx)
        ``vis[m, iy, ix]``: marker m visible from cell (iy, ix); False where not free.
    free : ndarray of bool, shape (ny, nx)
        Cell centre in free space.
    """
    x = np.ascontiguousarray(x, dtype=float)
    y = np.ascontiguousarray(y, dtype=float)
    mk = np.asarray(markers, float).reshape(-1, 2)
    boxes = np.ascontiguousarray(box_params(corners))
    free = np.empty((y.size, x.size), dtype=np.bool_)
    _free_grid_kernel(x, y, float(workspace_size[0]), float(workspace_size[1]), boxes, free)
    vis = np.empty((mk.shape[0], y.size, x.size), dtype=np.bool_)
    run_ranges(_visible_grid_markers, mk.shape[0],
               (x, y, np.ascontiguousarray(mk[:, 0]), np.ascontiguousarray(mk[:, 1]), float(max_range),
                boxes, BOX_SHRINK, free, vis))
    return vis, free


def scenario_visible_points(scenario: Scenario, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`visible_points` for a scenario's markers, obstacles and declared sensor range.

    Returns ``vis`` (M, N) and ``free`` (N,).
    """
    return visible_points(points, scenario.marker_positions(), scenario.obstacle_corners(),
                          scenario.sensor.max_range, scenario.workspace.size)


def scenario_visible_grid(scenario: Scenario, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`visible_grid` for a scenario's markers, obstacles and declared sensor range.

    Returns ``vis`` (M, ny, nx) and ``free`` (ny, nx).
    """
    return visible_grid(x, y, scenario.marker_positions(), scenario.obstacle_corners(),
                        scenario.sensor.max_range, scenario.workspace.size)
