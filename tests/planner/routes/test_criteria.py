"""Route criteria: geometry against shapely, time model, normalisation, choice, Pareto front."""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import pytest
import shapely

import scenarios
from planner.routes import criteria, ranking
from scenarios.schema import Obstacle, Weights


@pytest.fixture(scope="module")
def warehouse():
    return scenarios.load("warehouse")


def test_clearance_matches_shapely(warehouse):
    rng = np.random.default_rng(0)
    tilted = Obstacle((6.0, 3.0), (2.0, 1.0), 0.7)
    sc = dataclasses.replace(warehouse, obstacles=(*warehouse.obstacles, tilted))
    pts = rng.uniform([0, 0], [30, 20], (400, 2))
    got = criteria.clearance(pts, sc)
    walls = shapely.Polygon([(0, 0), (30, 0), (30, 20), (0, 20)]).exterior
    boxes = [shapely.Polygon(o.corners()) for o in sc.obstacles]
    for p, g in zip(pts, got, strict=True):
        pt = shapely.Point(p)
        signed = [b.exterior.distance(pt) * (-1 if b.contains(pt) else 1) for b in boxes]
        d = min([walls.distance(pt), *signed])
        assert g == pytest.approx(d, abs=1e-9)


def test_turning_length_traffic_sampling():
    square = np.array([[0, 0], [2, 0], [2, 1], [0, 1]], float)
    assert criteria.turning(square) == pytest.approx(math.pi)
    assert criteria.turning(np.array([[0, 0], [1, 0], [0, 0]], float)) == pytest.approx(math.pi)
    assert criteria.turning(np.array([[0, 0], [1, 0], [1, 0], [2, 0]], float)) == 0.0
    assert criteria.polyline_length(square) == pytest.approx(5.0)
    # Length-weighted: 2 m at 0.5, 1 m at 0.2, 2 m at 0 -> 1.2 / 5.
    assert criteria.traffic_density(square, [0.5, 0.2, 0.0]) == pytest.approx(1.2 / 5)
    pts, s = criteria.sample_polyline(square, 0.3)
    assert np.all(np.diff(s) <= 0.3 + 1e-12) and s[-1] == pytest.approx(5.0)
    for v in square:  # vertices are samples
        assert np.min(np.hypot(*(pts - v).T)) < 1e-12
    np.testing.assert_allclose(np.cumsum(np.r_[0, np.hypot(*np.diff(pts, axis=0).T)]), s)


def test_travel_time_model(warehouse):
    sc = warehouse
    s = np.linspace(0.0, 10.0, 101)
    v = np.full_like(s, 0.5)
    # Far under eps_max and slow: no fix needs a stop, time is pure driving.
    tau = np.full_like(s, 1e-4)
    t, n_fix, n_stop = criteria.travel_time(s, v, tau, sc)
    assert t == pytest.approx(20.0) and n_stop == 0 and n_fix >= 1
    # Independent count of the fixes: drift 0.012 / m eats the margin eps - tau every d metres,
    # but never more often than max_speed / fix_rate.
    drift = sc.robot.odometry_noise + sc.robot.wheel_radius_error
    d = max((sc.planning.eps_max - 1e-4) / drift, sc.robot.max_speed / sc.sensor.fix_rate_hz)
    assert n_fix == len(np.arange(0.0, 10.0 + 1e-9, d))
    # Close to eps_max: every fix must stop, each costing k * measurement_time.
    tau = np.full_like(s, sc.planning.eps_max * 0.99)
    t2, n_fix2, n_stop2 = criteria.travel_time(s, v, tau, sc, turn_in_place=math.pi)
    dwell = sc.sensor.markers_per_fix * sc.sensor.measurement_time
    assert n_stop2 == n_fix2 == 51  # every max_speed / fix_rate = 0.2 m, ends included
    assert t2 == pytest.approx(20.0 + math.pi / sc.robot.max_yaw_rate + 51 * dwell)


