"""Free-space route search on the PEF grid: 8-connected A* with true √2 diagonals.

The robot may occupy a cell when its centre is at least the robot radius (plus a cell's
half-diagonal, so the whole cell is safe) from every obstacle and wall, and τ < ε_max there.
Moving between neighbouring cells u, v costs ``step · (c_u + c_v) / 2`` with ``step`` the
cell width, height or diagonal (``h·√2`` on a square grid) and the cell cost
``c = 1 + w · τ / ε_max``: on top of length, a route pays up to
``w`` times its length for running close to the edge of the navigation region. A diagonal
move needs both cells beside it free, so paths never cut an obstacle's corner.

The search is a 4-ary-heap A* compiled with numba; its octile heuristic times the least
cell cost is consistent, so the result is the exact grid optimum (tests compare it with
:func:`scipy.sparse.csgraph.dijkstra`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from jit import compiled

SQRT2 = math.sqrt(2.0)


@dataclass(frozen=True)
class Grid:
    """A regular grid of cell centres.

    Attributes
    ----------
    x : ndarray, shape (nx,)
        Cell-centre x [m], increasing, uniform spacing (at least two cells).
    y : ndarray, shape (ny,)
        Cell-centre y [m], increasing, uniform spacing (may differ from x's).
    """

    x: np.ndarray
    y: np.ndarray

    def __post_init__(self) -> None:
        if len(self.x) < 2 or len(self.y) < 2:
            raise ValueError(f"grid needs at least 2 x 2 cells, got {len(self.x)} x {len(self.y)}")

    @property
    def hx(self) -> float:
        """Cell width [m]."""
        return float(self.x[1] - self.x[0])

    @property
    def hy(self) -> float:
        """Cell height [m]."""
        return float(self.y[1] - self.y[0])

    @property
    def shape(self) -> tuple[int, int]:
        return len(self.y), len(self.x)

    def centres(self) -> np.ndarray:
        """All cell centres, shape (ny, nx, 2) [m]."""
        xx, yy = np.meshgrid(self.x, self.y)
        return np.stack([xx, yy], axis=-1)

    def cell_of(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Nearest cell (row, col) of each point and whether the point lies on the grid.

        Parameters
        ----------
        points : ndarray, shape (N, 2)

        Returns
        -------
        row, col : ndarray of int, shape (N,)
            Clipped to the grid.
        inside : ndarray of bool, shape (N,)
        """
        p = np.asarray(points, float).reshape(-1, 2)
        c = np.rint((p[:, 0] - self.x[0]) / self.hx).astype(np.int64)
        r = np.rint((p[:, 1] - self.y[0]) / self.hy).astype(np.int64)
        ny, nx = self.shape
        inside = (c >= 0) & (c < nx) & (r >= 0) & (r < ny)
        return np.clip(r, 0, ny - 1), np.clip(c, 0, nx - 1), inside

    def lookup(self, mask: np.ndarray, points: np.ndarray) -> np.ndarray:
        """``mask`` at the nearest cell of each point (False off the grid), shape (N,)."""
        r, c, inside = self.cell_of(points)
        return inside & mask[r, c]


def conservative_tau(tau: np.ndarray) -> np.ndarray:
    """τ grid replaced by its 3×3 maximum, shape (ny, nx).

    A straight move between neighbouring cells, and any point whose nearest cell is a given
    one, stays inside that cell's 3×3 block; using the block maximum keeps grid decisions on
    the safe side of the τ < ε_max boundary.
    """
    from scipy import ndimage  # here: its import costs 0.3 s, and a route network never gets here

    t = np.where(np.isfinite(tau), tau, np.inf)
    return ndimage.maximum_filter(t, size=3, mode="nearest")


@compiled.njit(cache=True)
def _heap_push(fk, nd, i, f, node):
    # 4-ary min-heap on key fk; i is the current size (the new slot).
    while i > 0:
        p = (i - 1) >> 2
        if fk[p] <= f:
            break
        fk[i] = fk[p]
        nd[i] = nd[p]
        i = p
    fk[i] = f
    nd[i] = node


@compiled.njit(cache=True)
def _heap_pop(fk, nd, size):
    node = nd[0]
    size -= 1
    f = fk[size]
    x = nd[size]
    i = 0
    while True:
        c = 4 * i + 1
        if c >= size:
            break
        best = c
        bf = fk[c]
        for j in range(c + 1, min(c + 4, size)):
            if fk[j] < bf:
                bf = fk[j]
                best = j
        if bf >= f:
            break
        fk[i] = bf
        nd[i] = nd[best]
        i = best
    fk[i] = f
    nd[i] = x
    return node


@compiled.njit(cache=True)
def _astar(cost, allowed, sr, sc, gr, gc, hx, hy, cmin):
    # Flat indices on a grid padded by one blocked cell, so neighbours need no bounds checks.
    # state: 0 blocked, 1 open, 2 closed (one byte array keeps the hot loop in cache).
    ny, nx = cost.shape
    wd = nx + 2
    n = (ny + 2) * wd
    state = np.zeros(n, np.uint8)
    cf = np.zeros(n)
    for r in range(ny):
        for c in range(nx):
            q = (r + 1) * wd + c + 1
            state[q] = allowed[r, c]
            cf[q] = cost[r, c]
    g = np.full(n, np.inf)
    parent = np.empty(n, np.int32)
    cap = 1 << 16
    fk = np.empty(cap)
    nd = np.empty(cap, np.int32)
    off = np.array([-wd, wd, -1, 1, -wd - 1, -wd + 1, wd - 1, wd + 1])
    side_r = np.array([0, 0, 0, 0, -wd, -wd, wd, wd])
    side_c = np.array([0, 0, 0, 0, -1, 1, -1, 1])
    # Step lengths by move (N, S, W, E, diagonals) and the octile heuristic on an
    # anisotropic grid: min(dr, dc) diagonals plus the rest straight, times the least cost.
    hd = math.hypot(hx, hy)
    steps = np.array([hy, hy, hx, hx, hd, hd, hd, hd])
    start = (sr + 1) * wd + sc + 1
    goal = (gr + 1) * wd + gc + 1
    gr1, gc1 = gr + 1, gc + 1
    g[start] = 0.0
    _heap_push(fk, nd, 0, 0.0, start)
    size = 1
    expanded = 0
    while size > 0:
        u = _heap_pop(fk, nd, size)
        size -= 1
        if state[u] != 1:
            continue
        state[u] = 2
        expanded += 1
        if u == goal:
            break
        gu = g[u]
        cu = cf[u]
        for k in range(8):
            v = u + off[k]
            if state[v] != 1:
                continue
            if k >= 4 and (state[u + side_c[k]] == 0 or state[u + side_r[k]] == 0):
                continue
            ng = gu + steps[k] * 0.5 * (cu + cf[v])
            if ng < g[v]:
                g[v] = ng
                parent[v] = u
                vr = v // wd
                ar = abs(vr - gr1)
                ac = abs(v - vr * wd - gc1)
                hv = cmin * (hd * min(ar, ac) + hy * (ar - min(ar, ac)) + hx * (ac - min(ar, ac)))
                if size == cap:
                    cap *= 2
                    fk2 = np.empty(cap)
                    nd2 = np.empty(cap, np.int32)
                    fk2[:size] = fk[:size]
                    nd2[:size] = nd[:size]
                    fk, nd = fk2, nd2
                _heap_push(fk, nd, size, ng + hv, v)
                size += 1
    if not np.isfinite(g[goal]):
        return np.inf, np.empty(0, np.int64), expanded
    m = 1
    v = goal
    while v != start:
        v = parent[v]
        m += 1
    path = np.empty(m, np.int64)
    v = goal
    for i in range(m - 1, -1, -1):
        path[i] = (v // wd - 1) * nx + (v % wd - 1)
        v = parent[v]
    return g[goal], path, expanded


@dataclass(frozen=True)
class GridPath:
    """One grid search result.

    Attributes
    ----------
    cells : ndarray of int, shape (n, 2)
        (row, col) from start to goal.
    points : ndarray, shape (n, 2)
        Cell centres [m].
    cost : float
        Search cost (length-weighted cell cost, see module docstring) [m].
    expanded : int
        Nodes expanded by A*.
    """

    cells: np.ndarray
    points: np.ndarray
    cost: float
    expanded: int


def grid_astar(grid: Grid, cost: np.ndarray, allowed: np.ndarray, start: tuple[int, int],
               goal: tuple[int, int]) -> GridPath | None:
    """Cheapest 8-connected path between two cells, or None when the goal is unreachable.

    Parameters
    ----------
    grid : Grid
    cost : ndarray, shape (ny, nx)
        Cell cost factor (≥ some positive minimum over allowed cells) [-].
    allowed : ndarray of bool, shape (ny, nx)
        Cells the path may use.
    start, goal : tuple[int, int]
        (row, col); both must be allowed.

    Returns
    -------
    GridPath or None
    """
    allowed = np.ascontiguousarray(allowed, dtype=np.bool_)
    cost = np.ascontiguousarray(cost, dtype=np.float64)
    if not (allowed[start] and allowed[goal]):
        return None
    cmin = float(cost[allowed].min())
    if not cmin > 0:
        raise ValueError(f"cell costs must be positive on allowed cells, got minimum {cmin}")
    total, flat, expanded = _astar(cost, allowed, start[0], start[1], goal[0], goal[1],
                                   grid.hx, grid.hy, cmin)
    if not np.isfinite(total):
        return None
    cells = np.column_stack([flat // grid.shape[1], flat % grid.shape[1]])
    points = np.column_stack([grid.x[cells[:, 1]], grid.y[cells[:, 0]]])
    return GridPath(cells, points, float(total), int(expanded))


def cell_cost(tau: np.ndarray, eps_max: float, weight: float) -> np.ndarray:
    """Cell cost factor ``1 + weight · τ / ε_max``, shape (ny, nx) (inf where τ is)."""
    return 1.0 + weight * np.asarray(tau, float) / eps_max


def alternatives(grid: Grid, tau: np.ndarray, allowed: np.ndarray, eps_max: float,
                 start: tuple[int, int], goal: tuple[int, int], weight: float,
                 n_routes: int = 4, band: float = 1.5) -> list[tuple[str, GridPath]]:
    """Several diverse free-space routes.

    The sequence tried: the scenario's accuracy weight; pure length (w = 0); strong accuracy
    (w = 4·weight + 1); then the scenario's weight again with cells within ``band`` metres of
    every earlier route costing double, which pushes the search into other corridors. A route
    that runs mostly (80 %) within ``band``/2 of an earlier one is dropped as a duplicate.

    Parameters
    ----------
    grid : Grid
    tau : ndarray, shape (ny, nx)
        τ per cell [m] (use :func:`conservative_tau`).
    allowed : ndarray of bool, shape (ny, nx)
    eps_max : float
        [m]
    start, goal : tuple[int, int]
        (row, col).
    weight : float
        The scenario's accuracy weight.
    n_routes : int
        Largest number of routes returned.
    band : float
        Width of the penalised corridor around earlier routes [m].

    Returns
    -------
    list of (label, GridPath)
        The label says how the route was found, e.g. ``"w=1"`` or ``"w=1, avoid 2"``.
    """
    tau_ok = np.where(allowed, tau, 0.0)
    from scipy import ndimage

    tries: list[tuple[str, float, bool]] = [(f"w={weight:g}", weight, False), ("w=0", 0.0, False),
                                            (f"w={4 * weight + 1:g}", 4 * weight + 1, False)]
    tries += [(f"w={weight:g}, avoid", weight, True)] * max(0, n_routes - 1)
    found: list[tuple[str, GridPath]] = []
    near = np.zeros(grid.shape, bool)
    attempts = 0
    for label, w, avoid in tries:
        if len(found) >= n_routes or attempts >= n_routes + 3:
            break
        attempts += 1
        cost = cell_cost(tau_ok, eps_max, w)
        if avoid and found:
            dist = ndimage.distance_transform_edt(~near, sampling=(grid.hy, grid.hx))
            cost = cost * np.where(dist < band, 2.0, 1.0)
            label = f"{label} {len(found)}"
        res = grid_astar(grid, cost, allowed, start, goal)
        if res is None:
            return found
        if found:
            dist = ndimage.distance_transform_edt(~near, sampling=(grid.hy, grid.hx))
            if np.mean(dist[res.cells[:, 0], res.cells[:, 1]] < band / 2) > 0.8:
                continue
        found.append((label, res))
        near[res.cells[:, 0], res.cells[:, 1]] = True
    return found
