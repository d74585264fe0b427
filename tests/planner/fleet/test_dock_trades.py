"""Robots that trade docks: swap, rotation, a dock on the only corridor; deadlock-free whatever the timing.

Each hard case is planned through zone control's stop rule (:func:`predict_timeline`, recording the
order in which the robots pass each cell), then driven abstractly as the simulation drives it
(``zone_runs.run_abstract``: braking distance plus lookahead, release slack, stops short of
the reservation's end) with timings the plan never saw: speeds 0.3-1.5 m/s and start
times 0-40 s drawn per trial. Kept in the plan's order of passage (``ZoneControl(after=...)``), every
robot arrives in every trial and the clearance holds. Negative control: reserving one sample at a
time with neither stops nor the order (the rule weakened) deadlocks in some of the same trials.
"""

from __future__ import annotations

import numpy as np
import pytest

from planner.fleet.zones import DEFAULT_MARGIN, ZoneControl, predict_timeline
from scenarios.errors import PlanningError
from tests.planner.fleet.zone_runs import (
    CLEAR,
    DEVIATION,
    RADIUS,
    floor,
    kinematics,
    min_distance,
    polyline,
    random_fleet,
    run_abstract,
    timings,
)

# r1 W -> E by the north aisle while r2 E -> W by the south one: each starts on the other's final dock
SWAP = [polyline((0, 5), (2, 5), (3, 8), (17, 8), (18, 5), (20, 5)),
        polyline((20, 5), (18, 5), (17, 2), (3, 2), (2, 5), (0, 5))]
_C = [np.array([0.0, 0.0]), np.array([12.0, 0.0]), np.array([6.0, 10.0])]
_MID = np.mean(_C, axis=0)


def _dock(i: int) -> tuple[float, float]:
    """Return the dock on a 2.5 m spur outside corner i of the triangle."""
    out = (_C[i] - _MID) / np.hypot(*(_C[i] - _MID))
    return tuple(_C[i] + 2.5 * out)


# robot i from dock i along a side of the triangle to dock i + 1: each ends where the next starts
ROTATION = [polyline(_dock(i), tuple(_C[i]), tuple(_C[(i + 1) % 3]), _dock((i + 1) % 3)) for i in range(3)]
# r1 parks on the only corridor, which r0 drives 15 s later
PARKED = [polyline((0, 0), (20, 0)), polyline((10, 4), (10, 0))]
CASES = {"swap": (SWAP, [0.0, 0.0]), "rotation": (ROTATION, [0.0, 0.0, 0.0]), "parked": (PARKED, [15.0, 0.0])}


class Greedy(ZoneControl):
    """Negative control: one sample at a time, no stops, no order of passage (what the rule forbids)."""

    def next_stop(self, i):
        return min(self.end[i] + 1, len(self.paths[i]) - 1)


def plan(paths, starts):
    """Plan ``paths`` under the stop rule; return the timelines and the order of passage."""
    zc = ZoneControl(paths, [RADIUS] * len(paths), record=True)
    assert zc.dock_conflict is not None   # the old rule refused every one of these fleets
    tls = predict_timeline(zc, [kinematics(p) for p in paths], starts, dt=0.05)
    return tls, zc.precedence()


@pytest.mark.parametrize("case", sorted(CASES))
def test_trades_plan_and_keep_their_order_whatever_the_timing(case):
    paths, starts = CASES[case]
    tls, after = plan(paths, starts)
    for tl, p in zip(tls, paths, strict=True):
        assert tl.s[-1] == pytest.approx(float(np.hypot(*np.diff(p, axis=0).T).sum()))   # everyone arrives
    assert min_distance(tls) >= 2 * (RADIUS + DEFAULT_MARGIN) - 0.05
    if case == "parked":
        # the robot bound for the corridor waits until the other has passed its dock
        assert tls[1].wait_time > 10.0 and tls[1].end_time > tls[0].t[np.argmax(tls[0].xy[:, 0] > 11.2)]
    for speeds, st in timings(np.random.default_rng(50), len(paths)):
        ok, closest, still = run_abstract(ZoneControl(paths, [RADIUS] * len(paths), after=after), speeds, st)
        assert ok, f"{case}: {still} (speeds {speeds}, starts {st})"
        assert closest >= CLEAR - 1e-9


@pytest.mark.parametrize("case", sorted(CASES))
def test_negative_control_without_stops_or_order_deadlocks(case):
    paths, _ = CASES[case]
    stuck = sum(not run_abstract(Greedy(paths, [RADIUS] * len(paths)), speeds, st)[0]
                for speeds, st in timings(np.random.default_rng(50), len(paths)))
    assert stuck > 0, "the weakened rule got through every timing: the trials cannot catch a deadlock"


def test_a_rotation_through_one_hub_is_refused_not_stuck():
    # three spurs off one hub, each robot to the next spur: each spur is driven both ways and
    # nobody can stand aside; planning says so (the simulation never starts a fleet that jams)
    hub = [polyline(_dock(i), tuple(_MID), _dock((i + 1) % 3)) for i in range(3)]
    with pytest.raises(PlanningError, match="no robot can move"):
        plan(hub, [0.0, 0.0, 0.0])


@pytest.mark.e2e
@pytest.mark.parametrize("count,seed", [(60, 48)])
def test_random_fleets_with_docks_anywhere_keep_their_order(count, seed):
    # random floors and fleets of test_deadlock_search, docks wherever the spurs fall (on other
    # robots' paths or not); those the plan can drive, driven with fresh speeds and starts
    rng = np.random.default_rng(seed)
    planned = refused = 0
    while planned < count:
        nodes, segments, radius = floor(rng)
        fleet = random_fleet(rng, nodes, segments, radius, clear=False)
        if fleet is None:
            continue
        zc, speeds, starts = fleet
        n = len(zc.paths)
        rec = ZoneControl(zc.paths, [radius] * n, record=True)
        try:
            predict_timeline(rec, [kinematics(p, v) for p, v in zip(zc.paths, speeds, strict=True)], starts, dt=0.1)
        except PlanningError as exc:
            assert "no robot can move" in str(exc) or "had not arrived" in str(exc), exc
            refused += 1
            continue
        planned += 1
        after = rec.precedence()
        for v, st in timings(rng, n)[:3]:
            ok, closest, still = run_abstract(ZoneControl(zc.paths, [radius] * n, after=after), v, st)
            assert ok, still
            assert closest >= 2.0 * (radius + DEFAULT_MARGIN) - 2.0 * DEVIATION - 1e-9
    assert planned > refused / 10   # the draw is not mostly fleets that cannot be planned
