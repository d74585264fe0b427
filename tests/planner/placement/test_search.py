"""Local search on the pair cover: a smaller cover, checked by the PEF itself, minimal, and reproducible."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import scenarios
from planner.pef.map import PEF
from planner.placement import cover, placement, search
from planner.placement.sites import candidate_sites, cover_points
from scenarios.schema import MarkerKind


@pytest.fixture(scope="module")
def warehouse():
    sc = scenarios.load("warehouse")
    sc = dataclasses.replace(sc, placement=dataclasses.replace(sc.placement, marker_kind=MarkerKind.POST))
    pts, sites = cover_points(sc), candidate_sites(sc)
    cov, coverable = placement.build_cover(sc, pts, sites, sc.planning.eps_max)
    return sc, pts, sites, cov, coverable


def test_search_finds_a_smaller_minimal_cover_the_pef_confirms(warehouse):
    sc, pts, sites, cov, coverable = warehouse
    start = cover.greedy(cov, 2)
    found = search.local_search(cov, 2, start, sites, seed=7, work=50_000_000)
    assert found.sum() < start.sum()
    # the pair bookkeeping of the search is not trusted: coverage from the rows' own test ...
    assert cover.covered(cov, found, 2).all()
    # ... and from the PEF of the chosen markers at every coverable point
    placed = placement._site_scenario(sc, sites[found])
    assert np.all(PEF(placed).at(pts[coverable]).tau < sc.planning.eps_max)
    # minimal: no chosen site can be dropped (the negative control of the coverage test)
    for j in np.flatnonzero(found):
        fewer = found.copy()
        fewer[j] = False
        assert not cover.covered(cov, fewer, 2).all()


def test_search_is_reproducible_and_follows_its_seed(warehouse):
    _, _, sites, cov, _ = warehouse
    start = cover.greedy(cov, 2)
    runs = [search.local_search(cov, 2, start, sites, seed=s, work=20_000_000) for s in (1, 1, 2)]
    np.testing.assert_array_equal(runs[0], runs[1])
    assert cover.covered(cov, runs[2], 2).all()
    # no budget: only the prune of the start
    pruned = search.local_search(cov, 2, start, sites, seed=1, work=0)
    assert pruned.sum() <= start.sum() and cover.covered(cov, pruned, 2).all()


def test_search_returns_a_non_cover_unchanged(warehouse):
    _, _, sites, cov, _ = warehouse
    partial = np.zeros(cov.n_sites, dtype=bool)
    partial[np.flatnonzero(cover.greedy(cov, 2))[:3]] = True
    np.testing.assert_array_equal(search.local_search(cov, 2, partial, sites, seed=1, work=10**6), partial)


def test_search_keeps_k_visible_markers_for_k3():
    sc = scenarios.load("warehouse")
    sc = dataclasses.replace(sc, sensor=dataclasses.replace(sc.sensor, markers_per_fix=3),
                             placement=dataclasses.replace(sc.placement, marker_kind=MarkerKind.POST))
    pts, sites = cover_points(sc), candidate_sites(sc)
    cov, _ = placement.build_cover(sc, pts, sites, sc.planning.eps_max)
    start = cover.greedy(cov, 3)
    found = search.local_search(cov, 3, start, sites, seed=3, work=20_000_000)
    assert found.sum() <= start.sum()
    assert cover.covered(cov, found, 3).all()
    assert np.all((cov.vis & found).sum(axis=1) >= 3)
