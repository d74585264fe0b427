"""A fleet episode: every robot of ``[[robots]]`` in one physics world, under zone control.

Each robot is a :class:`sim.episode.driver.RobotDriver`, as a lone robot is
(:mod:`sim.episode.drive`): its own wheels, encoders, odometry, filter, laser, fix recorder and
random streams; robot 0 draws from exactly the streams a lone robot would, robot i > 0 from
streams spawned under the key (4, i). The robots share the physics steps and the control ticks;
what the fleet adds is scheduled here. At each control tick a robot

* asks zone control (its :class:`ZoneGate`, :mod:`planner.fleet.zones`) for the floor up to its braking distance
  ahead, releases what it has left behind, and is slowed so that it stops at the end of its
  reservation; it waits there parked (:meth:`sim.physics.robot.DiffDriveRobot.park`), holding
  its stop's cells alone (:meth:`planner.fleet.zones.ZoneControl.stand`);
* starts its scheduled fixes as a lone robot does; before a fix it checks which scheduled
  markers another robot's body hides (the fix's note: ``FixLog.notes``, a ``FixNote``: marker
  index -> robot, and the plan's probability of it), and every other line of sight within range
  a robot hides there (``FixNote.sight_hidden``: what the laser would see without the robots).
  Those lines of sight count as blocked for the fix, as ``sensor.block_probability``'s do: the
  robot measures the schedule's fallback, or improvises beyond what the plan promised
  (``beyond_redundancy``), and the single-failure test (runs column ``lost_guarantee``) judges
  the robot's certified bound wherever a fix lost at most one of them.

Each robot keeps the timing its run drew from its declared spread (:mod:`planner.fleet.timing`,
from a stream of its own under the episode's seed): it leaves its first dock that much later,
dwells at each dock between two tasks, and drives at that fraction of its planned speeds
(:class:`sim.episode.driver.Mission`). When a dock lies on another robot's path the zones keep
the plan's order of passage (``FleetPlan.order``, :mod:`planner.fleet.zones`).

Robot bodies are cylinders of each robot's radius and height that only rays see
(:meth:`sim.physics.world.PhysicsWorld.place_bodies`); the bodies are moved to the robots before
every fix start and measurement. ``FleetResult.collisions`` counts pairs of those bodies that start to
overlap (pybullet's closest points below 0) at the control ticks; each robot's row counts the contact
episodes of its own physical body with anything but the floor, other robots included, and says
whether it stuck or deadlocked (:mod:`sim.episode.outcome`).

Each robot drives its tasks in order; its results are one :class:`EpisodeResult` over all of
them (steps and fixes concatenated, the certified bound along its whole path).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from planner.fleet import timing as fleet_timing
from planner.fleet.gate import zone_cap
from planner.fleet.plan import FleetPlan, FleetRobotPlan, plan_fleet, zones_of
from scenarios import PlanningError, Scenario, SimulationError
from sim.episode.drive import check_markers, seed_sequence
from sim.episode.driver import Mission, RobotDriver, advance, check_control_period
from sim.episode.follower import SPEED, YAW_RATE
from sim.episode.outcome import longest_run, wait_bound, wait_cycles
from sim.episode.types import FleetResult, RobotResult


@dataclass
class FleetPrepared:
    """What a fleet episode needs that does not depend on its seed: the fleet's plans and the PEF."""

    plan: FleetPlan
    pef: object


def prepare_fleet(scenario: Scenario, pef=None, traffic: bool = True) -> FleetPrepared:
    """Plan the fleet of ``scenario`` once (raises PlanningError if it cannot)."""
    from planner.pef.map import PEF

    check_markers(scenario)
    pef = pef if pef is not None else PEF(scenario)
    plan = plan_fleet(scenario, traffic=traffic, pef=pef)
    for rp in plan.robots:
        if any(p.schedule is None for p in rp.plans):
            raise PlanningError(f"{scenario.source}: robot {rp.name!r}: a plan has no measurement schedule")
    return FleetPrepared(plan, pef)


