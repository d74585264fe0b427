"""Zone control: no two robots' zones overlap, nobody deadlocks on the adversarial layouts, waits happen."""

from __future__ import annotations

import numpy as np
import pytest

from planner.fleet.zones import DEFAULT_MARGIN, ZoneControl, predict_timeline
from scenarios.errors import PlanningError
from tests.planner.fleet.zone_runs import RADIUS, SPACING, kinematics, min_distance, polyline


def drive(paths, starts=None, cls=ZoneControl):
    zc = cls(paths, [RADIUS] * len(paths))
    tls = predict_timeline(zc, [kinematics(p) for p in paths], starts or [0.0] * len(paths), dt=0.05)
    return zc, tls


# Held samples' footprints (radius + margin) are disjoint; each robot is within half a sample
# spacing of a held sample: centres stay 2 (radius + margin) - spacing apart.
BOUND = 2 * (RADIUS + DEFAULT_MARGIN) - SPACING

# Layouts whose docks are clear of the other robots' paths; every one needs a wait.
HEAD_ON = [polyline((0, 0), (2, 5), (18, 5), (20, 10)), polyline((20, 0), (18, 5), (2, 5), (0, 10))]
CROSSING = [polyline((0, 5), (20, 5)), polyline((10, -5), (10, 15))]
_T = [np.array([0.0, 0.0]), np.array([12.0, 0.0]), np.array([6.0, 10.0])]


def _rot(v: np.ndarray, deg: float) -> np.ndarray:
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def cycle_paths() -> list[np.ndarray]:
    """Three robots around a triangle, robot i along T_i -> T_i+1 -> T_i+2.

    Each side is driven by two robots and each robot's way is the next one's, a cycle of
    who-is-in-whose-way. Docks sit on spurs outside the corners (start spurs turned +40 deg, final
    ones -40 deg from the outward direction: a start and a final dock at one corner are
    2.5 m x 2 sin 40 deg = 3.2 m apart).
    """
    c = np.mean(_T, axis=0)
    paths = []
    for i in range(3):
        a, b, d = _T[i], _T[(i + 1) % 3], _T[(i + 2) % 3]
        out_a, out_d = (a - c) / np.hypot(*(a - c)), (d - c) / np.hypot(*(d - c))
        start, end = a + 2.5 * _rot(out_a, 40.0), d + 2.5 * _rot(out_d, -40.0)
        paths.append(polyline(tuple(start), tuple(a), tuple(b), tuple(d), tuple(end)))
    return paths


@pytest.mark.parametrize("name,paths", [("head-on", HEAD_ON), ("crossing", CROSSING)])
def test_two_robots_never_meet_and_one_waits(name, paths):
    zc, tls = drive(paths)
    assert all(tl.s[-1] == pytest.approx(zc.length(i)) for i, tl in enumerate(tls))
    assert min_distance(tls) >= BOUND
    assert sum(tl.wait_time for tl in tls) > 0.5, "the layouts force a wait"


def test_three_robots_in_a_cycle_all_arrive():
    paths = cycle_paths()
    zc, tls = drive(paths)
    assert all(tl.s[-1] == pytest.approx(zc.length(i)) for i, tl in enumerate(tls))
    assert min_distance(tls) >= BOUND
    assert sum(tl.wait_time for tl in tls) > 0.5


def test_head_on_waits_where_it_blocks_nobody():
    zc, tls = drive(HEAD_ON)
    # one robot waits on its start spur (which one is a tie the time step's rounding breaks),
    # clear of the other's path, until the other has passed the 16 m corridor at 1 m/s
    waiter = int(np.argmax([tl.wait_time for tl in tls]))
    assert tls[waiter].wait_time > 16.0 and tls[1 - waiter].wait_time == 0.0
    # where it waits is clear of what the other robot still has to drive (its remaining path)
    other = HEAD_ON[1 - waiter]
    s_other = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(other, axis=0).T))])
    for n in np.flatnonzero(tls[waiter].waiting):
        rest = other[s_other >= tls[1 - waiter].s[min(n, len(tls[1 - waiter].s) - 1)] - SPACING]
        if len(rest):
            assert np.hypot(*(rest - tls[waiter].xy[n]).T).min() >= BOUND


