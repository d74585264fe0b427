"""The traffic-aware schedule on two robots crossing: it stops counting on what the other hides.

The fleet is the crossing of ``tests/sim/episode/test_fleet_episode.py`` (east along y = 6,
north along x = 6, reflectors at 0.3 m below the 0.5 m robots): planned alone, each robot
counts on reflectors the other drives in front of; planned with traffic, every fix whose
blocking probability exceeds the limit has a fallback for each marker (or none is left so).
"""

from __future__ import annotations

import json
import math

import pytest

import cli
from planner.fleet.plan import plan_fleet
from planner.fleet.summary import summarize
from planner.fleet.traffic import block_limit
from scenarios import loads
from tests.sim.fleets import CROSS


@pytest.fixture(scope="module")
def crossing():
    sc = loads(CROSS, source="cross.toml")
    return sc, plan_fleet(sc, traffic=False), plan_fleet(sc, traffic=True)


def test_alone_the_robots_count_on_reflectors_the_other_hides(crossing):
    _, alone, _ = crossing
    assert not alone.traffic and alone.note is None
    assert sum(r.blocking.expected_blocked_fixes for r in alone.robots) > 1.0


def test_with_traffic_risky_fixes_are_avoided_or_protected(crossing):
    sc, alone, aware = crossing
    limit = block_limit(sc)
    assert limit == pytest.approx(0.5 * (1 - sc.montecarlo.success_target))
    assert aware.traffic and aware.note.unprotected == ()
    for r in aware.robots:
        b = r.blocking
        assert not ((b.p_fix > limit) & ~b.protected).any()
    before = sum(r.blocking.expected_blocked_fixes for r in alone.robots)
    after = sum(r.blocking.expected_blocked_fixes for r in aware.robots)
    assert after < 0.1 * before


def test_the_summary_adds_up(crossing):
    sc, _, aware = crossing
    for s, r in zip(summarize(sc, aware), aware.robots, strict=True):
        assert s.fixes == sum(len(p.schedule.fixes) for p in r.plans)
        assert s.traffic_cost == pytest.approx(s.time - s.alone_time)
        assert s.wait_time == r.timeline.wait_time and s.time >= s.alone_time + s.wait_time - 0.2
        assert s.near_length + s.far_length == pytest.approx(r.s[-1])
        assert s.expected_blocked_los >= s.expected_blocked_fixes - 1e-9


def test_pefsim_plan_prints_each_robot_of_a_fleet(tmp_path, capsys):
    path = tmp_path / "cross.toml"
    path.write_text(CROSS)
    assert cli.main(["plan", str(path), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["traffic"] and [r["name"] for r in doc["robots"]] == ["east", "north"]
    assert set(doc["fleet"]) == {"fixes_per_m_near", "fixes_per_m_far"}
    assert cli.main(["plan", str(path), "--alone"]) == 0
    out = capsys.readouterr().out
    assert "as if it drove alone" in out and "east" in out and "E blocked fixes" in out
    assert any(line.startswith("fleet ") for line in out.splitlines())


def test_the_fleet_density_pools_the_robots_fixes_over_their_lengths():
    from planner.fleet.summary import RobotSummary, fleet_density

    def robot(near_len, far_len, n_near, n_far):
        return RobotSummary("r", [], n_near + n_far, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, near_len, far_len,
                            n_near / near_len if near_len else math.nan, n_far / far_len)

    # 10 fixes on 2 m near and 30 on 10 m elsewhere; the second robot never comes near the others
    near, far = fleet_density([robot(2.0, 4.0, 10, 20), robot(0.0, 6.0, 0, 10)])
    assert near == pytest.approx(5.0) and far == pytest.approx(3.0)
    assert math.isnan(fleet_density([robot(0.0, 6.0, 0, 10)])[0])


def test_a_stretch_without_a_protected_schedule_is_exempted_alone():
    """The risk is zeroed within EXEMPT_REACH of each named stretch and nowhere else.

    A task of a fleet with a declared spread whose protected schedule fails on one stretch keeps
    the risk (and so the protection) everywhere else. Negative control: with no stretch named the
    risk is the block function's own.
    """
    import numpy as np

    from planner.fleet.traffic import EXEMPT_REACH, _exempting

    s = np.linspace(0.0, 10.0, 101)
    xy = np.column_stack([s, np.zeros_like(s)])
    block = lambda s_, xy_: np.full((3, len(s_)), 0.4)  # noqa: E731 (a stand-in risk)
    got = _exempting(block, [(4.0, 4.2)])(s, xy)
    inside = (s >= 4.0 - EXEMPT_REACH) & (s <= 4.2 + EXEMPT_REACH)
    assert np.all(got[:, inside] == 0.0) and np.all(got[:, ~inside] == 0.4)
    assert 0 < inside.sum() < len(s)
    assert np.all(_exempting(block, [])(s, xy) == 0.4)   # the negative control