def brute_scores(values, adm, w):
    """Min-max normalisation over admissible rows and the weighted sum, written out longhand."""
    out = np.full(len(values), np.nan)
    rows = [i for i in range(len(values)) if adm[i]]
    for i in rows:
        tot = 0.0
        for c in range(values.shape[1]):
            col = [values[j, c] for j in rows]
            lo, hi = min(col), max(col)
            tot += w[c] * ((values[i, c] - lo) / (hi - lo) if hi > lo else 0.0)
        out[i] = tot
    return out


def brute_pareto(values, adm):
    n = len(values)
    front = []
    for i in range(n):
        dom = any(adm[j] and j != i and all(values[j] <= values[i]) and any(values[j] < values[i])
                  for j in range(n))
        front.append(bool(adm[i] and not dom))
    return np.array(front)


@pytest.mark.parametrize("seed", range(8))
def test_rank_matches_brute_force(seed):
    rng = np.random.default_rng(seed)
    n = 12
    # Coarse values so that ties and dominance both happen.
    values = rng.integers(0, 4, (n, 5)).astype(float) * np.array([0.01, 10.0, 0.2, 0.5, 1.0])
    adm = rng.random(n) < 0.8
    w = Weights(*rng.uniform(0, 2, 5))
    wv = ranking.weight_vector(w)
    r = ranking.rank(values, adm, w)
    np.testing.assert_allclose(r.scores, brute_scores(values, adm, wv), equal_nan=True, atol=1e-8)
    assert set(r.order) == set(np.flatnonzero(adm))
    best = r.order[0]
    assert r.scores[best] == pytest.approx(np.nanmin(brute_scores(values, adm, wv)), abs=1e-8)
    assert np.array_equal(r.pareto, brute_pareto(values, adm))
    # Weighted-sum minimisers with positive weights are always Pareto-optimal.
    if np.all(wv > 0):
        assert r.pareto[best]


@pytest.mark.parametrize("order", [("traffic", "length"), ("accuracy",),
                                   ("smoothness", "clearance", "length"),
                                   ("clearance", "accuracy", "traffic", "length", "smoothness")])
def test_lexicographic_matches_brute_force(order):
    rng = np.random.default_rng(len(order))
    values = rng.integers(0, 3, (15, 5)).astype(float)
    adm = rng.random(15) < 0.8
    r = ranking.rank(values, adm, Weights(), order)
    idx = [criteria.CRITERIA.index(c) for c in order]
    ranked = sorted(np.flatnonzero(adm), key=lambda i: tuple(values[i, idx]))
    assert [tuple(values[i, idx]) for i in r.order] == [tuple(values[i, idx]) for i in ranked]
    with pytest.raises(ValueError, match="unknown criterion"):
        ranking.rank(values, adm, Weights(), ("speed",))


def test_no_admissible_and_constant_columns():
    values = np.array([[1.0, 2, 3, 4, 5], [1.0, 3, 3, 4, 5]])
    r = ranking.rank(values, np.array([False, False]), Weights())
    assert r.order == () and not r.pareto.any() and np.isnan(r.scores).all()
    r = ranking.rank(values, np.array([True, True]), Weights(length=2.0))
    # Only "length" varies: normalised 0 and 1, the others contribute nothing.
    np.testing.assert_allclose(r.scores, [0.0, 2.0])
    assert r.pareto.tolist() == [True, False]


def test_ties_from_rounding_noise_are_ties():
    a = np.array([0.01, 17.89, 0.0, -0.56, 0.53])
    values = np.array([a, a * (1 + 1e-13)])
    r = ranking.rank(values, np.array([True, True]), Weights())
    assert r.pareto.tolist() == [True, True] and r.order == (0, 1)


def test_pareto_all_pairs_non_dominated():
    rng = np.random.default_rng(11)
    values = rng.normal(size=(40, 5))
    front = ranking.pareto_front(values)
    for i, j in itertools.product(np.flatnonzero(front), range(40)):
        assert not (np.all(values[j] <= values[i]) and np.any(values[j] < values[i]))
    for i in np.flatnonzero(~front):
        assert any(np.all(values[j] <= values[i]) and np.any(values[j] < values[i]) for j in range(40))
