"""Redundancy 1 with flat reflectors on a corridor floor: the sites are refined where no set is robust.

``corridor-aisles`` of ``benchmarks/placement_gap.py`` (two 3 m aisles between three rack rows)
at eps_max = 0.05 m, sites sampled 4 m apart: 76 of its route points have good pairs but no set
of sites keeps one with any marker blocked; they were reported uncovered, because refinement
only looked at points without any good pair. (At the default 2 m, 32 points did, until the
line-of-sight margin came from the plan's certified bound instead of eps_max + 0.12 m: since
then 2 m covers them all.)
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
    return scenarios.loads(gap.AISLES.replace("eps_max = 0.03", "eps_max = 0.05") + "\n[placement]\nspacing = 4.0\n")


def test_points_only_redundancy_leaves_bare_are_refined(aisles):
    assert aisles.planning.redundancy == 1 and aisles.placement.marker_kind.value == "flat"
    coarse = placement.place(aisles, sites=candidate_sites(aisles))  # given sites: never refined
    bad = coarse.uncovered
    assert len(bad) > 0  # negative control: the 4 m sampling leaves them bare
    _, paired = placement.build_cover(aisles, bad, candidate_sites(aisles), aisles.planning.eps_max)
    assert paired.all()  # each has a good pair: only a rule that asks for robust sets refines there
    res = placement.place(aisles, points=bad)  # sampled sites: refined where needed
    assert len(res.uncovered) == 0 and res.finest_spacing is not None and res.finest_spacing < aisles.placement.spacing
    # every point keeps a fix with any one chosen marker blocked
    cov, ok = placement.build_cover(aisles, bad, res.sites, aisles.planning.eps_max)
    chosen = np.zeros(len(res.sites), dtype=bool)
    chosen[res.chosen] = True
    assert ok.all() and robust_rows(cov, chosen, aisles.sensor.markers_per_fix, 1)[cov.row_of].all()
