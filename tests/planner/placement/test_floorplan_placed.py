"""A placed scenario written from a floor-plan scenario keeps the drawing's obstacles, not its markers."""

from __future__ import annotations

import numpy as np

import scenarios
from planner.placement.placement import PlacementResult, write_scenario_with_markers
from tests.scenarios import drawings as dr
from tests.scenarios.worlds import DXF, scenario_text


def test_placed_scenario_replaces_the_drawings_markers(tmp_path):
    dr.write_hall(tmp_path / "hall.dxf")
    (tmp_path / "fp.toml").write_text(scenario_text(DXF))
    s = scenarios.load(tmp_path / "fp.toml")
    placed = [("P1", (5.0, 0.1)), ("P2", (15.0, 0.1)), ("P3", (0.1, 8.0))]
    result = PlacementResult(markers=placed, count=3, lower_bound=3, optimal=True, uncovered=np.zeros((0, 2)),
                             method="test", sites=np.zeros((0, 2)), points=np.zeros((0, 2)), chosen=np.arange(3))
    out = write_scenario_with_markers(s, result, tmp_path / "placed.toml")
    again = scenarios.load(out)
    assert [m.id for m in again.markers] == ["P1", "P2", "P3"]
    assert again.obstacles == s.obstacles and again.floorplan.marker_layer is None
