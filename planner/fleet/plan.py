"""Planning a fleet: each robot's tasks with the single-robot planner, chained, and the zone timeline.

:func:`plan_fleet` plans every task of every robot of a scenario's ``[[robots]]`` with
:func:`planner.plan.plan_task` (the robot's own declared spec, so a robot that overrides
``radius`` or ``max_speed`` gets its own clearance and speeds), chains each robot's plans into
one path (task i+1 starts at the dock task i ended at, checked by the loader) and predicts,
through zone control (:mod:`planner.fleet.zones`), when each robot is where, waits included. A
robot whose last dock another robot passes later drives on to its parking place when it names
one, or when the fleet cannot move otherwise and the planner finds one (:mod:`planner.fleet.parking`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from planner.fleet import exposure
from planner.fleet.exposure import RobotBlocking
from planner.fleet.parking import add_parking, blocking_docks, check_parking, later_passers
from planner.fleet.traffic import TrafficNote, plan_traffic
from planner.fleet.zones import Timeline, ZoneControl, predict_timeline
from planner.plan import Plan, plan_route, plan_task
from planner.schedule.pathtime import Kinematics
from scenarios.errors import PlanningError
from scenarios.schema import FleetRobot, RobotSpec, Scenario


@dataclass
class FleetRobotPlan:
    """One robot's plans.

    Attributes
    ----------
    name : str
    plans : list of Plan
        One per task, in driving order, and the leg to its parking place last when it parks.
    start_time : float
        When it leaves its first dock [s].
    robot : RobotSpec
        Its declared spec (what it was planned with).
    offsets : ndarray, shape (len(plans),)
        Arc length along the whole path where each task's plan begins [m].
    path : ndarray, shape (N, 2)
        The whole path: the plans' paths chained (each junction dock once) [m].
    s : ndarray, shape (N,)
        Arc length along ``path`` [m].
    speed : ndarray, shape (N,)
        Planned speed along ``path`` [m/s] (0 at each task's goal).
    timeline : Timeline
        Predicted drive in space and time under zone control.
    blocking : RobotBlocking
        Predicted blocking of its scheduled fixes by the other robots (:mod:`planner.fleet.exposure`).
    alone_blocking : RobotBlocking
        The same for its schedule planned as if alone (``blocking`` itself without traffic): where
        the others hide what a lone robot would count on.
    alone_time : float
        Its drive time as planned alone: the schedule of one robot, no waits [s].
    declared : FleetRobot, optional
        Its ``[[robots]]`` table: the timing spread its blocking prediction assumes
        (:mod:`planner.fleet.timing`).
    park : str, optional
        The dock it drives on to after its last task, its parking place (the last of ``plans``;
        :mod:`planner.fleet.parking`); None: it stays at its last task's dock.
    """

    name: str
    plans: list[Plan]
    start_time: float
    robot: RobotSpec
    offsets: np.ndarray
    path: np.ndarray
    s: np.ndarray
    speed: np.ndarray
    timeline: Timeline | None = None
    blocking: RobotBlocking | None = None
    alone_blocking: RobotBlocking | None = None
    alone_time: float = math.nan
    declared: FleetRobot | None = None
    park: str | None = None

    @property
    def time(self) -> float:
        """Planned drive time from its start to its final dock, zone waits included [s]."""
        return float(self.timeline.end_time - self.start_time)


@dataclass
class FleetPlan:
    """A fleet's plans: ``robots[i]`` for ``scenario.robots[i]``; ``traffic``: the flag it was planned with.

    ``note`` says how the traffic-aware schedule came about (None with ``traffic`` False).
    ``order``: the planned order of passage the robots keep (:meth:`ZoneControl.precedence`) when
    the stop rule alone could deadlock (a dock on another robot's path); None: the stop rule.
    """

    robots: list[FleetRobotPlan]
    traffic: bool
    note: TrafficNote | None = None
    order: list[np.ndarray] | None = None


def chain(plans: list[Plan]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Chain plans driven one after another into one path.

    Returns
    -------
    path : ndarray, shape (N, 2)
    s : ndarray, shape (N,)
    speed : ndarray, shape (N,)
    offsets : ndarray, shape (len(plans),)
        Arc length where each plan begins [m].
    """
    pts, spd, offsets = [], [], []
    total = 0.0
    for j, p in enumerate(plans):
        offsets.append(total)
        first = 0 if j == 0 else 1      # the junction dock is the previous plan's last point
        pts.append(np.asarray(p.path, float)[first:])
        spd.append(np.asarray(p.speed, float)[first:])
        total += float(p.s[-1])
    path = np.concatenate(pts)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(path, axis=0).T))])
    return path, s, np.concatenate(spd), np.array(offsets)


