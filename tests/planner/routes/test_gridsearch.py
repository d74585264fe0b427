"""Grid search against scipy's Dijkstra; smoothing: curvature bound, admissibility, speeds."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from planner.routes import gridsearch, smoothing
from scenarios.schema import RobotSpec


def random_world(seed: int, ny: int = 40, nx: int = 55, hx: float = 0.1, hy: float = 0.1):
    rng = np.random.default_rng(seed)
    grid = gridsearch.Grid(np.arange(nx) * hx + hx / 2, np.arange(ny) * hy + hy / 2)
    allowed = rng.random((ny, nx)) > 0.25
    tau = rng.uniform(0.0, 0.05, (ny, nx))
    return grid, allowed, tau


def scipy_cost(grid, cost, allowed, start, goal) -> float:
    """Independent optimum: the same 8-connected graph built edge by edge, solved by scipy."""
    ny, nx = allowed.shape
    rows, cols, w = [], [], []
    for r in range(ny):
        for c in range(nx):
            if not allowed[r, c]:
                continue
            for dr, dc in [(-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (-1, 1), (1, -1), (1, 1)]:
                rr, cc = r + dr, c + dc
                if not (0 <= rr < ny and 0 <= cc < nx and allowed[rr, cc]):
                    continue
                if dr and dc and not (allowed[r, cc] and allowed[rr, c]):
                    continue  # no corner cutting
                step = math.hypot(dr * grid.hy, dc * grid.hx)
                rows.append(r * nx + c)
                cols.append(rr * nx + cc)
                w.append(step * 0.5 * (cost[r, c] + cost[rr, cc]))
    m = coo_matrix((w, (rows, cols)), shape=(ny * nx, ny * nx)).tocsr()
    d = dijkstra(m, indices=start[0] * nx + start[1])
    return float(d[goal[0] * nx + goal[1]])


def path_cost(grid, cost, cells) -> float:
    tot = 0.0
    for (r0, c0), (r1, c1) in zip(cells[:-1], cells[1:], strict=False):
        tot += math.hypot((r1 - r0) * grid.hy, (c1 - c0) * grid.hx) * 0.5 * (cost[r0, c0] + cost[r1, c1])
    return tot


@pytest.mark.parametrize("seed,hx,hy,w", [(0, 0.1, 0.1, 1.0), (1, 0.1, 0.1, 0.0), (2, 0.1, 0.13, 3.0),
                                          (3, 0.2, 0.1, 1.0), (4, 0.05, 0.05, 10.0)])
def test_astar_cost_equals_scipy_dijkstra(seed, hx, hy, w):
    grid, allowed, tau = random_world(seed, hx=hx, hy=hy)
    cost = gridsearch.cell_cost(tau, 0.05, w)
    start, goal = (1, 1), (grid.shape[0] - 2, grid.shape[1] - 3)
    allowed[start] = allowed[goal] = True
    ref = scipy_cost(grid, cost, allowed, start, goal)
    res = gridsearch.grid_astar(grid, cost, allowed, start, goal)
    if not math.isfinite(ref):
        assert res is None
        return
    assert res.cost == pytest.approx(ref, rel=1e-12)
    cells = res.cells
    assert tuple(cells[0]) == start and tuple(cells[-1]) == goal
    steps = np.abs(np.diff(cells, axis=0))
    assert steps.max() == 1 and np.all(steps.sum(axis=1) >= 1)  # 8-connected moves
    assert allowed[cells[:, 0], cells[:, 1]].all()
    diag = (steps[:, 0] == 1) & (steps[:, 1] == 1)
    for (r0, c0), (r1, c1) in zip(cells[:-1][diag], cells[1:][diag], strict=False):
        assert allowed[r0, c1] and allowed[r1, c0]
    assert path_cost(grid, cost, cells) == pytest.approx(res.cost, rel=1e-12)
    np.testing.assert_allclose(res.points, np.column_stack([grid.x[cells[:, 1]], grid.y[cells[:, 0]]]))


def test_diagonal_moves_cost_sqrt2():
    grid = gridsearch.Grid(np.arange(30) * 0.1, np.arange(30) * 0.1)
    allowed = np.ones((30, 30), bool)
    cost = np.ones((30, 30))
    res = gridsearch.grid_astar(grid, cost, allowed, (0, 0), (20, 20))
    assert res.cost == pytest.approx(20 * 0.1 * math.sqrt(2), rel=1e-12) and len(res.cells) == 21
    res = gridsearch.grid_astar(grid, cost, allowed, (0, 0), (10, 25))
    assert res.cost == pytest.approx(0.1 * (10 * math.sqrt(2) + 15), rel=1e-12)


def test_never_enters_blocked_or_unreachable():
    grid = gridsearch.Grid(np.arange(20) * 0.1, np.arange(20) * 0.1)
    allowed = np.ones((20, 20), bool)
    allowed[:, 10] = False  # a wall with a one-cell diagonal-only gap is not a gap
    allowed[5, 10] = True
    allowed[5, 9] = allowed[5, 11] = False
    cost = np.ones((20, 20))
    assert gridsearch.grid_astar(grid, cost, allowed, (5, 2), (5, 18)) is None
    allowed[5, 9] = allowed[5, 11] = True
    res = gridsearch.grid_astar(grid, cost, allowed, (0, 2), (19, 18))
    assert res is not None and allowed[res.cells[:, 0], res.cells[:, 1]].all()
    assert [5, 10] in res.cells.tolist()


def test_conservative_tau_and_alternatives():
    grid, allowed, tau = random_world(7, ny=50, nx=80)
    tau = tau * 0.8  # 0 .. 0.04
    tau[5, 5] = 0.049  # one bad cell: its 3 x 3 block leaves the region below
    allowed = np.ones_like(allowed)
    allowed[10:40, 30:50] = False  # one block: routes above and below
    tc = gridsearch.conservative_tau(tau)
    assert np.all(tc >= tau) and np.all(tc[4:7, 4:7] == 0.049)
    nav = allowed & (tc < 0.045)
    assert not nav[4:7, 4:7].any()
    found = gridsearch.alternatives(grid, tc, nav, 0.05, (25, 2), (25, 77), weight=1.0, n_routes=4)
    assert 2 <= len(found) <= 4
    sides = set()
    for _, gp in found:
        assert nav[gp.cells[:, 0], gp.cells[:, 1]].all()
        sides.add(bool(np.mean(gp.cells[:, 0]) > 25))
    assert sides == {True, False}  # both corridors around the block are offered


# ------------------------------------------------------------------------------ smoothing


def disk_ok(centre, radius):
    c = np.asarray(centre, float)
    return lambda p: np.hypot(*(np.asarray(p) - c).T) >= radius


def estimated_curvature(points):
    """Heading change per metre between consecutive sample chords (independent of the arcs)."""
    d = np.diff(points, axis=0)
    d = d[np.hypot(*d.T) > 1e-12]
    turn = np.abs(np.arctan2(d[:-1, 0] * d[1:, 1] - d[:-1, 1] * d[1:, 0], (d[:-1] * d[1:]).sum(1)))
    ds = 0.5 * (np.hypot(*d[:-1].T) + np.hypot(*d[1:].T))
    return turn / ds


def test_round_corners_bounded_curvature_and_admissible():
    rng = np.random.default_rng(5)
    poly = np.cumsum(rng.uniform(-3, 3, (8, 2)), axis=0)
    ok = disk_ok(poly[3] + [0.6, 0.0], 0.3)  # an obstacle near one corner
    r_min, spacing = 0.25, 0.05
    sp = smoothing.round_corners(poly, ok, 1.0, r_min, spacing)
    assert ok(sp.points).all()
    assert np.all(np.diff(sp.s) <= spacing + 1e-9)
    assert np.all(sp.curvature <= 1 / r_min + 1e-12)
    # Between stops the sampled path's heading changes by at most spacing / r_min per sample.
    kappa = estimated_curvature(sp.points)
    stops = np.flatnonzero(sp.stop)
    near_stop = np.zeros(len(kappa), bool)
    for i in stops:
        near_stop[max(0, i - 2): i + 1] = True
    assert np.all(kappa[~near_stop] <= 1 / r_min * 1.05)
    # Ends and total turning are kept.
    np.testing.assert_allclose(sp.points[0], poly[0])
    np.testing.assert_allclose(sp.points[-1], poly[-1])


def test_round_corners_falls_back_to_sharp_corner():
    poly = np.array([[0, 0], [5, 0], [5, 5]], float)
    # Nothing off the legs is admissible: the corner stays sharp and is a stop.
    on_legs = lambda p: (np.abs(p[:, 1]) < 1e-9) | (np.abs(p[:, 0] - 5) < 1e-9)
    sp = smoothing.round_corners(poly, on_legs, 1.0, 0.25, 0.1)
    assert on_legs(sp.points).all()
    assert sp.stop.sum() == 1 and np.allclose(sp.points[sp.stop][0], [5, 0])
    assert sp.turn_in_place == pytest.approx(math.pi / 2)
    assert sp.length == pytest.approx(10.0)
    # With room, the corner becomes an arc of the preferred radius: the path is shorter by
    # 2 r - r pi / 2 and has no stop.
    sp = smoothing.round_corners(poly, lambda p: np.ones(len(p), bool), 1.0, 0.25, 0.01)
    assert not sp.stop.any()
    assert sp.length == pytest.approx(10.0 - 2.0 + math.pi / 2, abs=1e-3)


def test_shortcut_keeps_admissibility():
    grid = gridsearch.Grid(np.arange(60) * 0.1 + 0.05, np.arange(60) * 0.1 + 0.05)
    allowed = np.ones((60, 60), bool)
    allowed[0:40, 28:32] = False
    res = gridsearch.grid_astar(grid, np.ones((60, 60)), allowed, (2, 2), (2, 57))
    ok = lambda p: grid.lookup(allowed, p)
    short = smoothing.shortcut(res.points, ok, 0.05)
    assert len(short) < len(res.points) / 4
    pts = np.vstack([np.linspace(a, b, 50) for a, b in zip(short[:-1], short[1:], strict=False)])
    assert ok(pts).all()


def test_speed_profile_limits():
    robot = RobotSpec(max_speed=1.0, max_yaw_rate=1.5)
    poly = np.array([[0, 0], [6, 0], [6, 6], [0.5, 6.2]], float)
    # The second corner is forced sharp (no arcs admissible near it).
    ok = lambda p: np.hypot(p[:, 0] - 6, p[:, 1] - 6) > 2.0
    sp = smoothing.round_corners(poly, ok, 2.0, 0.25, 0.05)
    v = smoothing.speed_profile(sp, robot, max_accel=0.5)
    assert np.all(v <= 1.0 + 1e-12) and v[-1] == 0.0
    arc = sp.curvature > 0
    assert arc.any() and np.all(v[arc] <= 1.5 / sp.curvature[arc] + 1e-12)
    assert np.all(v[sp.stop] == 0.0) and sp.stop.sum() == 1
    dv2 = np.abs(np.diff(v ** 2))
    assert np.all(dv2 <= 2 * 0.5 * np.diff(sp.s) + 1e-9)
