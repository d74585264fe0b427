"""Parking: a robot that would finish where another robot has still to pass drives on to a parking place.

A fleet robot's last task may end on a dock that lies on another robot's path (a dock in an aisle,
a station on the only corridor). Zone control keeps such a dock for the robot passing it first
(:mod:`planner.fleet.zones`): the arriving robot waits short of it until the other has passed. That
costs the arriving robot the wait, and where it has nowhere to stand aside (its whole way lies
on the other's path) no robot can move. A robot that names a parking place (``[[robots]] park``,
a dock) instead drives its last task as planned and then on to that dock, planned like a task
(:func:`planner.plan.plan_route`: an admissible route with its measurement schedule): the dock of
its last task becomes a place on its path it passes, and the parking place its final dock.

**When it parks.** Robot i parks when another robot j passes its last task's dock (their
footprints under zone control share a cell) *later* than i would arrive there: j's last sample
meeting that dock is reached, on j's predicted timeline (:func:`planner.fleet.zones.predict_timeline`,
the stop rule, without parking), after i's start time plus its drive time as planned alone (no
waits: the earliest it could stand there). A robot j that passed earlier (the one i traded docks
with, which left at the start) does not make i park. Where the stop rule cannot drive the fleet
at all (no robot can move) every such dock counts as passed later.

**Where.** A parking place lies off every other robot's path (no shared zone cell with any of
their samples, parking legs included), so a parked robot is in nobody's way: zone control's
argument for docks clear of the other robots' paths then holds for it (:mod:`planner.fleet.zones`).
A named place on another robot's path is refused, naming both. A robot whose dock lies on a
later path and that names no parking place waits as before. Only where the fleet then cannot move
(robots meeting head-on routed around each other too) the planner picks one for it
(:func:`pick_parking`): the nearest dock of the scenario that no robot starts, ends or parks at
and that lies off every other robot's path, with an admissible route to it; where there is none,
planning is refused naming the robot, its dock and the robot that must pass it
(:func:`blocking_docks`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from planner.fleet.zones import Timeline, ZoneControl
from planner.plan import plan_route
from planner.schedule.pathtime import Kinematics
from scenarios.errors import PlanningError
from scenarios.schema import Scenario


def passage_time(timeline: Timeline | None, s: float) -> float:
    """Return the time [s] a robot's predicted ``timeline`` first reaches arc length ``s`` [m].

    inf: never, or no timeline.
    """
    if timeline is None:
        return float("inf")
    reached = np.flatnonzero(np.asarray(timeline.s) >= s - 1e-9)
    return float(timeline.t[reached[0]]) if len(reached) else float("inf")


def later_passers(zones: ZoneControl, fleet: Sequence, timelines: Sequence[Timeline] | None) -> list[int]:
    """For each robot, another robot that passes its final dock later than it could arrive there (-1: none).

    Parameters
    ----------
    zones : ZoneControl
        Zone control of the fleet's paths (``zones.paths[i]`` is ``fleet[i].path``); only read.
    fleet : sequence of FleetRobotPlan
        Each robot's plans (``path``, ``s``, ``speed``, ``start_time``).
    timelines : sequence of Timeline, optional
        The fleet's predicted timelines; None: the stop rule could not drive the fleet, and every
        robot whose path meets a final dock counts as passing it later.

    Returns
    -------
    list of int
        Per robot the index of the first such robot, or -1.
    """
    out = []
    for i, r in enumerate(fleet):
        last = len(zones.paths[i]) - 1
        arrive = float(r.start_time) + float(Kinematics(r.s, r.speed).t_v[-1])
        meets = zones.meets(i, last)
        who = -1
        for j in np.flatnonzero(meets >= 0).tolist():
            if j == i:
                continue
            t = passage_time(None if timelines is None else timelines[j], float(zones.s[j][meets[j]]))
            if t > arrive:
                who = j
                break
        out.append(who)
    return out


#: Most docks :func:`pick_parking` tries to plan a route to, nearest first, for one robot (each
#: attempt is a full route search with its schedule: seconds on a big floor).
PICK_TRIES = 3


def pick_parking(scenario: Scenario, fleet: Sequence, zones: ZoneControl, i: int, own: Scenario,
                 pef) -> tuple[str, object] | None:
    """Pick a parking place for robot ``i`` that names none; return it and the leg's plan (None: none found).

    Candidates: the scenario's docks that no robot starts, ends or parks at, whose position lies
    farther from every other robot's path (its samples, ``zones.paths``) than the two robots'
    reaches plus two cell diagonals (so that no zone cell can be shared; :func:`check_parking`
    checks the cells themselves afterwards), nearest to robot ``i``'s last dock first; the first of
    :data:`PICK_TRIES` with an admissible route from there wins.
    """
    used = set()
    for r in fleet:
        used.update(p.start for p in r.plans)
        used.update(p.goal for p in r.plans)
        if getattr(r.declared, "park", None) is not None:
            used.add(r.declared.park)
    here = np.asarray(zones.paths[i][-1], float)
    gap = 2.0 * math.sqrt(2.0) * zones.grid.cell
    found = []
    for d in scenario.docks:
        if d.name in used:
            continue
        p = np.asarray(d.position, float)
        clear = all(float(np.hypot(*(zones.paths[j] - p).T).min()) > zones.reach[i] + zones.reach[j] + gap
                    for j in range(len(fleet)) if j != i)
        if clear:
            found.append((float(np.hypot(*(p - here))), d.name))
    for _, name in sorted(found)[:PICK_TRIES]:
        try:
            return name, plan_route(own, fleet[i].plans[-1].goal, name, pef=pef)
        except PlanningError:
            continue
    return None


def add_parking(scenario: Scenario, fleet: list, owns: Sequence[Scenario], pefs: dict, passers: Sequence[int],
                chain: Callable, pick: bool = False) -> list[int]:
    """Give each robot that names a parking place and has a later passer a last leg to it (in place).

    Parameters
    ----------
    scenario : Scenario
    fleet : list of FleetRobotPlan
        Modified in place: a parking robot's ``plans`` get the leg, ``path``, ``s``, ``speed`` and
        ``offsets`` are chained again and ``park`` names the dock.
    owns : sequence of Scenario
        Each robot's scenario (its declared robot).
    pefs : dict
        The PEF of each declared robot spec.
    passers : sequence of int
        :func:`later_passers`.
    chain : callable
        :func:`planner.fleet.plan.chain`.
    pick : bool
        Pick a parking place (:func:`pick_parking`) for a robot with a later passer that names
        none: the stop rule could not drive the fleet.

    Returns
    -------
    list of int
        The robots that got a parking leg.

    Raises
    ------
    PlanningError
        The leg has no admissible route.
    """
    parked = []
    for i, (r, j) in enumerate(zip(fleet, passers, strict=True)):
        park = getattr(r.declared, "park", None)
        if j < 0 or r.park is not None or (park is None and not pick):
            continue
        goal = r.plans[-1].goal
        if park is None:
            # the fleet's paths as they are now (earlier robots' parking legs included)
            zones = ZoneControl([q.path for q in fleet], [q.robot.radius for q in fleet])
            picked = pick_parking(scenario, fleet, zones, i, owns[i], pefs[r.robot])
            if picked is None:
                continue
            park, leg = picked
        else:
            try:
                leg = plan_route(owns[i], goal, park, pef=pefs[r.robot])
            except PlanningError as exc:
                raise PlanningError(f"{r.name} parks at {park!r} ({goal!r} lies on {fleet[j].name}'s later path), "
                                    f"but {exc}") from None
        r.plans = [*r.plans, leg]
        r.path, r.s, r.speed, r.offsets = chain(r.plans)
        r.park = park
        parked.append(i)
    return parked


def check_parking(zones: ZoneControl, fleet: Sequence) -> None:
    """Refuse a parking place that lies within reach of another robot's path (module docstring: where)."""
    for i, r in enumerate(fleet):
        if r.park is None:
            continue
        meets = zones.meets(i, len(zones.paths[i]) - 1)
        others = [j for j in np.flatnonzero(meets >= 0).tolist() if j != i]
        if others:
            x, y = zones.paths[i][-1]
            j = others[0]
            raise PlanningError(f"{r.name}'s parking place {r.park!r} ({x:.2f}, {y:.2f}) lies within "
                                f"{zones.reach[i] + zones.reach[j]:.2f} m of {fleet[j].name}'s path: "
                                f"a parking place must be off every other robot's path")


def blocking_docks(zones: ZoneControl, fleet: Sequence, passers: Sequence[int]) -> str:
    """Name the robots that finish on another's later path without a parking place (empty: none).

    For the refusal of a fleet the stop rule cannot drive: ``"; r1's final dock 'B' (x, y) lies on
    r2's path: name a parking place for r1 ([[robots]] park)"``.
    """
    out = []
    for i, (r, j) in enumerate(zip(fleet, passers, strict=True)):
        if j >= 0 and r.park is None:
            x, y = zones.paths[i][-1]
            out.append(f"{r.name}'s final dock {r.plans[-1].goal!r} ({x:.2f}, {y:.2f}) lies on {fleet[j].name}'s "
                       f"path: name a parking place for {r.name} ([[robots]] park)")
    return "; ".join(out)
