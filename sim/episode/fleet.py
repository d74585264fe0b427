"""A fleet episode: every robot of ``[[robots]]`` in one physics world, under zone control.

Each robot is what a single-robot episode drives (:mod:`sim.episode.drive`): its own wheels,
encoders, odometry, filter, laser, fix recorder and random streams; robot 0 draws from exactly
the streams a single robot would, robot i > 0 from streams spawned under the key (4, i). The
robots share the physics steps and the control ticks. At each control tick a robot

* asks zone control (:mod:`planner.fleet.zones`) for the floor up to its braking distance
  ahead, releases what it has left behind, and is slowed so that it stops at the end of its
  reservation; it waits there parked (:meth:`sim.physics.robot.DiffDriveRobot.park`), holding
  its stop's cells alone (:meth:`planner.fleet.zones.ZoneControl.stand`);
* starts its scheduled fixes as a single robot does; before a fix it checks which scheduled
  markers another robot's body hides (the fix's note: ``FixLog.notes``, a ``FixNote``: marker
  index -> robot, and the plan's probability of it), and every other line of sight within range
  a robot hides there (``FixNote.sight_hidden``: what the laser would see without the robots).
  Those lines of sight count as blocked for the fix, as ``sensor.block_probability``'s do: the
  robot measures the schedule's fallback, or improvises beyond what the plan promised
  (``beyond_redundancy``), and the single-failure test (runs column ``lost_guarantee``) judges
  the robot's certified bound wherever a fix lost at most one of them.

Each robot keeps the timing its run drew from its declared spread (:mod:`planner.fleet.timing`,
from a stream of its own under the episode's seed): it leaves its first dock that much later,
dwells at each dock between two tasks, and drives at that fraction of its planned speeds. When
a dock lies on another robot's path the zones keep the plan's order of passage
(``FleetPlan.order``, :mod:`planner.fleet.zones`).

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

import bisect
import math
from dataclasses import dataclass, field, replace

import numpy as np

from planner.fleet import timing as fleet_timing
from planner.fleet.plan import FleetPlan, FleetRobotPlan, plan_fleet, zones_of
from planner.schedule.promise import POLYGON_TOLERANCE, START_LAG
from scenarios import PlanningError, Scenario, SimulationError
from scenarios.schema import NoiseModel
from sim.episode.certify import certified_bound, lost_markers, single_failure_excused
from sim.episode.control_tick import LOG_COLUMNS, LOG_COV, LOG_EST, LOG_S, LOG_T, LOG_TRUE, ControlTick
from sim.episode.drive import (
    CONTROL_STEPS,
    START_POS_STD,
    START_YAW_STD,
    _seed_repr,
    _step_log,
    _streams,
    _summary,
    check_markers,
    encoder_phases,
    episode_localizer,
    hold_fix,
    run_watch,
    seed_sequence,
)
from sim.episode.follower import SPEED, YAW_RATE, PurePursuit, wheel_speeds
from sim.episode.outcome import longest_run, wait_bound, wait_cycles
from sim.episode.types import EpisodeResult, FixNote, StepLog
from sim.physics.turn_lag import read_turn_slip

STOP_MARGIN = 0.05
"""A robot aims to stop this far before the end of its reservation [m] (the follower's overshoot)."""
RELEASE_SLACK = 0.1
"""A robot releases the zones of its path up to this far behind its estimate [m]: its true
position may trail the estimate's projection by the tracking error."""
LOOKAHEAD = 0.5
"""A robot asks for the floor this far beyond its braking distance [m], so that it rarely
slows for a reservation it would have got."""
BRAKE = 0.8
"""Share of the follower's deceleration limit a zone stop uses (the follower brakes for its goal
with the same share)."""
WAIT_SPEED = 0.02
"""A robot whose zone speed cap is below this [m/s] stands at the end of its reservation: it
waits there, within ``STOP_MARGIN`` + 0.5 mm of its stop (a cap this low leaves ``0.02^2 / (2 BRAKE
a)`` of room, a = 0.5 m/s^2), and holds the stop's cells alone (``margin`` of the zones covers the gap)."""


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


@dataclass
class RobotResult:
    """One robot of a fleet episode: its episode over all its tasks, and what the fleet did to it.

    Attributes
    ----------
    name : str
    result : EpisodeResult
        Its steps and fixes over all its tasks (``result.fixes.notes``: per fix, a FixNote whose ``hidden`` maps
        marker index -> index of the robot that hid it at the fix start).
    wait_time : float
        Time it stood at the end of its reservation waiting for zones [s].
    reserved : ndarray, shape (R, 3)
        Its reservation at each control tick it drove: time [s], and the stretch of its whole
        path it held, from and to (arc lengths [m]).
    path : ndarray, shape (N, 2)
        Its whole path (all its tasks chained) [m], the arc lengths of ``reserved`` are along it.
    """

    name: str
    result: EpisodeResult
    wait_time: float
    reserved: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    path: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))


