"""Placement with its defaults: sites refined where flat reflectors leave gaps; keeping installed markers.

Coverage is checked independently of the placement's pair kernel: the PEF of the placed
scenario (:class:`planner.pef.map.PEF`, best subset over every visible marker) at every point
placement had to cover.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import scenarios
from planner.pef.map import PEF
from planner.placement import placement
from planner.placement.sites import candidate_sites, cover_points

KEEP_EPS = 0.02
"""A tightened eps_max for the warehouse with its 12 reflectors kept [m]."""
GAP = 1.3
"""Largest ratio of added markers to the reported lower bound this test accepts."""


def tau_at_cover_points(sc):
    return PEF(sc).at(cover_points(sc)).tau


@pytest.fixture(scope="module")
def warehouse():
    return scenarios.load("warehouse")


def test_warehouse_defaults_cover_every_point_after_refinement(warehouse):
    base = candidate_sites(warehouse)
    coarse = placement.place(warehouse, sites=base)  # given sites are never refined
    assert len(coarse.uncovered) > 0 and coarse.finest_spacing is None  # the 2 m sites leave gaps (control)
    res = placement.place(warehouse)
    assert len(res.uncovered) == 0
    assert res.finest_spacing is not None and res.finest_spacing < warehouse.placement.spacing
    assert len(res.sites) > len(base) and np.array_equal(res.sites[:len(base)], base)
    placed = placement.scenario_with_markers(warehouse, res)
    assert np.all(tau_at_cover_points(placed) < warehouse.planning.eps_max)


@pytest.fixture(scope="module")
def keep(warehouse):
    sc = dataclasses.replace(warehouse, planning=dataclasses.replace(warehouse.planning, eps_max=KEEP_EPS),
                             placement=dataclasses.replace(warehouse.placement, existing="keep"))
    return sc, placement.place(sc)


def test_keep_leaves_installed_markers_and_adds_within_gap_of_bound(keep, warehouse):
    sc, res = keep
    assert res.kept == warehouse.markers  # ids, positions, kinds, facings
    placed = placement.scenario_with_markers(sc, res)
    assert placed.markers[:len(warehouse.markers)] == warehouse.markers
    assert len(placed.markers) == len(warehouse.markers) + res.count
    assert not set(res.new_ids) & {m.id for m in warehouse.markers}
    assert res.lower_bound >= 1 and res.count <= math.floor(GAP * res.lower_bound)
    assert len(res.uncovered) == 0
    assert np.all(tau_at_cover_points(placed) < KEEP_EPS)


def test_keep_negative_control_installed_markers_alone_break_the_tighter_target(keep):
    sc, _ = keep
    assert np.any(tau_at_cover_points(sc) >= KEEP_EPS)  # the 12 alone do not hold 20 mm: something must be added


def test_keep_written_scenario_keeps_the_file_markers(keep, warehouse, tmp_path):
    sc, res = keep
    out = placement.write_scenario_with_markers(sc, res, tmp_path / "kept.toml")
    back = scenarios.load(out)
    assert back.markers[:len(warehouse.markers)] == warehouse.markers
    assert [m.id for m in back.markers[len(warehouse.markers):]] == list(res.new_ids)
    assert back.placement.existing == "keep"
    doc = res.to_dict()
    assert doc["kept"] == [m.id for m in warehouse.markers] and doc["new"] == list(res.new_ids)
    assert [m["new"] for m in doc["markers"]] == [False] * len(warehouse.markers) + [True] * res.count


def test_replace_ignores_installed_markers(warehouse):
    res = placement.place(warehouse, sites=candidate_sites(warehouse)[:40], points=cover_points(warehouse)[:50])
    assert res.kept == () and all(i.startswith("P") for i in res.new_ids)
