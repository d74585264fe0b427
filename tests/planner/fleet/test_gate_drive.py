"""The sampled blocking model's kinematic drive through the zone gate (planner.fleet.drive.drive_draw).

Two robots of radius 0.4 m cross at the origin: A drives east along y = 0, B north along x = 0,
both released at t = 0 at 1 m/s, 10 m from the crossing. A asks first each tick (index order, as the
simulation's robots tick), so it holds the crossing; B must stop short of it and go once A has
passed, as the simulation's robot does under the same gate (planner.fleet.gate.zone_cap).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from planner.fleet.drive import drive_draw
from planner.fleet.gate import GOAL_TOLERANCE, STOP_MARGIN
from planner.fleet.zones import DEFAULT_MARGIN, ZoneControl

RADIUS = 0.4
SPACING = 0.1
ACCEL = 0.5
DT = 0.05
#: How much earlier than the continuous closed form the drive may reach its goal [s]: each tick takes
#: its goal-braking speed from the distance left at the tick's start, so the discrete braking runs
#: ahead, by less than 4 ticks (0.2, 0.083, 0.04 s at dt = 0.05, 1/60, 0.005 s), and the follower's
#: creep at 0.02 m/s covers the last 0.5 mm in half the continuous time (0.025 s).
SLACK = 4.0 * DT + 0.05


def _robot(name, path):
    path = np.asarray(path, float)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(path, axis=0).T))])
    speed = np.ones(len(path))
    speed[-1] = 0.0
    plan = SimpleNamespace(schedule=SimpleNamespace(fixes=()))
    return SimpleNamespace(name=name, path=path, s=s, speed=speed, offsets=np.array([0.0]), plans=[plan],
                           robot=SimpleNamespace(radius=RADIUS, height=0.5, max_speed=1.0))


def _cross():
    line = np.linspace(-10.0, 10.0, int(round(20.0 / SPACING)) + 1)
    a = _robot("A", np.column_stack([line, np.zeros_like(line)]))
    b = _robot("B", np.column_stack([np.zeros_like(line), line]))
    return [a, b]


def _drive(fleet, zones):
    return drive_draw(fleet, zones, [0.0, 0.0], [1.0, 1.0], [np.zeros(0), np.zeros(0)], dt=DT, accel=ACCEL)


def _closest(fleet, runs) -> float:
    t = np.union1d(runs[0][0], runs[1][0])
    xy = [np.column_stack([np.interp(np.interp(t, tt, ss), r.s, r.path[:, 0]),
                           np.interp(np.interp(t, tt, ss), r.s, r.path[:, 1])])
          for r, (tt, ss, _) in zip(fleet, runs, strict=True)]
    return float(np.hypot(*(xy[0] - xy[1]).T).min())


def test_a_robot_waits_where_the_gate_stops_it_and_the_two_never_touch():
    """B stands STOP_MARGIN short of a stop clear of A's path, until A has passed; they keep apart.

    Bounds: a standing robot's footprint shares no zone cell with another's, so their centres are at
    least 2 (r + margin) apart less how far each stands from its held sample (STOP_MARGIN, the goal
    tolerance, half a spacing while driving): 2 x 0.55 - 2 x 0.05 = 1.0 m. B's stop is the last sample
    clear of A's remaining path, so B stands at least r + margin + r + margin = 1.1 m (less a cell
    of 0.25 m and a spacing) short of the crossing, and never more than 3 m short (the cells a
    footprint reaches plus the braking distance at 1 m/s, 1.25 m). A, asking first, never waits:
    it arrives as a lone robot does (:func:`_alone`, within SLACK). Negative control: the same drive
    through zones that do not know the paths cross (B's path moved 100 m away) lets B through
    the crossing with A, and the bodies meet (centres closer than 2 r).
    """
    fleet = _cross()
    runs = _drive(fleet, ZoneControl([r.path for r in fleet], [RADIUS, RADIUS]))
    (ta, sa, wa), (tb, sb, wb) = runs
    moving_a = ~wa & (ta > 0.0) & (sa < fleet[0].s[-1] - GOAL_TOLERANCE)
    assert moving_a[1:np.argmax(sa >= fleet[0].s[-1] - GOAL_TOLERANCE)].all()          # A never waits
    arrive_a = ta[np.argmax(sa >= fleet[0].s[-1] - GOAL_TOLERANCE)]
    assert abs(arrive_a - _alone()) < SLACK, arrive_a
    # B's wait: standing between its start and its end, short of the crossing (y = s - 10)
    waiting = wb & (sb > 0.0) & (sb < fleet[1].s[-1] - GOAL_TOLERANCE)
    assert waiting.sum() * DT > 1.0
    y_wait = sb[waiting] - 10.0
    assert np.ptp(y_wait) < 1e-9                                    # one place, held still
    gap = -float(y_wait[0])
    reach = RADIUS + DEFAULT_MARGIN
    assert 2.0 * reach - 0.25 - SPACING - STOP_MARGIN < gap < 3.0, gap
    # and it went on once A had passed: A's body clear of B's path by the time B moves again
    restart = tb[np.flatnonzero(waiting)[-1]]
    assert np.interp(restart, ta, sa) - 10.0 > reach, np.interp(restart, ta, sa)
    clear = 2.0 * reach - 2.0 * max(STOP_MARGIN, GOAL_TOLERANCE, SPACING / 2.0)
    assert _closest(fleet, runs) >= clear - 1e-9
    # negative control: zones that do not see the crossing
    blind = ZoneControl([fleet[0].path, fleet[1].path + 100.0], [RADIUS, RADIUS])
    assert _closest(fleet, _drive(fleet, blind)) < 2.0 * RADIUS


def _alone(length: float = 20.0, v: float = 1.0) -> float:
    """When a lone robot driving ``length`` m at ``v`` reaches its goal tolerance [s] (closed form).

    From rest at ACCEL: v / a s for v^2 / 2a m; then full speed until the follower's goal braking
    ``sqrt(1.6 a (d - tol))`` falls below v, D = v^2 / 1.6 a before the goal tolerance; then a constant
    deceleration 0.8 a over D, which takes 2 D / v.
    """
    ramp, brake = v * v / (2.0 * ACCEL), v * v / (1.6 * ACCEL)
    return v / ACCEL + (length - GOAL_TOLERANCE - ramp - brake) / v + 2.0 * brake / v


def test_the_drive_ramps_and_brakes_as_the_follower_does():
    """A lone robot's 20 m at 1 m/s take the closed form's 22.2 s (:func:`_alone`) within SLACK.

    Negative control: the same without the goal braking (20.95 s) is outside it.
    """
    a = _cross()[0]
    t, s, _ = drive_draw([a], ZoneControl([a.path], [RADIUS]), [0.0], [1.0], [np.zeros(0)], dt=DT, accel=ACCEL)[0]
    arrive = t[np.argmax(s >= a.s[-1] - GOAL_TOLERANCE)]
    assert abs(arrive - _alone()) < SLACK, (arrive, _alone())
    no_braking = 1.0 / ACCEL + (20.0 - GOAL_TOLERANCE - 1.0)
    assert abs(no_braking - _alone()) > SLACK


def test_the_gate_assumes_the_goal_tolerance_the_simulated_follower_has():
    """planner.fleet.gate's copy of the follower's goal tolerance is the follower's own.

    The planner may not import sim (layers), so the sampled drive keeps a copy; this check fails
    the day one side changes without the other (an exact comparison of two constants: nothing to
    control for).
    """
    from sim.episode.follower import PurePursuit

    assert PurePursuit.goal_tolerance == GOAL_TOLERANCE   # the dataclass default