def zones_of(fleet: list[FleetRobotPlan], order: list[np.ndarray] | None = None, record: bool = False) -> ZoneControl:
    """Fresh zone control of the fleet's whole paths (``order``: :class:`ZoneControl`'s ``after``)."""
    return ZoneControl([r.path for r in fleet], [r.robot.radius for r in fleet], [r.name for r in fleet],
                       after=order, record=record)


#: Traffic density the rerouting of :func:`_reroute` puts on the segments the robots before a robot drive.
REROUTE_TRAFFIC = 1.0


def _reroute(scenario: Scenario, fleet: list[FleetRobotPlan], owns: list[Scenario], pefs: dict) -> None:
    """Replan each robot but the first with the segments of the robots before it as busy (in place).

    The route network's ``traffic`` criterion (:mod:`planner.routes.criteria`) gets density
    :data:`REROUTE_TRAFFIC` on every segment an earlier robot's chosen routes use, and comes first
    in the choice (lexicographic, the scenario's own choice breaking ties): a robot takes the way
    the others use least where there is one (a second aisle for robots swapping docks).
    """
    busy: set[frozenset[str]] = set()
    for k, r in enumerate(fleet):
        if k:
            net = scenario.routes
            traffic = dict(net.traffic)
            for a, b in net.segments:
                if frozenset((a, b)) in busy:
                    traffic[f"{a}-{b}"] = max(net.traffic_of(a, b), REROUTE_TRAFFIC)
                    traffic.pop(f"{b}-{a}", None)
            # busy segments first, then the scenario's own choice (its order, or its weights as the tie-break)
            rest = tuple(c for c in owns[k].planning.order if c != "traffic")
            planning = replace(owns[k].planning, order=("traffic", *rest))
            own = replace(owns[k], routes=replace(net, traffic=traffic), planning=planning)
            try:
                plans = [plan_task(own, i, pef=pefs[r.robot]) for i in r.declared.tasks]
                if r.park is not None:
                    plans.append(plan_route(own, plans[-1].goal, r.park, pef=pefs[r.robot]))
            except PlanningError:
                plans = r.plans
            r.plans = plans
            r.path, r.s, r.speed, r.offsets = chain(plans)
        for p in r.plans:
            nodes = p.candidates[p.chosen].nodes if p.chosen is not None else None
            busy.update(frozenset(e) for e in zip(nodes or (), (nodes or ())[1:], strict=False))


