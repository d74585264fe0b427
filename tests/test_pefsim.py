"""The Python API: each facade function returns its documented type and writes only where told."""

from __future__ import annotations

import numpy as np
import pytest

import pefsim
from planner.pef.map import PEF


@pytest.fixture(scope="module")
def two_markers():
    return pefsim.load("paper-two-markers")


def test_map_plan_place_and_run_write_nothing(two_markers, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    m = pefsim.pef_map(two_markers, resolution=0.25)
    assert isinstance(m, pefsim.PefMap) and m.tau.shape == (m.y.size, m.x.size)
    np.testing.assert_array_equal(m.tau, PEF(two_markers).grid(0.25).tau)
    moving = pefsim.pef_map(two_markers, resolution=0.25, speed=0.5)
    fin = np.isfinite(m.tau)
    assert np.all(moving.tau[fin] > m.tau[fin])  # a moving fix promises more than a robot standing still
    p = pefsim.plan(two_markers)
    assert isinstance(p, pefsim.Plan) and p.chosen is not None and p.schedule.fixes
    assert pefsim.plan(two_markers, start="A", goal="B").path.shape == p.path.shape
    placed = pefsim.place(two_markers)
    assert isinstance(placed, pefsim.Placement) and placed.count >= 2 and placed.count >= placed.lower_bound
    r = pefsim.run_episode(two_markers, seed=1)
    assert isinstance(r, pefsim.EpisodeResult) and r.summary["reached"]
    assert list(tmp_path.iterdir()) == []


def test_outputs_only_where_told(two_markers, tmp_path):
    pefsim.place(two_markers, out=tmp_path / "placed.toml")
    assert pefsim.load(tmp_path / "placed.toml").markers
    r = pefsim.run_episode(two_markers, seed=2, tum=tmp_path / "tum")
    assert sorted(p.name for p in (tmp_path / "tum").iterdir()) == ["estimate.txt", "groundtruth.txt"]
    assert r.written == [tmp_path / "tum" / "groundtruth.txt", tmp_path / "tum" / "estimate.txt"]


def test_a_fleets_plan_refuses_what_it_would_not_do(tmp_path):
    """A fleet's plan draws no figure or recording and searches no free space: asked, it says so, writes nothing."""
    from scenarios import loads
    from tests.sim.fleets import CROSS

    cross = loads(CROSS, source="cross.toml")
    for kwargs in (dict(out=tmp_path / "f.png"), dict(rrd=tmp_path / "f.rrd"), dict(free=True)):
        name = next(iter(kwargs))
        with pytest.raises(pefsim.PefsimError, match=rf"^{name}: cross\.toml is a fleet"):
            pefsim.plan(cross, **kwargs)
    assert list(tmp_path.iterdir()) == []


def test_bad_input_is_a_pefsim_error(two_markers):
    with pytest.raises(pefsim.PefsimError, match="start and goal"):
        pefsim.plan(two_markers, start="A")
    with pytest.raises(pefsim.PefsimError):
        pefsim.load("no-such-scenario")