@dataclass
class FleetResult:
    """A fleet episode.

    Attributes
    ----------
    robots : list of RobotResult
        ``robots[i]`` for ``scenario.robots[i]``.
    collisions : int
        Times two robots' footprint bodies (cylinders of their radius) began to overlap.
    duration : float
        Simulated time until the last robot arrived (or the time limit) [s].
    names : list of str
        The robots' names, in order.
    """

    robots: list[RobotResult]
    collisions: int
    duration: float
    names: list[str] = field(default_factory=list)


class _Robot:
    """One robot's drive in a fleet episode (the loop body of :func:`sim.episode.drive._drive`)."""

    def __init__(self, i: int, scenario: Scenario, rp: FleetRobotPlan, world, pef, ss, zones, n_max: int,
                 q_scale: float) -> None:
        from sim.episode.fixes import FixRecorder
        from sim.physics.laser import LaserSensor
        from sim.physics.odometry import WheelOdometry

        fr = scenario.robots[i]
        self.i, self.name, self.rp, self.world, self.zones = i, fr.name, rp, world, zones
        # this run's declared timing spread: release delay, dwells, speed factor (planner.fleet.timing)
        self.timing = fleet_timing.draw(fr, fleet_timing.stream(ss, i))
        self.start_time = fr.start_time + self.timing.release_delay
        self.dwell_until: float | None = None   # when its dwell at the dock it stands at ends
        # planner and filter see this robot's declared spec, the physics its actual one
        self.sc = replace(scenario, robot=fr.robot, robot_actual=fr.robot_actual)
        own = ss if i == 0 else np.random.SeedSequence(ss.entropy, spawn_key=(*ss.spawn_key, 4, i))
        self.ss = own
        rng_start, rng_laser, rng_odo, self.rng_block = _streams(own)
        dock = scenario.dock(rp.plans[0].start)
        P0 = np.diag([START_POS_STD**2, START_POS_STD**2, START_YAW_STD**2])
        self.true_start = np.array(dock.pose) + rng_start.multivariate_normal(np.zeros(3), P0)
        self._phase = encoder_phases(rng_start)
        self.body = world.robots[i]
        self.laser = LaserSensor(world, scenario.sensor_actual, scenario.marker_positions(),
                                 scenario.marker_normals(), robot=i)
        self._P0, self._dock = P0, dock
        self._rng_laser, self._rng_odo = rng_laser, rng_odo
        self.pef = pef
        self.q_scale = q_scale
        self.log = np.empty((n_max, LOG_COLUMNS))
        self.n = 0
        self.task_rows: list[int] = []
        self.waited = 0.0
        self.q_block = scenario.sensor_actual.block_probability
        self.n_markers = len(scenario.markers)
        self.attempts: list[tuple[float, bool]] = []
        self.counts = {"merged": 0, "reads": 0}
        self.scheduled = 0
        self.robot_blocked = 0
        self.reserved: list[tuple[float, float, float]] = []
        self.hold = scenario.montecarlo.hold
        self.hold_until: float | None = None   # when its hold at the final dock ends
        self._FixRecorder, self._WheelOdometry = FixRecorder, WheelOdometry
        self.wait_limit, self.names = math.inf, [fr.name]   # set by the fleet's driver (sim.episode.outcome)
        self.watch = None

    def begin(self, dt_ctrl: float) -> None:
        """After the world's reset: zero the encoders, build the filter, start task 0."""
        angles0 = self.body.wheel_angles()
        pose = np.array(self._dock.pose)
        self.loc = episode_localizer(self.sc, pose, self._P0, q_scale=self.q_scale,
                                     step_time=self.world.config.time_step)
        actual = self.sc.robot_actual
        self.last_read = self.world.steps   # the physics step of the last odometry read
        self.odo = self._WheelOdometry(self.sc.robot, angles0, pose, slip_std=actual.odometry_noise, rng=self._rng_odo,
                                       bounded=self.sc.sensor_actual.noise is NoiseModel.UNIFORM, phase=self._phase)
        self.fixes = self._FixRecorder(self.sc, self.pef, self.laser, self.loc, self._rng_laser)
        self.dt_ctrl = dt_ctrl
        self.min_gap = 1.0 / self.sc.sensor.fix_rate_hz - dt_ctrl
        self.task = -1
        self.finished = False
        self.arrival = math.nan
        self.waiting = False   # stood at the end of its reservation at the last tick
        self._next_task()
        self.watch = run_watch(self.world, self.i, self.follower, dt_ctrl, self.wait_limit, self.names)

    def _next_task(self) -> None:
        self.task += 1
        plan = self.rp.plans[self.task]
        robot = self.sc.robot
        self.plan = plan
        self.offset = float(self.rp.offsets[self.task])
        speed = plan.speed if self.timing.speed_factor == 1.0 else plan.speed * self.timing.speed_factor
        self.follower = PurePursuit(path=plan.path, speed=speed, max_speed=robot.max_speed,
                                    max_yaw_rate=robot.max_yaw_rate)
        self.tick = ControlTick(self.odo, self.loc, self.follower, self.log, self.dt_ctrl)
        if self.watch is not None:
            self.watch.follow(plan.path, self.offset)
        self.fix_s = [f.s for f in plan.schedule.fixes]
        # the plan's probability that robots hide a scheduled marker at each fix (the blocking check)
        self.p_fix = [math.nan] * len(self.fix_s)
        b = self.rp.blocking
        if b is not None:
            for f, p in zip(b.fix[b.task == self.task].tolist(), b.p_fix[b.task == self.task].tolist(), strict=True):
                self.p_fix[f] = p
        self.scheduled += len(self.fix_s)
        self.next_fix, self.last_fix_start = 0, -math.inf
        self.holding = len(self.fix_s) > 0 and self.fix_s[0] <= 1e-9
        self.s_now, self.done, self.at_goal = 0.0, False, False
        self.task_rows.append(self.n)

    # -- fixes ------------------------------------------------------------------------------

    def read_span(self) -> tuple[float, int]:
        """Return a read's turn slip now (the physics' lag depends on the steps it spans) and its span."""
        steps, self.last_read = self.world.steps - self.last_read, self.world.steps
        return read_turn_slip(self.sc.robot.turn_slip, steps, CONTROL_STEPS), steps

    def read_odometry(self) -> None:
        d_left, d_right = self.odo.update(self.body.wheel_angle_pair())
        self.loc.predict(d_left, d_right, *self.read_span())
        self.counts["reads"] += 1

    def start_fix(self, s_now: float, t: float) -> None:
        fix_s, fixes, laser = self.fix_s, self.fixes, self.laser
        if fixes.pending is not None or self.next_fix >= len(fix_s) or s_now < fix_s[self.next_fix] \
                or t - self.last_fix_start < self.min_gap - 1e-9:
            return
        f = bisect.bisect_right(fix_s, s_now) - 1
        self.counts["merged"] += f - self.next_fix
        sched = self.plan.schedule.fixes[f]
        drawn: frozenset[int] = frozenset()
        if self.q_block > 0.0:
            drawn = frozenset(np.flatnonzero(self.rng_block.random(self.n_markers) < self.q_block).tolist())
            fixes.blocked_markers += len(drawn & set(sched.markers))
        # which scheduled lines of sight another robot's body hides now: blocked for this fix, as
        # a passer-by's are (the fallback, or an improvised fix the plan promised nothing for)
        laser.blocked = drawn
        hidden = {}
        for m in sched.markers:
            if m not in drawn and not laser.visible(m) and m in laser.blocked_by:
                hidden[int(m)] = laser.blocked_by[m]
        self.robot_blocked += len(hidden)
        # every line of sight the others hide here, not only the scheduled ones (fixes table)
        sight = laser.hidden_by_robots()
        laser.blocked = drawn | frozenset(hidden)
        # the single-failure test counts every line of sight lost at the fix, whoever blocked it
        self.attempts.append((t, lost_markers(laser.blocked, sched.markers, sched.fallbacks) > 1))
        subset = fixes.choose_subset(sched.markers, self.loc.x[:2], sched)
        if subset is None:
            fixes.skipped += 1
        else:
            fixes.start(subset, t, sched, note=FixNote(hidden, self.p_fix[f], sight))
            self.last_fix_start = t
        self.next_fix = f + 1

    # -- one control tick ---------------------------------------------------------------------

    def command(self, left: float, right: float) -> None:
        """Command the wheel rates [rad/s]: the motors, and the filter, which predicts each read's turn from them."""
        self.body.set_wheel_speeds(left, right)
        self.loc.set_command(left, right)

    def control(self, t: float) -> None:
        """Read, predict, log, and command the wheels for the next control period."""
        body = self.body
        waiting_start = t < self.start_time - 1e-9
        steer = not (self.holding or self.done or self.at_goal or self.finished or waiting_start)
        pose = body.true_pose_tuple()
        v, omega, cmd_done, s_cmd = self.tick(body.wheel_angle_pair(), pose, t, self.n, self.s_now, steer,
                                              *self.read_span())
        waiting = steer and self.waiting
        self.watch.tick(t, pose, steer and not waiting, waiting, self.zones.refused_by[self.i])
        self.waiting = False
        self.n += 1
        if self.finished or waiting_start:
            self.command(0.0, 0.0)
            return
        if self.at_goal:
            self._hold_at_goal(t)
            return
        if self.holding:
            self.start_fix(0.0, t)
            self.holding = self.fixes.pending is not None
            if self.holding:
                self.command(0.0, 0.0)
                return
            v, omega, cmd_done, s_cmd = self.follower.command(self.loc.x, self.dt_ctrl)
            self.log[self.n - 1, LOG_S] = s_cmd
        self.s_now, self.done = s_cmd, cmd_done
        if self.done:
            self.at_goal = True
            self._hold_at_goal(t)
            return
        v, omega = self._zone_limit(v, omega)
        self.reserved.append((t, self.offset + self.s_now, self.zones.reserved_to(self.i)))
        self.start_fix(self.s_now, t)
        self.command(*wheel_speeds(v, omega, self.sc.robot.wheel_radius, self.sc.robot.wheel_base))

    def _hold_at_goal(self, t: float) -> None:
        """Hold at the task's goal until the schedule's last fixes are taken, then go on.

        As a lone robot does (:mod:`sim.episode.drive`): the follower is done within its goal
        tolerance of the path's end, short of fixes the schedule puts within a fix gap of it; the
        robot finishes the fix under way and takes each of them in turn, at the goal. At its
        final dock it parks (:meth:`sim.physics.robot.DiffDriveRobot.park`) and stands there
        ``montecarlo.hold`` s, fixing at the laser's rate, before it has finished.
        """
        self.command(0.0, 0.0)
        if self.fixes.pending is not None or self.next_fix < len(self.fix_s):
            if self.next_fix < len(self.fix_s):
                self.start_fix(self.fix_s[self.next_fix], t)
            return
        if self.task + 1 < len(self.rp.plans):
            # it dwells at the dock this run's draw long, then drives its next task
            if self.dwell_until is None:
                self.dwell_until = t + self.timing.dwell[self.task]
            if t < self.dwell_until - 1e-9:
                return
            self.dwell_until = None
            self._next_task()
            return
        if self.hold_until is None:
            # parked within the goal tolerance of its final dock: it keeps the dock's cells alone
            self.arrival, self.hold_until = t, t + self.hold
            self.zones.stand(self.i)
            self.body.park(True)
        if t < self.hold_until - 1e-9:
            # held there (montecarlo.hold), re-localising at the laser's rate
            self._hold_fix(t)
            return
        self.finished = True

    def _hold_fix(self, t: float) -> None:
        """Start a fix at the final dock during the hold, as :func:`sim.episode.drive.hold_fix` does.

        Robots driving past hide lines of sight: those count as blocked for the fix, as at a
        scheduled fix (:meth:`start_fix`), so that the fix measures the fallback or improvises
        beyond the plan instead of on a subset the plan never named.
        """
        if self.fixes.pending is not None or t - self.last_fix_start < self.min_gap - 1e-9:
            return
        laser = self.laser
        laser.blocked = frozenset()
        sched = self.plan.schedule.fixes[-1]
        hidden = {int(m): laser.blocked_by[m] for m in sched.markers
                  if not laser.visible(m) and m in laser.blocked_by}
        laser.blocked = frozenset(hidden)
        self.last_fix_start = hold_fix(self.fixes, self.plan.schedule, self.loc.x[:2], t, self.last_fix_start,
                                       self.min_gap, note=FixNote(hidden, math.nan, {}))

    def unreached(self) -> int:
        """Scheduled fixes the time limit left untaken (the one under way included)."""
        if self.finished:
            return 0
        later = sum(len(p.schedule.fixes) for p in self.rp.plans[self.task + 1:])
        return len(self.fix_s) - self.next_fix + int(self.fixes.pending is not None) + later

    def _zone_limit(self, v: float, omega: float) -> tuple[float, float]:
        """Cap the command so that the robot stops at the end of its reservation; count the wait."""
        zones, i = self.zones, self.i
        s_glob = self.offset + self.s_now
        zones.release(i, s_glob - RELEASE_SLACK)
        a = self.follower.max_accel
        brake = v * v / (2.0 * BRAKE * a)
        zones.request(i, s_glob + brake + LOOKAHEAD)
        if zones.reserved_to(i) >= zones.length(i):
            # reserved to its final dock: the follower's own goal stop rules (compared as arc
            # lengths: the room below and the way left summed in another order differed in the
            # last bit, and a robot 5 cm short of its goal was held there for good)
            self.body.park(False)
            return v, omega
        room = zones.reserved_to(i) - STOP_MARGIN - s_glob
        cap = math.sqrt(2.0 * BRAKE * a * max(room, 0.0))
        if cap < WAIT_SPEED:
            # it stands at its stop, parked: the samples just before a stop need not be safe,
            # and a waiting robot that held them could block the robot it waits for (zones.stand)
            zones.stand(i)
            self.body.park(True)
            self.waited += self.dt_ctrl
            self.waiting = True
            self.follower.state[SPEED], self.follower.state[YAW_RATE] = 0.0, 0.0
            return 0.0, 0.0
        self.body.park(False)
        if v <= cap:
            return v, omega
        w = omega * cap / v if v > 0.0 else omega
        self.follower.state[SPEED], self.follower.state[YAW_RATE] = cap, w
        return cap, w

    # -- result ---------------------------------------------------------------------------------

    def result(self, scenario: Scenario) -> RobotResult:
        n, log, sc = self.n, self.log[:self.n], self.sc
        k = sc.sensor.markers_per_fix
        bounds = [*self.task_rows, n]
        pieces = []
        s_glob = np.empty(n)
        for j, (a, b) in enumerate(zip(bounds[:-1], bounds[1:], strict=True)):
            if b <= a:
                continue
            plan = self.rp.plans[j]
            pieces.append(_step_log(log[a:b, LOG_T], log[a:b, LOG_TRUE], log[a:b, LOG_EST],
                                    log[a:b, LOG_COV].reshape(b - a, 3, 3), log[a:b, LOG_S], plan.schedule, self.pef))
            s_glob[a:b] = log[a:b, LOG_S] + float(self.rp.offsets[j])
        steps = StepLog(**{f: np.concatenate([getattr(p, f) for p in pieces])
                           for f in ("t", "true_pose", "est_pose", "est_cov", "error", "predicted_tau", "pef_tau",
                                     "nees")})
        fix_log = self.fixes.log()
        certified = certified_bound(sc.robot, steps.t, s_glob, steps.est_pose[:, 2], fix_log.t,
                                    fix_log.predicted_tau, k * sc.sensor.measurement_time)
        steps.certified = certified
        lost_guarantee = 0
        if self.q_block > 0.0 or self.robot_blocked > 0:
            at = np.array(self.attempts, dtype=float).reshape(-1, 2)
            planned = ~np.asarray(fix_log.beyond_redundancy, bool) & np.isfinite(fix_log.predicted_tau)
            excused = single_failure_excused(steps.t, at[:, 0], at[:, 1] > 0.5, fix_log.t, planned,
                                             k * sc.sensor.measurement_time)
            lost_guarantee = int(np.sum((certified > sc.planning.eps_max * (1.0 + POLYGON_TOLERANCE)) & ~excused))
            steps.excused = excused
        goal = np.array(scenario.dock(self.rp.plans[-1].goal).position)
        outcome = self.watch.summary()
        # a robot that touched something, stuck or deadlocked did not do what was asked
        reached = bool(self.finished and np.hypot(*(steps.true_pose[-1, :2] - goal)) <=
                       self.follower.goal_tolerance + sc.planning.eps_max and outcome["status"] == "ok")
        summary = {**_summary(steps, fix_log, reached, sc.planning.eps_max, self.ss, self.fixes.skipped,
                              self.counts["merged"]),
                   "scheduled_fixes": self.scheduled, "blocked_markers": self.fixes.blocked_markers,
                   "fallback_fixes": int(np.sum(fix_log.fallback)), "failed_fixes": self.fixes.skipped,
                   "unreached_fixes": self.unreached(),
                   "certified_max": float(np.max(certified, initial=0.0)), "lost_guarantee": lost_guarantee,
                   "robot": self.name, "arrival": self.arrival, "wait_time": self.waited,
                   "robot_blocked": self.robot_blocked,
                   "predicted_wait": longest_run(self.rp.timeline.waiting, self.rp.timeline.t)
                   if self.rp.timeline is not None else math.nan,
                   "predicted_wait_time": float(self.rp.timeline.wait_time)
                   if self.rp.timeline is not None else math.nan,
                   **outcome}
        res = EpisodeResult(scenario_name=scenario.name, task_index=int(scenario.robots[self.i].tasks[0]),
                            seed=_seed_repr(self.ss), eps_max=sc.planning.eps_max, steps=steps, fixes=fix_log,
                            plan=self.rp.plans[0], summary=summary)
        return RobotResult(self.name, res, self.waited, np.array(self.reserved, dtype=float).reshape(-1, 3),
                           self.rp.path)


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
    dt_phys = world.config.time_step
    dt_ctrl = CONTROL_STEPS * dt_phys
    if dt_ctrl + dt_phys > START_LAG * (1.0 + 1e-9):
        raise SimulationError(f"physics time_step {dt_phys:g} s: a fix may start {dt_ctrl + dt_phys:.4g} s late, "
                              f"the plan's promises allow {START_LAG:.4g} s")
    plans = prepared.plan.robots
    predicted_end = max(float(rp.timeline.end_time) for rp in plans)
    t_max = time_limit if time_limit is not None else 3.0 * predicted_end + 30.0 + scenario.montecarlo.hold
    n_max = int(t_max / dt_ctrl) + 2
    zones = zones_of(plans, prepared.plan.order)
    robots = [_Robot(i, scenario, rp, world, prepared.pef, ss, zones, n_max, q_scale) for i, rp in enumerate(plans)]
    names = [r.name for r in robots]
    for r, rp in zip(robots, plans, strict=True):
        longest = longest_run(rp.timeline.waiting, rp.timeline.t) if rp.timeline is not None else 0.0
        r.wait_limit, r.names = wait_bound(longest, predicted_end), names
    world.reset_fleet([r.true_start for r in robots])
    k = scenario.sensor.markers_per_fix
    for r in robots:
        seen = int(r.laser.visible_all().sum())
        if seen < k:
            raise SimulationError(f"{scenario.source}: robot {r.name!r}: {seen} marker(s) visible from dock "
                                  f"{r.rp.plans[0].start}, a fix needs {k}")
        r.begin(dt_ctrl)

    touching: set[tuple[int, int]] = set()
    collisions = [0] * len(robots)
    n = 0
    while n < n_max and not all(r.finished for r in robots):
        t = world.time
        world.place_bodies()
        for r in robots:
            r.control(t)
        circles = wait_cycles([r.watch.waiting for r in robots], [zones.refused_by[r.i] for r in robots])
        for r, in_circle in zip(robots, circles, strict=True):
            r.watch.circle(in_circle)
        n += 1
        _advance(world, robots, dt_phys)
        now = set(world.touching())
        for a, b in now - touching:
            collisions[a] += 1
            collisions[b] += 1
        touching = now
    # a last log row for each robot at the final time, as a single episode has
    t = world.time
    for r in robots:
        if r.n < n_max:
            r.finished = True
            r.control(t)
    out = [r.result(scenario) for r in robots]
    return FleetResult(robots=out, collisions=sum(collisions) // 2, duration=float(world.time),
                       names=[r.name for r in robots])


def _advance(world, robots, dt_phys: float) -> None:
    """One control period of physics, stopping at each physics step a measurement of any robot falls due."""
    end = world.steps + CONTROL_STEPS
    # every robot's control tick has just read its odometry at this physics step: a second read
    # here would report zero travel and renew the filter's quantisation residuals (sim.episode.drive)
    read_at = {id(r): world.steps for r in robots}
    while True:
        due = [(math.ceil(r.fixes.next_due / dt_phys - 1e-9), r) for r in robots
               if r.fixes.pending is not None]
        first = min((d for d, _ in due), default=end)
        if first >= end:
            world.step(end - world.steps)
            return
        world.step(max(first - world.steps, 0))
        world.place_bodies()
        for d, r in due:
            if d <= world.steps:
                if read_at[id(r)] != world.steps:
                    r.read_odometry()
                    read_at[id(r)] = world.steps
                r.fixes.measure_due(r.odo.pose, r.body.true_pose_tuple(), world.time, r.n + r.counts["reads"],
                                    r.odo.slip_weight, r.odo.wheel_paths)