def test_zones_are_exclusive_at_every_step():
    zc = ZoneControl(CROSSING, [RADIUS, RADIUS])
    kins = [kinematics(p) for p in CROSSING]
    clock = [0.0, 0.0]
    for _ in range(600):
        for i in (0, 1):
            s = float(kins[i].s_at(clock[i] + 0.05))
            if zc.request(i, s):
                clock[i] += 0.05
                zc.release(i, s)
        held = [set(zc.held(i).tolist()) for i in (0, 1)]
        assert not held[0] & held[1]


class Greedy(ZoneControl):
    """Negative control: reserve one sample at a time, no stops (what the rule forbids)."""

    def next_stop(self, i):
        return min(self.end[i] + 1, len(self.paths[i]) - 1)


def test_greedy_reservation_deadlocks_head_on():
    with pytest.raises(PlanningError, match="no robot can move"):
        drive(HEAD_ON, cls=Greedy)


def test_dock_on_another_path_is_named_and_two_robots_on_one_dock_refused():
    # a dock on another robot's path is allowed (the plan's order of passage keeps the fleet
    # deadlock-free, test_dock_trades.py), and said: the stop rule alone needs docks clear
    paths = [polyline((0, 5), (20, 5)), polyline((10, 5.3), (10, 15))]
    assert "robot 1's start (10.00, 5.30) lies within 1.10 m of robot 0's path" in ZoneControl(
        paths, [RADIUS, RADIUS]).dock_conflict
    assert ZoneControl(CROSSING, [RADIUS, RADIUS]).dock_conflict is None
    with pytest.raises(PlanningError, match="robot 0's and robot 1's starts lie within 1.10 m of each other"):
        ZoneControl([polyline((0, 5), (20, 5)), polyline((0.5, 5), (0, 15))], [RADIUS, RADIUS])


def test_start_times_delay_and_record():
    zc, tls = drive(CROSSING, starts=[0.0, 30.0])
    assert tls[1].s[tls[1].t <= 30.0].max() == 0.0
    assert tls[0].wait_time == 0.0 and tls[1].wait_time == 0.0   # robot 0 is long gone


def random_fleet(rng: np.random.Generator, n: int) -> list[np.ndarray]:
    """Draw n robots' paths on a 20 x 20 m floor.

    Each from a dock on the west or south edge through three random interior points to a dock on
    the east or north edge; docks 3 m apart along the edges.
    """
    slots = rng.permutation(6)[: 2 * n]
    edge = [(0.0, 2.0 + 3.0 * k) for k in range(6)] + [(2.0 + 3.0 * k, 0.0) for k in range(6)]
    far = [(20.0, 2.0 + 3.0 * k) for k in range(6)] + [(2.0 + 3.0 * k, 20.0) for k in range(6)]
    paths = []
    for i in range(n):
        a = edge[int(slots[i]) + 6 * int(rng.integers(2))]
        b = far[int(slots[n + i]) + 6 * int(rng.integers(2))]
        mid = [tuple(p) for p in rng.uniform(3.0, 17.0, size=(3, 2))]
        paths.append(polyline(a, *mid, b))
    return paths


@pytest.mark.parametrize("count,seed", [(6, 20261203), pytest.param(60, 1203, marks=pytest.mark.e2e)])
def test_random_fleets_all_arrive_and_never_meet(count, seed):
    # the argument of planner/fleet/zones.py on random three-robot floors whose docks zone control
    # accepts: every robot arrives (no deadlock, no livelock) and the clearance holds
    # (negative control: reserving one sample at a time, the same floors deadlock)
    rng = np.random.default_rng(seed)
    tried = accepted = stuck = 0
    while accepted < count:
        tried += 1
        paths = random_fleet(rng, 3)
        starts = list(rng.uniform(0.0, 5.0, size=3))
        try:
            if ZoneControl(paths, [RADIUS] * 3).dock_conflict is not None:
                continue                 # a dock on another's path: the stop rule's argument needs them clear
        except PlanningError as exc:
            assert "of each other" in str(exc), exc   # two robots on one dock: refused
            continue
        zc, tls = drive(paths, starts=starts)
        accepted += 1
        assert all(tl.s[-1] == pytest.approx(zc.length(i)) for i, tl in enumerate(tls))
        assert min_distance(tls) >= BOUND
        try:
            drive(paths, starts=starts, cls=Greedy)
        except PlanningError as exc:
            assert "no robot can move" in str(exc)
            stuck += 1
    assert tried < 25 * count
    assert stuck > 0, "no random floor is adversarial: greedy reservation got through every one"