class ZoneGate:
    """Zone control for one robot of a fleet (:mod:`planner.fleet.zones`): the fleet's part of its drive.

    At each tick it drives, the robot releases the floor it has left behind, asks for the floor up
    to its braking distance ahead, and is slowed so that it stops at the end of its reservation
    (:meth:`limit`); it waits there parked, holding its stop's cells alone. At its final dock it
    keeps the dock's cells (:meth:`stand`).
    """

    def __init__(self, zones, i: int) -> None:
        self.zones, self.i = zones, i
        self.reserved: list[tuple[float, float, float]] = []

    def holder(self) -> int:
        """Return the robot whose reservation refused this one's request at the last tick (-1: none)."""
        return self.zones.refused_by[self.i]

    def stand(self) -> None:
        """Hold only the cells of where the robot stands (:meth:`planner.fleet.zones.ZoneControl.stand`)."""
        self.zones.stand(self.i)

    def limit(self, d: RobotDriver, t: float, v: float, omega: float) -> tuple[float, float]:
        """Cap the command to stop at the end of its reservation, count the wait, log the reservation."""
        v, omega = self._cap(d, v, omega)
        self.reserved.append((t, d.offset + d.s_now, self.zones.reserved_to(self.i)))
        return v, omega

    def _cap(self, d: RobotDriver, v: float, omega: float) -> tuple[float, float]:
        cap = zone_cap(self.zones, self.i, d.offset + d.s_now, v, d.follower.max_accel)
        if cap == 0.0:
            # it stands at its stop, parked (planner.fleet.gate: it holds the stop's cells alone)
            d.body.park(True)
            d.waited += d.dt_ctrl
            d.waiting = True
            d.follower.state[SPEED], d.follower.state[YAW_RATE] = 0.0, 0.0
            return 0.0, 0.0
        d.body.park(False)
        if v <= cap:
            return v, omega
        w = omega * cap / v if v > 0.0 else omega
        d.follower.state[SPEED], d.follower.state[YAW_RATE] = cap, w
        return cap, w


def _robot_result(d: RobotDriver, gate: ZoneGate, rp: FleetRobotPlan, name: str, scenario: Scenario) -> RobotResult:
    """Return robot ``d``'s episode with the fleet's columns: its name, arrival, waits and hidden lines of sight."""
    timeline = rp.timeline
    extra = {"robot": name, "arrival": d.arrival, "wait_time": d.waited, "robot_blocked": d.robot_blocked,
             "predicted_wait": longest_run(timeline.waiting, timeline.t) if timeline is not None else math.nan,
             "predicted_wait_time": float(timeline.wait_time) if timeline is not None else math.nan}
    res = d.result(scenario.name, extra)
    return RobotResult(name, res, d.waited, np.array(gate.reserved, dtype=float).reshape(-1, 3), rp.path)


def run_fleet_episode(scenario: Scenario, seed: int | np.random.SeedSequence = 0, world=None,
                      prepared: FleetPrepared | None = None, time_limit: float | None = None,
                      q_scale: float = 1.0) -> FleetResult:
    """Drive every robot of ``scenario.robots`` through its tasks, together, once.

    Parameters
    ----------
    scenario : Scenario
        A fleet scenario (``[[robots]]``).
    seed : int or numpy.random.SeedSequence
        Root of the episode's random streams (robot 0 draws what a single robot would).
    world : sim.physics.world.PhysicsWorld, optional
        A fleet world (``fleet=True``) of ``scenario`` to reuse; by default one is built and closed.
    prepared : FleetPrepared, optional
        The fleet's plans (:func:`prepare_fleet`; computed here when not given).
    time_limit : float, optional
        Give up after this many simulated seconds [s]; default 3x the predicted end + 30 s.
    q_scale : float
        Multiplies every filter's process noise (negative controls).

    Returns
    -------
    FleetResult
    """
    from sim.physics.world import PhysicsWorld

    if not scenario.robots:
        raise SimulationError(f"{scenario.source}: robots: not a fleet scenario (no [[robots]])")
    ss = seed_sequence(seed)
    prepared = prepared if prepared is not None else prepare_fleet(scenario)
    own_world = world is None
    world = PhysicsWorld(scenario, fleet=True) if own_world else world
    try:
        return _drive_fleet(scenario, ss, world, prepared, time_limit, q_scale)
    finally:
        if own_world:
            world.close()


