"""plan_fleet: every robot's tasks planned, chained, and a timeline in which nobody meets."""

from __future__ import annotations

import itertools
from types import SimpleNamespace

import numpy as np
import pytest

from planner.fleet.plan import chain, plan_fleet
from planner.fleet.zones import DEFAULT_MARGIN
from scenarios import PlanningError, load, loads
from tests.sim.fleets import CROSS


@pytest.fixture(scope="module", params=["cross", pytest.param("warehouse-fleet", marks=pytest.mark.e2e)])
def fleet(request):
    """Return a fleet and its plan: two robots crossing on a 12 m floor (fast), the built-in's three (~30 s: e2e).

    Chaining, timeline and clearance do not depend on the traffic-aware schedule
    (tests/planner/fleet/test_traffic.py plans the crossing both ways).
    """
    sc = loads(CROSS, source="cross.toml") if request.param == "cross" else load(request.param)
    return sc, plan_fleet(sc, traffic=False)


def test_each_robot_drives_its_tasks_from_dock_to_dock(fleet):
    sc, fp = fleet
    assert [r.name for r in fp.robots] == [r.name for r in sc.robots] and not fp.traffic
    for fr, rp in zip(sc.robots, fp.robots, strict=True):
        assert [(p.start, p.goal) for p in rp.plans] == [(sc.tasks[i].start, sc.tasks[i].goal) for i in fr.tasks]
        tl = rp.timeline
        assert np.allclose(tl.xy[0], sc.dock(rp.plans[0].start).position)
        assert np.allclose(tl.xy[-1], sc.dock(rp.plans[-1].goal).position, atol=1e-6)
        assert tl.s[-1] == pytest.approx(rp.s[-1])
        assert np.all(tl.s[tl.t <= fr.start_time] == 0.0)
        assert np.all(np.diff(tl.s) >= 0.0)


def test_the_predicted_fleet_keeps_its_clearance(fleet):
    sc, fp = fleet
    spacing = max(float(np.diff(r.s).max()) for r in fp.robots)
    for a, b in itertools.combinations(fp.robots, 2):
        n = max(len(a.timeline.t), len(b.timeline.t))
        pa = np.concatenate([a.timeline.xy, np.repeat(a.timeline.xy[-1:], n - len(a.timeline.t), axis=0)])
        pb = np.concatenate([b.timeline.xy, np.repeat(b.timeline.xy[-1:], n - len(b.timeline.t), axis=0)])
        # disjoint footprints (radius + margin), each robot within half a sample of a held sample
        bound = a.robot.radius + b.robot.radius + 2 * DEFAULT_MARGIN - spacing
        assert np.hypot(*(pa - pb).T).min() >= bound


def test_crossing_routes_make_someone_wait(fleet):
    _, fp = fleet
    assert max(r.timeline.wait_time for r in fp.robots) > 1.0


def test_not_a_fleet_is_refused():
    with pytest.raises(PlanningError, match="has no \\[\\[robots\\]\\]"):
        plan_fleet(load("warehouse"))


def test_chain_joins_at_the_dock_once():
    a = SimpleNamespace(path=np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]), s=np.array([0.0, 1.0, 2.0]),
                        speed=np.array([1.0, 1.0, 0.0]))
    b = SimpleNamespace(path=np.array([[2.0, 0.0], [2.0, 1.0]]), s=np.array([0.0, 1.0]), speed=np.array([1.0, 0.0]))
    path, s, speed, offsets = chain([a, b])
    assert path.tolist() == [[0, 0], [1, 0], [2, 0], [2, 1]]
    assert s.tolist() == [0, 1, 2, 3] and speed.tolist() == [1, 1, 0, 0] and offsets.tolist() == [0, 2]


@pytest.mark.e2e  # plans two of the built-in's robots (~30 s); tests/planner/fleet/test_zones.py refuses it fast
def test_two_robots_on_one_dock_are_refused_in_one_line():
    from dataclasses import replace

    sc = load("warehouse-fleet")
    # r3 given r1's task: both start on dock A
    bad = replace(sc, robots=(sc.robots[0], replace(sc.robots[2], tasks=(0,))))
    with pytest.raises(PlanningError, match=r"^warehouse-fleet\.toml: robots: zone control: r1's and r3's starts "
                                            r"lie within 1\.10 m of each other"):
        plan_fleet(bad, traffic=False)  # zone control refuses the docks whatever the schedule
