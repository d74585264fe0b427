"""The parallelogram block kernel (:mod:`planner.pef.pairs`): pair pruning, grid tiles, tau.

Pruning may not change a single choice: the pruned sweep is compared cell by cell with the
full sweep (``margin = inf`` keeps every pair) on whole grids, open and with obstacles, and a
deliberately wrong bound (``margin = 0.5`` drops pairs that are up to twice better than a
tile's bound) must change them (negative control: the pruning is live). Independently, every
cell's tau is checked against a float64 brute force over all visible pairs.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

import scenarios
from estimators.fault.linearized import parallelogram
from planner.pef import pairs as pef_pairs
from planner.pef.map import PEF
from planner.pef.result import grid_centres
from planner.pef.scalar import diagonal_of_offsets
from planner.pef.visibility import scenario_visible_grid

REL, AB = 6.7e-5, 0.002


def floor_scenario(n_boxes, seed=3, size=(40.0, 30.0), n_markers=12):
    """Markers on the four walls of a floor, ``n_boxes`` random boxes off the walls."""
    rng = np.random.default_rng(seed)
    w, h = size
    pos = [(rng.uniform(2, w - 2), 0.0) for _ in range(n_markers // 4)] + \
          [(rng.uniform(2, w - 2), h) for _ in range(n_markers // 4)] + \
          [(0.0, rng.uniform(2, h - 2)) for _ in range(n_markers // 4)] + \
          [(w, rng.uniform(2, h - 2)) for _ in range(n_markers - 3 * (n_markers // 4))]
    boxes = [{"center": [float(rng.uniform(5, w - 5)), float(rng.uniform(5, h - 5))],
              "size": [float(rng.uniform(1, 4)), float(rng.uniform(0.5, 2))],
              "yaw_deg": float(rng.uniform(0, 180))} for _ in range(n_boxes)]
    return scenarios.from_dict({
        "name": "pairs", "workspace": {"size": list(size)}, "obstacles": boxes,
        "markers": [{"id": f"M{i}", "position": [float(x), float(y)]} for i, (x, y) in enumerate(pos)],
        "sensor": {"relative_error": REL, "absolute_error": AB, "max_range": 100.0, "markers_per_fix": 2},
        "planning": {"eps_max": 0.03, "pef_model": "parallelogram", "resolution": 0.2},
    }, "test")


def grid_inputs(sc, resolution):
    x, y = grid_centres(sc.workspace.size, resolution)
    vis, _ = scenario_visible_grid(sc, x, y)
    mk = sc.marker_positions()
    subsets = np.array(list(itertools.combinations(range(len(mk)), 2)), dtype=np.int64)
    return x, y, np.ascontiguousarray(mk[:, 0]), np.ascontiguousarray(mk[:, 1]), np.ascontiguousarray(vis), subsets


def run_grid(x, y, mx, my, vis, subsets, margin):
    tau, best = np.empty((y.size, x.size)), np.empty((y.size, x.size, 2), dtype=np.int64)
    pef_pairs.blocks_grid(0, pef_pairs.tile_count(x.size, y.size), x, y, mx, my, vis.reshape(-1), REL, AB,
                          subsets, margin, tau.reshape(-1), best.reshape(-1))
    return tau, best


def run_points(x, y, mx, my, vis, subsets, margin):
    px, py = np.tile(x, y.size), np.repeat(y, x.size)
    tau, best = np.empty(px.size), np.empty((px.size, 2), dtype=np.int64)
    nblk = -(-px.size // pef_pairs.BLOCK)
    pef_pairs.blocks_points(0, nblk, px, py, mx, my, vis.reshape(-1), REL, AB, subsets, margin, tau,
                            best.reshape(-1))
    return tau.reshape(y.size, x.size), best.reshape(y.size, x.size, 2)


@pytest.mark.parametrize("n_boxes", [0, 8])
def test_pruned_sweep_chooses_what_the_full_sweep_chooses(n_boxes):
    inputs = grid_inputs(floor_scenario(n_boxes), 0.2)  # 200 x 150 cells, 66 pairs
    full_tau, full_best = run_grid(*inputs, margin=math.inf)
    for run in (run_grid, run_points):
        tau, best = run(*inputs, margin=pef_pairs.MARGIN)
        assert np.array_equal(best, full_best)
        assert np.array_equal(tau, full_tau)
    # Negative control: a bound without its slack, shrunk to half, drops winning pairs.
    tau, best = run_grid(*inputs, margin=0.5)
    assert np.sum(np.any(best != full_best, axis=-1)) > 100
    assert np.all(tau >= full_tau * (1 - 1e-6))  # never better than the full sweep (float32 ties aside)


@pytest.mark.parametrize("shape", [(23, 37), (1, 40), (17, 1), (1, 1), (16, 16), (33, 17)])
def test_tiles_cover_any_grid_shape(shape):
    sc = floor_scenario(4, seed=5)
    ny, nx = shape
    x = np.linspace(0.3, 39.7, nx)
    y = np.linspace(0.3, 29.7, ny)
    vis, _ = scenario_visible_grid(sc, x, y)
    _, _, mx, my, _, subsets = grid_inputs(sc, 1.0)
    inputs = (x, y, mx, my, np.ascontiguousarray(vis), subsets)
    tau, best = run_grid(*inputs, margin=pef_pairs.MARGIN)
    ref_tau, ref_best = run_points(*inputs, margin=math.inf)
    assert np.array_equal(best, ref_best)
    assert np.array_equal(tau, ref_tau)


def brute_force_tau(px, py, mx, my, vis, rel, ab):
    """Smallest long diagonal over all visible pairs, float64 numpy (inf where none)."""
    dx, dy = px[None] - mx[:, None], py[None] - my[:, None]
    r = np.hypot(dx, dy)
    ux, uy, rho = dx / r, dy / r, rel * r + ab
    best = np.full(px.shape, np.inf)
    for i, j in itertools.combinations(range(mx.size), 2):
        s = np.abs(ux[i] * uy[j] - uy[i] * ux[j])
        c = np.abs(ux[i] * ux[j] + uy[i] * uy[j])
        with np.errstate(divide="ignore"):
            d = 2 / s * np.sqrt(rho[i] ** 2 + rho[j] ** 2 + 2 * rho[i] * rho[j] * c)
        best = np.minimum(best, np.where(vis[i] & vis[j] & (s > 0), d, np.inf))
    return best


def test_grid_tau_is_within_1e6_of_the_float64_minimum():
    sc = floor_scenario(8, seed=11)
    pm = PEF(sc).grid(0.25)
    x, y, mx, my, vis, _ = grid_inputs(sc, 0.25)
    xx, yy = np.meshgrid(x, y)
    ref = brute_force_tau(xx.ravel(), yy.ravel(), mx, my, vis.reshape(vis.shape[0], -1), REL, AB)
    ref = ref.reshape(pm.tau.shape)
    fin = np.isfinite(ref)
    assert np.array_equal(fin, np.isfinite(pm.tau))
    # Ranking in float32 (documented): the chosen pair is within ~1e-6 of the best one.
    assert np.all(np.abs(pm.tau[fin] / ref[fin] - 1) < 1e-6)
    assert np.all(pm.tau[fin] >= ref[fin] * (1 - 1e-14))  # never below the true minimum


def test_diagonal_of_offsets_matches_the_unit_vector_formula():
    rng = np.random.default_rng(7)
    d1, d2 = rng.uniform(-30, 30, (500, 2)), rng.uniform(-30, 30, (500, 2))
    r1, r2 = np.hypot(*d1.T), np.hypot(*d2.T)
    _, ref = parallelogram(d1 / r1[:, None], d2 / r2[:, None], REL * r1 + AB, REL * r2 + AB)
    got = np.array([diagonal_of_offsets(a[0], a[1], b[0], b[1], REL, AB) for a, b in zip(d1, d2, strict=True)])
    np.testing.assert_allclose(got, ref, rtol=1e-12)
    assert diagonal_of_offsets(0.0, 0.0, 3.0, 4.0, REL, AB) == math.inf  # on a marker
    assert diagonal_of_offsets(1.0, 2.0, -2.0, -4.0, REL, AB) == math.inf  # collinear
