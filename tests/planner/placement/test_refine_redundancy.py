"""Redundancy 1 with flat reflectors on a corridor floor: the sites are refined where no set is robust.

``corridor-aisles`` of ``benchmarks/placement_gap.py`` (two 3 m aisles between three rack rows)
at eps_max = 0.05 m: at the 2 m sampling 32 of its 520 route points have good pairs but no set
of sites keeps one with any marker blocked; they were reported uncovered, because refinement
only looked at points without any good pair.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

import scenarios
from planner.placement import placement
from planner.placement.redundant import robust_rows
from planner.placement.sites import candidate_sites

BENCH = Path(__file__).resolve().parents[3] / "benchmarks" / "placement_gap.py"


@pytest.fixture(scope="module")
def aisles():
    spec = importlib.util.spec_from_file_location("placement_gap", BENCH)
    gap = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gap)
    return scenarios.loads(gap.AISLES.replace("eps_max = 0.03", "eps_max = 0.05"))


def test_points_only_redundancy_leaves_bare_are_refined(aisles):
    assert aisles.planning.redundancy == 1 and aisles.placement.marker_kind.value == "flat"
    coarse = placement.place(aisles, sites=candidate_sites(aisles))  # given sites: never refined
    bad = coarse.uncovered
    assert len(bad) > 0  # negative control: the 2 m sampling leaves them bare
    res = placement.place(aisles, points=bad)  # sampled sites: refined where needed
    assert len(res.uncovered) == 0 and res.finest_spacing is not None and res.finest_spacing < 2.0
    # every point keeps a fix with any one chosen marker blocked
    cov, ok = placement.build_cover(aisles, bad, res.sites, aisles.planning.eps_max)
    chosen = np.zeros(len(res.sites), dtype=bool)
    chosen[res.chosen] = True
    assert ok.all() and robust_rows(cov, chosen, aisles.sensor.markers_per_fix, 1)[cov.row_of].all()
