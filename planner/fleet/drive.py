"""A fleet driven kinematically through its zone gate, in one draw of its timing spread.

The sampled blocking prediction (:mod:`planner.fleet.sampled`) and the measurement schedule's
risk need to know where each robot of a fleet is at each moment of a run whose timing varies as
the scenario declares (:mod:`planner.fleet.timing`: a release delay, a speed factor, dwells). The
plan's own timeline (:func:`planner.fleet.zones.predict_timeline`) reserves step by step and stands
at the reservation's end, which is not where the simulated robots wait. So each draw drives the
fleet through its zone control with the simulation's own gate (:func:`planner.fleet.gate.zone_cap`:
release behind, request up to the braking distance ahead, stop ``STOP_MARGIN`` short of the
reservation's end), at the simulation's control step, so that a robot waits where and as long as
the simulated one does. In each draw a robot

* leaves ``start_time + U J`` (plus the standstill fix on its dock) and is commanded its path
  follower's speed: its planned speed times f, braked for its task's end as the follower brakes,
  changed by at most :data:`planner.schedule.promise.FOLLOWER_MAX_ACCEL` per second: the ramp from
  rest at each start and after each zone wait comes out of it; it gains :data:`CORNER_GAIN` of
  arc length per radian its path turns, as the follower cuts the corners;
* stands its dwell at each dock between two tasks, and on its final dock once there;
* stands where the gate stops it while it waits.

How close that comes to the episodes is measured by ``benchmarks/fleet_timelines.py``
(docs/benchmarks.md, ``fleet_timelines``).
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Iterable, Iterator, Sequence

import numpy as np

from planner.fleet.gate import BRAKE, CREEP_SPEED, GOAL_TOLERANCE, STOP_MARGIN, zone_cap
from planner.fleet.zones import ZoneControl, predict_timeline
from planner.schedule.pathtime import Kinematics
from planner.schedule.promise import FOLLOWER_MAX_ACCEL
from scenarios.errors import PlanningError

#: Time step of the sampled timelines [s] (that of the plan's own timeline).
DT = 0.05
#: Arc length a simulated robot gains on its path per radian it turns [m/rad]: the pure-pursuit
#: follower cuts inside each corner, so its projection on the path runs ahead of the distance it
#: drove. Measured on ``warehouse-fleet-spread`` (30 s spread, 40 episodes against the kinematic
#: drive of each run's own draws, the runs where neither waits): the lag grows 0.04 (r2) and 0.067
#: (r3) m per radian of the path's cumulative turning, 1110 points; pooled 0.06.
CORNER_GAIN = 0.06


def _lerp(xs: list, ys: list, x: float) -> float:
    """``np.interp`` of one scalar on lists (the drive's inner loop asks a few times a tick)."""
    k = bisect.bisect_right(xs, x)
    if k <= 0:
        return ys[0]
    if k >= len(xs):
        return ys[-1]
    x0, x1 = xs[k - 1], xs[k]
    return ys[k - 1] + (ys[k] - ys[k - 1]) * ((x - x0) / (x1 - x0) if x1 > x0 else 0.0)


def drive_draw(robots: Sequence, zones: ZoneControl, starts: Sequence[float], factors: Sequence[float],
               dwells: Sequence[np.ndarray], hold: float = 0.0, dt: float = DT, accel: float = FOLLOWER_MAX_ACCEL
               ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Drive the fleet kinematically through its zones as the simulation does, in one draw of its timing.

    Each control tick of ``dt`` every robot in index order (as the simulation's robots tick) is
    commanded its path follower's speed: the planned speed at its place times its factor (at most
    its ``max_speed``), at most the speed from which it stops within the goal tolerance at its
    task's end (the follower's ``sqrt(2 BRAKE a d)``, creeping at ``CREEP_SPEED``), and changed by at most
    ``a dt`` from the last; the zone gate (:func:`planner.fleet.gate.zone_cap`, the simulation's
    own rule) then releases behind it, requests ahead and caps it, or has it stand at its stop.
    Its arc length advances by the mean of the two ticks' speeds (exact for a constant
    acceleration). A robot stands on its dock until ``starts[i]`` (plus ``hold``, the standstill
    fix, when its first fix is on the dock), at each task's end for its dwell, and, arrived, on its
    final dock (:meth:`planner.fleet.zones.ZoneControl.stand`, as the simulation's robot does).

    Parameters
    ----------
    robots : sequence of FleetRobotPlan
    zones : ZoneControl
        Fresh zone control of the fleet (consumed).
    starts : sequence of float
        Release of each robot [s].
    factors : sequence of float
        Speed factor of each robot.
    dwells : sequence of ndarray
        Per robot, its dwell at the end of each of its tasks but the last [s].
    hold : float
        Time the standstill fix on the start dock takes [s].
    dt : float
        Control period [s].
    accel : float
        The path follower's acceleration limit [m/s^2].

    Returns
    -------
    list of (t, s, stand)
        Per robot, the ticks' times (T,) [s], arc lengths (T,) [m] and whether it stood (T,) bool.
    """
    n = len(robots)
    ends = [list(np.asarray(r.offsets, float)[1:]) + [float(r.s[-1])] for r in robots]
    # distance driven to reach each path sample: the follower cuts the corners (CORNER_GAIN)
    driven = []
    for r in robots:
        d = np.diff(np.asarray(r.path, float), axis=0)
        turn = np.abs(np.diff(np.unwrap(np.arctan2(d[:, 1], d[:, 0])))) if len(d) > 1 else np.zeros(0)
        # cumulative turning at each sample: the turn at a vertex between its two segments
        theta = np.concatenate([[0.0], np.cumsum(turn), [turn.sum()]])[:len(r.s)]
        u = np.maximum.accumulate(np.asarray(r.s, float) - CORNER_GAIN * theta)
        # strictly increasing (the running maximum holds u flat along a sharp turn), so that _lerp
        # back from driven distance to arc length has one answer; 1e-9 m per sample moves no place
        driven.append((u + 1e-9 * np.arange(len(u))).tolist())
    path_s = [np.asarray(r.s, float).tolist() for r in robots]
    speeds = [np.asarray(r.speed, float).tolist() for r in robots]
    u_now = [0.0] * n
    first_on_dock = [any(len(p.schedule.fixes) and p.schedule.fixes[0].s <= 1e-9 for p in r.plans[:1])
                     for r in robots]
    go = [float(starts[i]) + (hold if first_on_dock[i] else 0.0) for i in range(n)]
    s, v = [0.0] * n, [0.0] * n
    task, until = [0] * n, [None] * n
    done = [False] * n
    rows = [[(0.0, 0.0, True)] for _ in range(n)]
    max_time = 10.0 * (max(go) + max(float(Kinematics(r.s, r.speed).t_v[-1]) for r in robots) + 60.0)
    t = 0.0
    while not all(done):
        if t > max_time:
            raise PlanningError("zone control: the sampled fleet had not arrived after "
                                f"{max_time:.0f} s")
        for i, r in enumerate(robots):
            if done[i] or t < go[i] - 1e-9:
                rows[i].append((t + dt, s[i], True))
                continue
            end = ends[i][task[i]]
            if until[i] is not None:
                # dwelling at the end of a task
                if t < until[i] - 1e-9:
                    rows[i].append((t + dt, s[i], True))
                    continue
                until[i] = None
                task[i] += 1
                end = ends[i][task[i]]
            if end - s[i] < GOAL_TOLERANCE:
                v[i] = 0.0
                if task[i] + 1 < len(ends[i]):
                    until[i] = t + float(dwells[i][task[i]])
                else:
                    done[i] = True
                    zones.stand(i)
                rows[i].append((t + dt, s[i], True))
                continue
            ref = min(_lerp(path_s[i], speeds[i], s[i]) * factors[i], r.robot.max_speed,
                      math.sqrt(2.0 * BRAKE * accel * max(end - s[i] - GOAL_TOLERANCE, 0.0)))
            ref = max(ref, CREEP_SPEED)
            cmd = min(max(ref, v[i] - accel * dt), v[i] + accel * dt)
            cap = zone_cap(zones, i, s[i], cmd, accel)
            new = min(cmd, cap)
            if new > 0.0:
                room = zones.reserved_to(i) - STOP_MARGIN if math.isfinite(cap) else end
                u_room = _lerp(path_s[i], driven[i], room)
                u_now[i] = max(u_now[i], min(u_now[i] + 0.5 * (v[i] + new) * dt, u_room))
                s[i] = _lerp(driven[i], path_s[i], u_now[i])
            v[i] = new
            rows[i].append((t + dt, s[i], new == 0.0))
        t += dt
    out = []
    for i in range(n):
        arr = np.array(rows[i], dtype=float)
        out.append((arr[:, 0], arr[:, 1], arr[:, 2] > 0.5))
    return out


def passage_order(robots: Sequence) -> list[np.ndarray] | None:
    """Return the plan's order of passage when a dock lies on another's path (as ``plan_fleet`` records it)."""
    zones = fresh_zones(robots, None, record=True)
    if zones.dock_conflict is None:
        return None
    predict_timeline(zones, [Kinematics(r.s, r.speed) for r in robots], [r.start_time for r in robots])
    return zones.precedence()


def fresh_zones(robots: Sequence, order, record: bool = False) -> ZoneControl:
    """Return a fresh zone control of the fleet's paths, kept in ``order`` (:func:`passage_order`) where given."""
    return ZoneControl([r.path for r in robots], [r.robot.radius for r in robots], [r.name for r in robots],
                       after=order, record=record)


def hold_time(scenario) -> float:
    """Time the standstill fix on the start dock holds a robot there [s]: it measures its markers one by one."""
    return scenario.sensor.measurement_time * scenario.sensor.markers_per_fix


def drive_timings(scenario, robots: Sequence, timing: Sequence
                  ) -> list[list[tuple[np.ndarray, np.ndarray, np.ndarray]]]:
    """Drive the fleet (:func:`drive_draw`) once per given draw of its timing, through fresh zones each time.

    ``timing``: per draw, each robot's release [s], speed factor and dwells [s] (as
    :func:`planner.fleet.sampled.predict_sampled`'s ``timing``). Returns per draw, per robot, (t, s, stand) as
    :func:`drive_draw` does.
    """
    return list(iter_drives(scenario, robots, timing))


def iter_drives(scenario, robots: Sequence, timing: Iterable
                ) -> Iterator[list[tuple[np.ndarray, np.ndarray, np.ndarray]]]:
    """Yield :func:`drive_timings`'s drives one draw at a time (memory of one draw, not of all)."""
    order = passage_order(robots)
    hold = hold_time(scenario)
    for st, f, dw in timing:
        yield drive_draw(robots, fresh_zones(robots, order), st, f, dw, hold=hold)