def _drive_fleet(scenario, ss, world, prepared, time_limit, q_scale) -> FleetResult:
    dt_ctrl = check_control_period(world)
    plans = prepared.plan.robots
    predicted_end = max(float(rp.timeline.end_time) for rp in plans)
    t_max = time_limit if time_limit is not None else 3.0 * predicted_end + 30.0 + scenario.montecarlo.hold
    n_max = int(t_max / dt_ctrl) + 2
    zones = zones_of(plans, prepared.plan.order)
    names = [fr.name for fr in scenario.robots]
    robots, gates = [], []
    for i, (fr, rp) in enumerate(zip(scenario.robots, plans, strict=True)):
        # robot 0 draws from exactly the streams a lone robot would
        own = ss if i == 0 else np.random.SeedSequence(ss.entropy, spawn_key=(*ss.spawn_key, 4, i))
        # this run's draw of the robot's declared timing spread (planner.fleet.timing)
        drawn = fleet_timing.draw(fr, fleet_timing.stream(ss, i), legs=len(rp.plans))
        # a parking leg (planner.fleet.parking) is no task of the scenario: -1
        legs = tuple(int(k) for k in fr.tasks) + (-1,) * (len(rp.plans) - len(fr.tasks))
        mission = Mission(rp.plans, legs, rp.offsets, f"robot {fr.name!r}",
                          start_time=fr.start_time + drawn.release_delay, blocking=rp.blocking,
                          speed_factor=drawn.speed_factor, dwell=drawn.dwell)
        gates.append(ZoneGate(zones, i))
        # planner and filter see this robot's declared spec, the physics its actual one
        sc = replace(scenario, robot=fr.robot, robot_actual=fr.robot_actual)
        d = RobotDriver(i, sc, mission, world, prepared.pef, own, n_max, q_scale, gate=gates[-1])
        longest = longest_run(rp.timeline.waiting, rp.timeline.t) if rp.timeline is not None else 0.0
        d.wait_limit, d.names = wait_bound(longest, predicted_end), names
        robots.append(d)
    world.reset_fleet([d.true_start for d in robots])
    for d in robots:
        d.check_visible()
        d.begin(dt_ctrl)

    touching: set[tuple[int, int]] = set()
    collisions = [0] * len(robots)
    n = 0
    while n < n_max and not all(d.finished for d in robots):
        t = world.time
        world.place_bodies()
        for d in robots:
            if d.control(t):
                d.hold_at_goal(t)   # at its goal: it goes on at once, the others drive on
        circles = wait_cycles([d.watch.waiting for d in robots], [g.holder() for g in gates])
        for d, in_circle in zip(robots, circles, strict=True):
            d.watch.circle(in_circle)
        n += 1
        advance(world, robots)
        now = set(world.touching())
        for a, b in now - touching:
            collisions[a] += 1
            collisions[b] += 1
        touching = now
    # a last log row for each robot at the final time, as a single episode has
    t = world.time
    for d in robots:
        if d.n < n_max:
            d.finished = True
            d.control(t)
    out = [_robot_result(d, g, rp, name, scenario) for d, g, rp, name in zip(robots, gates, plans, names, strict=True)]
    return FleetResult(robots=out, collisions=sum(collisions) // 2, duration=float(world.time), names=names)
