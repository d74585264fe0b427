"""The streamed parallelogram grid and the per-block points kernel give the full-array values."""

from __future__ import annotations

import numpy as np
import pytest

from planner.pef import kernels, pairs
from planner.pef.gridtiles import parallelogram_grid
from planner.pef.pointblocks import blocks_points_local
from planner.pef.result import grid_centres
from planner.pef.visibility import visible_grid, visible_points

REL, AB = 6.7e-5, 0.002


def _floor(seed: int, n_markers: int):
    """Build a 40 x 30 m floor with random boxes and markers on their faces and in the open."""
    rng = np.random.default_rng(seed)
    boxes = []
    for _ in range(12):
        c = rng.uniform([3, 3], [37, 27])
        h = rng.uniform([0.3, 0.3], [4.0, 2.0])
        boxes.append(np.array([c - h, [c[0] + h[0], c[1] - h[1]], c + h, [c[0] - h[0], c[1] + h[1]]]))
    boxes = np.array(boxes)
    mk = [b[0] + rng.uniform() * (b[1] - b[0]) for b in boxes]            # on a face
    mk += list(rng.uniform([0, 0], [40, 30], size=(n_markers - len(mk), 2)))
    mk += [[0.0, 15.0], [40.0, 0.0]]                                         # on the walls, a corner
    return boxes, np.array(mk, dtype=float)


@pytest.mark.parametrize("seed,max_range,res", [(0, 12.0, 0.25), (1, 60.0, 0.4), (2, 7.0, 0.13)])
def test_streamed_grid_equals_the_full_visibility_path(seed, max_range, res):
    boxes, mk = _floor(seed, 40)
    bounds = (0.0, 0.0, 40.0, 30.0)
    x, y = grid_centres((40.0, 30.0), res)
    vis, free = visible_grid(x, y, mk, boxes, max_range, bounds)
    subsets = np.array([(i, j) for i in range(len(mk)) for j in range(i + 1, len(mk))], dtype=np.int64)
    tau = np.empty((y.size, x.size))
    best = np.empty((y.size, x.size, 2), dtype=np.int64)
    kernels.best_subset_grid(x, y, mk[:, 0].copy(), mk[:, 1].copy(), vis, REL, AB, 0.0, kernels.PARALLELOGRAM,
                             subsets, 0.0, tau, best)
    tau2, best2, free2, _ = parallelogram_grid(x, y, mk, boxes, max_range, bounds, REL, AB)
    assert np.array_equal(free, free2)
    assert np.array_equal(best, best2)
    assert np.array_equal(tau, tau2)
    assert np.isfinite(tau).mean() > 0.2 and np.isinf(tau[free]).any()  # both kinds of cell compared


def test_points_kernel_on_seen_markers_equals_the_full_one():
    boxes, mk = _floor(3, 30)
    rng = np.random.default_rng(4)
    pts = rng.uniform([0, 0], [40, 30], size=(3000, 2))
    pts = pts[np.lexsort((pts[:, 0], np.floor(pts[:, 1])))]
    vis, _ = visible_points(pts, mk, boxes, 10.0, (0.0, 0.0, 40.0, 30.0))
    # any subset rows, in any order and orientation: the chosen row is kept as given
    subsets = np.array([(j, i) for i in range(len(mk)) for j in range(i + 1, len(mk))], dtype=np.int64)[::-1].copy()
    px, py = pts[:, 0].copy(), pts[:, 1].copy()
    nblk = -(-len(pts) // pairs.BLOCK)
    out = []
    for kern in (pairs.blocks_points, blocks_points_local):
        tau, best = np.empty(len(pts)), np.empty(2 * len(pts), dtype=np.int64)
        kern(0, nblk, px, py, mk[:, 0].copy(), mk[:, 1].copy(), vis.reshape(-1), REL, AB, subsets, pairs.MARGIN,
             tau, best)
        out.append((tau, best))
    assert np.array_equal(out[0][0], out[1][0])
    assert np.array_equal(out[0][1], out[1][1])
    assert np.isfinite(out[0][0]).mean() > 0.3


def _general_grid(pef, res):
    """Return PEF.grid's general path (full (M, ny, nx) visibility, the redundancy recursion)."""
    from planner.pef.result import PefResult
    from planner.pef.visibility import scenario_visible_grid

    x, y = grid_centres(pef.scenario.workspace.size, res, pef.scenario.workspace.origin)
    vis, free = scenario_visible_grid(pef.scenario, x, y)

    def evaluate(v):
        t, b = pef._kernel_grid(x, y, v.reshape(v.shape[0], y.size, x.size))
        return PefResult(tau=t.ravel(), best=b.reshape(y.size * x.size, pef.k))

    r = pef._redundant(evaluate, vis.reshape(vis.shape[0], -1))
    shape = (y.size, x.size)
    return r.tau.reshape(shape), r.best.reshape(*shape, 2), r.tau_plain.reshape(shape), free


@pytest.mark.parametrize("redundancy", [0, 1])
@pytest.mark.parametrize("flat", [False, True])
def test_streamed_grid_with_flat_markers_and_redundancy_equals_the_general_path(flat, redundancy):
    import dataclasses
    import math

    import scenarios
    from planner.pef.map import PEF

    boxes, mk = _floor(5, 24)
    rng = np.random.default_rng(6)
    text = ['name = "tiles"', "[workspace]", "size = [40.0, 30.0]"]
    for b in boxes:
        lo, hi = b.min(axis=0), b.max(axis=0)
        text += ["[[obstacles]]", f"center = [{(lo[0] + hi[0]) / 2}, {(lo[1] + hi[1]) / 2}]",
                 f"size = [{hi[0] - lo[0]}, {hi[1] - lo[1]}]"]
    for i, p in enumerate(mk):
        text += ["[[markers]]", f'id = "M{i}"', f"position = [{p[0]}, {p[1]}]"]
    text += ["[sensor]", "max_range = 14.0", "max_incidence_deg = 60.0",
             "[planning]", "eps_max = 0.05", f"redundancy = {redundancy}"]
    sc = scenarios.loads("\n".join(text), "tiles.toml")
    if flat:  # every other marker flat, facing a random way
        sc = dataclasses.replace(sc, markers=tuple(
            dataclasses.replace(m, kind=scenarios.MarkerKind.FLAT, facing=float(rng.uniform(-math.pi, math.pi)))
            if i % 2 else m for i, m in enumerate(sc.markers)))
    pef = PEF(sc)
    pm = pef.grid(0.2)
    tau, best, tau_plain, free = _general_grid(pef, 0.2)
    assert np.array_equal(pm.free, free)
    assert np.array_equal(pm.best, best)
    assert np.array_equal(pm.tau_plain, tau_plain)
    assert np.array_equal(pm.tau, tau)
    fin = np.isfinite(tau_plain)
    assert fin.mean() > 0.2
    if redundancy:  # blocking a marker matters somewhere, and makes some fixes impossible
        assert (pm.tau[fin] > tau_plain[fin]).any() and np.isinf(pm.tau[fin]).any()