def plan_fleet(scenario: Scenario, *, traffic: bool = True, pef=None) -> FleetPlan:
    """Plan every robot of ``scenario.robots``: its tasks in order, and the fleet's timeline.

    Parameters
    ----------
    scenario : Scenario
        A fleet scenario (``[[robots]]``).
    traffic : bool
        Plan with the other robots in mind: the traffic-aware measurement schedule
        (:mod:`planner.fleet.traffic`); False plans each robot's schedule as if it drove alone.
        Either way each fix's predicted blocking is in ``blocking`` (:mod:`planner.fleet.exposure`).
    pef : planner.pef.map.PEF, optional
        The PEF of the scenario (default built once here); robots whose declared spec differs
        from ``scenario.robot`` get their own.

    Returns
    -------
    FleetPlan

    Raises
    ------
    PlanningError
        Not a fleet scenario, a task or parking leg without an admissible route, a parking place
        on another robot's path, or a fleet zone control cannot drive (no robot can move; the
        message names each robot whose last dock lies on another's path and that got no parking place).
    """
    if not scenario.robots:
        raise PlanningError(f"scenario {scenario.name!r} has no [[robots]]: plan its tasks one by one")
    from planner.pef.map import PEF
    if pef is None:
        pef = PEF(scenario)
    pefs = {scenario.robot: pef}
    fleet, owns = [], []
    for fr in scenario.robots:
        own = replace(scenario, robot=fr.robot, robot_actual=fr.robot_actual)
        owns.append(own)
        if fr.robot not in pefs:
            pefs[fr.robot] = PEF(own)
        plans = []
        for i in fr.tasks:
            try:
                plans.append(plan_task(own, i, pef=pefs[fr.robot]))
            except PlanningError as exc:
                raise PlanningError(f"{scenario.source}: robots: {fr.name!r}, task {i}: {exc}") from None
        path, s, speed, offsets = chain(plans)
        fleet.append(FleetRobotPlan(fr.name, plans, fr.start_time, fr.robot, offsets, path, s, speed, declared=fr))

    def drive() -> tuple[list | None, PlanningError | None]:
        """Return the fleet's timelines under the stop rule, or None and why no robot can move."""
        try:
            return predict_timeline(zones_of(fleet), [Kinematics(r.s, r.speed) for r in fleet],
                                    [r.start_time for r in fleet]), None
        except PlanningError as exc:
            if "no robot can move" not in str(exc):
                raise
            return None, exc

    passers: list[int] = []
    try:
        timelines, jam = drive()
        # a robot that would finish where another passes later drives on to the parking place it names
        passers = later_passers(zones_of(fleet), fleet, timelines)
        if add_parking(scenario, fleet, owns, pefs, passers, chain):
            check_parking(zones_of(fleet), fleet)
            timelines, jam = drive()
        if jam is not None and scenario.routes is not None and len(fleet) >= 2:
            # robots that trade docks along one route meet head-on with nowhere to stand aside:
            # route each robot around the segments of the robots before it, where the network allows
            _reroute(scenario, fleet, owns, pefs)
            check_parking(zones_of(fleet), fleet)
            timelines, jam = drive()
        if jam is not None:
            # still nobody can move: robots finishing on another's path get a parking place picked
            passers = later_passers(zones_of(fleet), fleet, None)
            if add_parking(scenario, fleet, owns, pefs, passers, chain, pick=True):
                check_parking(zones_of(fleet), fleet)
                timelines, jam = drive()
        if jam is not None:
            docks = blocking_docks(zones_of(fleet), fleet, passers)
            raise PlanningError(f"{jam}" + (f"; {docks}" if docks else ""))
    except PlanningError as exc:
        raise PlanningError(f"{scenario.source}: robots: {exc}") from None
    for r, tl in zip(fleet, timelines, strict=True):
        r.timeline = tl
        r.alone_time = float(Kinematics(r.s, r.speed).t_v[-1])
    alone = exposure.predict(scenario, fleet)
    note = None
    if traffic:
        note = plan_traffic(scenario, fleet, owns, [pefs[r.robot] for r in fleet], zones_of, chain)
    for r, b in zip(fleet, alone, strict=True):
        r.alone_blocking = b
    for r, b in zip(fleet, exposure.predict(scenario, fleet) if traffic else alone, strict=True):
        r.blocking = b
    order = None
    zones = zones_of(fleet, record=True)
    if zones.dock_conflict is not None:
        # a dock on another robot's path: the robots keep the order of passage of the plan's
        # timeline, which cannot deadlock whatever their timing (planner.fleet.zones)
        predict_timeline(zones, [Kinematics(r.s, r.speed) for r in fleet], [r.start_time for r in fleet])
        order = zones.precedence()
    return FleetPlan(robots=fleet, traffic=traffic, note=note, order=order)
