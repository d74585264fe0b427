"""Parking: a robot that would finish on the only corridor another robot drives later moves off it.

The hard case: r1 starts on the corridor and its task ends on it, r0 drives the corridor later.
Neither can stand aside, so zone control's stop rule drives nobody (``no robot can move``); with
a parking place off the corridor r1 drives on to it and r0 passes. Planned on a scenario floor
(:data:`tests.sim.fleets.PARKED` names the place, :data:`~tests.sim.fleets.CORRIDOR` leaves it to
the planner, the negative control :data:`~tests.sim.fleets.NOWHERE` has none), abstractly with
timings the plan never saw (as ``test_dock_trades.py``), and in physics
(``tests/sim/episode/test_fleet_trades.py``).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from planner.fleet.parking import later_passers
from planner.fleet.plan import plan_fleet, zones_of
from planner.fleet.zones import ZoneControl, predict_timeline
from scenarios import PlanningError, loads
from tests.planner.fleet.zone_runs import CLEAR, RADIUS, kinematics, polyline, run_abstract, timings
from tests.sim import fleets

CORRIDOR = polyline((0, 0), (20, 0))
# r1 from (6, 0) on the corridor to (12, 0) on it, then (the parking leg) along it to a spur at
# x = 16 and up the spur to (16, 4): 4 m off the corridor, beyond both robots' reach
TASK = polyline((6, 0), (12, 0))
WITH_PARKING = polyline((6, 0), (12, 0), (16, 0), (16, 4))


def _robots(paths, starts):
    """Stand-ins for FleetRobotPlan: what :func:`later_passers` reads."""
    out = []
    for p, st in zip(paths, starts, strict=True):
        k = kinematics(p)
        out.append(SimpleNamespace(path=p, s=k.s_v, speed=np.r_[np.ones(len(k.s_v) - 1), 0.0], start_time=st))
    return out


def test_the_robot_finishing_on_the_corridor_parks_and_the_plan_drives():
    fp = plan_fleet(loads(fleets.PARKED, source="parked.toml"), traffic=False)
    r0, r1 = fp.robots
    assert r0.park is None and [(p.start, p.goal) for p in r0.plans] == [("W", "E")]
    assert r1.park == "P" and [(p.start, p.goal) for p in r1.plans] == [("M1", "M2"), ("M2", "P")]
    assert np.allclose(r1.path[-1], (16.25, 6.5)) and r1.timeline.xy[-1] == pytest.approx((16.25, 6.5))
    # parked, it is in nobody's way: its final dock shares no zone cell with r0's path
    zones = zones_of(fp.robots)
    assert zones.meets(1, len(r1.path) - 1)[0] == -1
    # r0 passes M2 after r1 got there: standing there, r1 would have blocked it
    at_m2 = np.flatnonzero(r0.timeline.xy[:, 0] >= 12.0)[0]
    assert r0.timeline.t[at_m2] > r1.timeline.t[np.flatnonzero(r1.timeline.s >= r1.offsets[1])[0]]
    assert r0.timeline.s[-1] == pytest.approx(r0.s[-1])


def test_with_none_named_the_planner_picks_a_dock_off_the_others_paths():
    # the stop rule cannot drive the corridor: r1 gets the spur's dock P, not Q, which is nearer
    # to M2 but on r0's corridor
    fp = plan_fleet(loads(fleets.CORRIDOR, source="corridor.toml"), traffic=False)
    r0, r1 = fp.robots
    assert r0.park is None and r1.park == "P" and [p.goal for p in r1.plans] == ["M2", "P"]
    assert zones_of(fp.robots).meets(1, len(r1.path) - 1)[0] == -1


def test_negative_control_with_no_parking_place_it_is_refused_naming_the_robot():
    with pytest.raises(PlanningError, match=r"no robot can move.*r1's final dock 'M2' \(12\.00, 2\.00\) lies on "
                                            r"r0's path: name a parking place for r1"):
        plan_fleet(loads(fleets.NOWHERE, source="nowhere.toml"), traffic=False)


def test_a_parking_place_on_another_path_is_refused():
    # the corridor's west end, where r0 starts: a robot parked there would stand in r0's way
    text = fleets.PARKED.replace('park = "P"', 'park = "W"')
    with pytest.raises(PlanningError, match=r"r1's parking place 'W' \(1\.00, 2\.00\) lies within 1\.10 m of "
                                            r"r0's path"):
        plan_fleet(loads(text, source="parked.toml"), traffic=False)


@pytest.mark.parametrize(("starts", "passer"), [([15.0, 0.0], 0), ([0.0, 40.0], -1)])
def test_only_a_robot_passing_later_makes_it_park(starts, passer):
    # r1 from a spur down to the corridor, r0 along it: r0 passes r1's dock after r1 arrives (it
    # starts 15 s later) or before (r1 starts 40 s later), when r1 has no reason to park
    paths = [CORRIDOR, polyline((10, 4), (10, 0))]
    robots = _robots(paths, starts)
    zc = ZoneControl(paths, [RADIUS] * 2)
    tls = predict_timeline(ZoneControl(paths, [RADIUS] * 2), [kinematics(p) for p in paths], starts, dt=0.05)
    assert later_passers(zc, robots, tls) == [-1, passer]
    # without a timeline (the stop rule jammed) every robot whose path meets the dock counts
    assert later_passers(zc, robots, None) == [-1, 0]


def test_parked_on_the_corridor_drives_whatever_the_timing():
    paths = [CORRIDOR, WITH_PARKING]
    rec = ZoneControl(paths, [RADIUS] * 2, record=True)
    tls = predict_timeline(rec, [kinematics(p) for p in paths], [15.0, 0.0], dt=0.05)
    assert all(tl.s[-1] == pytest.approx(zc_len) for tl, zc_len in zip(tls, [20.0, 14.0], strict=True))
    after = rec.precedence()
    for speeds, st in timings(np.random.default_rng(51), 2):
        ok, closest, still = run_abstract(ZoneControl(paths, [RADIUS] * 2, after=after), speeds, st)
        assert ok, f"{still} (speeds {speeds}, starts {st})"
        assert closest >= CLEAR - 1e-9
    # the stop rule alone (no order of passage) drives it too: the parked robot blocks nobody
    for speeds, st in timings(np.random.default_rng(52), 2):
        assert run_abstract(ZoneControl(paths, [RADIUS] * 2), speeds, st)[0]


def test_negative_control_without_the_parking_leg_no_robot_can_move():
    paths = [CORRIDOR, TASK]
    with pytest.raises(PlanningError, match="no robot can move"):
        predict_timeline(ZoneControl(paths, [RADIUS] * 2), [kinematics(p) for p in paths], [15.0, 0.0], dt=0.05)
    # and driven anyway, some timings jam
    stuck = sum(not run_abstract(ZoneControl(paths, [RADIUS] * 2), speeds, st)[0]
                for speeds, st in timings(np.random.default_rng(51), 2))
    assert stuck > 0
