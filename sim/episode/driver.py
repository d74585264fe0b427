"""One robot driving its tasks: the loop body of every episode, a lone robot's or a fleet member's.

A :class:`RobotDriver` owns everything one robot needs: its wheels (a body of the physics world),
encoders and odometry, filter, laser, fix recorder, follower, run watch and its own random
streams. An episode drives one or more of them in one physics world
(:func:`sim.episode.drive.run_episode`: a lone robot; :func:`sim.episode.fleet.run_fleet_episode`:
a fleet under zone control); both call :meth:`RobotDriver.control` at each control tick and
:func:`advance` for the physics in between, which stops at each physics step a measurement of
any robot falls due.

At each control tick a driver reads its odometry, predicts, logs a row and, unless it is held,
commands its wheels from the estimate (:class:`sim.episode.control_tick.ControlTick`). Its
scheduled fixes start at the control tick it passes them, when its laser is free; the lines of
sight ``sensor.block_probability`` blocks are drawn at each fix start (one draw per marker, from
the ``block`` stream), and in a world with robot bodies those the other robots hide count as
blocked too (a :class:`~sim.episode.types.FixNote` with the fix). The follower is done within
its goal tolerance of a task's path end, short of the schedule's last fixes; the robot then holds
at the goal and takes them there, one after another, and goes on to its next task. At its final
dock it parks (:meth:`sim.physics.robot.DiffDriveRobot.park`) and stands ``montecarlo.hold`` s,
fixing at the laser's rate, before it has finished.

Every scheduled fix is accounted for in the summary: taken (a row of the fix log), merged into a
later one (``merged_fixes``: the laser was still busy when it fell due), failed (``failed_fixes``:
too few markers seen, or one lost mid-fix) or unreached (``unreached_fixes``: the time limit ran
out first).

Where a robot's timing is decided, each in one place (a fleet's timing spread draws there):
its release (:attr:`Mission.start_time`: it stands at its first dock until then), its stay at
each goal (:meth:`RobotDriver.hold_at_goal`) and its speed along each plan
(:meth:`RobotDriver._follower`).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from planner.pef.map import PEF
from planner.plan import Plan
from planner.schedule.promise import POLYGON_TOLERANCE, START_LAG
from scenarios import Scenario, SimulationError
from scenarios.schema import NoiseModel, PefModel
from sim.episode.certify import certified_bound, lost_markers, single_failure_excused
from sim.episode.control_tick import LOG_COLUMNS, LOG_COV, LOG_EST, LOG_S, LOG_T, LOG_TRUE, ControlTick
from sim.episode.follower import PurePursuit, wheel_speeds
from sim.episode.types import EpisodeResult, FixNote, StepLog
from sim.physics.turn_lag import read_turn_slip

CONTROL_STEPS = 4
"""Physics steps per control step: 60 Hz control at pybullet's 240 Hz. An odometry increment
is then at most 1.7 cm at 1 m/s, inside the 2 cm the planner's drift bound assumes."""

START_POS_STD = 0.001
"""Standard deviation of the start position about the dock [m]: docks are calibrated."""
START_YAW_STD = math.radians(0.1)
"""Standard deviation of the start heading about the dock's [rad]."""


@dataclass(frozen=True)
class Mission:
    """What one robot drives: its tasks' plans, in order, and when it may leave its first dock.

    Attributes
    ----------
    plans : list of Plan
        One per task, in driving order (each with a measurement schedule).
    tasks : tuple of int
        The indices into ``scenario.tasks`` of ``plans`` (-1: a fleet robot's leg to its parking place).
    offsets : ndarray, shape (len(plans),)
        Arc length along the whole path where each plan begins [m].
    where : str
        How messages name the robot (``tasks[0]``, ``robot 'r1'``).
    start_time : float
        When it leaves its first dock [s] (its release).
    blocking : planner.fleet.exposure.RobotBlocking, optional
        The plan's probability that other robots hide a scheduled marker at each fix.
    speed_factor : float
        It drives at this fraction of its planned speeds (a fleet robot's drawn timing,
        :mod:`planner.fleet.timing`).
    dwell : tuple of float
        How long it stands at the dock ending each of its tasks but the last [s].
    """

    plans: list[Plan]
    tasks: tuple[int, ...]
    offsets: np.ndarray
    where: str
    start_time: float = 0.0
    blocking: Any = None
    speed_factor: float = 1.0
    dwell: tuple[float, ...] = ()


def check_control_period(world) -> float:
    """Return the control period [s] of ``world``; raise unless the plan's promises allow its lag."""
    dt_phys = world.config.time_step
    dt_ctrl = CONTROL_STEPS * dt_phys
    if dt_ctrl + dt_phys > START_LAG * (1.0 + 1e-9):
        # a fix starts up to a control tick late and measures up to a physics step late: the
        # plan's promises hold for starts up to START_LAG late only
        raise SimulationError(f"physics time_step {dt_phys:g} s: a fix may start {dt_ctrl + dt_phys:.4g} s late, "
                              f"the plan's promises allow {START_LAG:.4g} s")
    return dt_ctrl


def streams(ss: np.random.SeedSequence) -> tuple[np.random.Generator, ...]:
    """Return a robot's random streams (start, laser, odometry, block) from its SeedSequence."""
    # Children are derived from (entropy, spawn_key) rather than ss.spawn(), which counts
    # calls: the same seed must give the same streams however often it is used.
    keys = ("start", "laser", "odometry", "block")
    return tuple(np.random.default_rng(np.random.SeedSequence(ss.entropy, spawn_key=(*ss.spawn_key, j)))
                 for j, _ in enumerate(keys))


def encoder_phases(rng: np.random.Generator) -> np.ndarray:
    """Draw where each encoder's tick edges sit on its wheel at a run's start, shape (2,) [ticks].

    Uniform in ``[0, 1)``, left then right (:class:`sim.physics.odometry.WheelOdometry`'s
    ``phase``). A fleet's missions start with the wheels wherever they stopped; the same
    sub-tick phase in every run of a sweep would make the encoders' count errors, which the
    filter treats as random, the same in every run, and the N-run tests, which average
    independent runs, would see them as a bias.
    """
    return rng.uniform(0.0, 1.0, 2)


def episode_localizer(scenario: Scenario, pose, P0, q_scale: float = 1.0, **overrides):
    """Build the filter an episode runs, on the declared robot and sensor.

    The pose with the relative wheel-radius error and both encoders' quantisation residuals in
    the state (:mod:`estimators.ekf`). The residuals start unknown, uniform over a tick: an
    incremental encoder counts from wherever its wheel stands, and cannot say where that is
    within a tick (the episode draws it per run, :func:`encoder_phases`).

    Parameters
    ----------
    scenario : Scenario
    pose : array_like, shape (3,)
        Start estimate (x [m], y [m], theta [rad]).
    P0 : array_like, shape (3, 3)
        Its covariance.
    q_scale : float
        Multiplies the process noise (1 = the declared model; negative controls).
    **overrides
        Other :class:`estimators.ekf.Localizer` arguments, for tests that compare models.

    Returns
    -------
    estimators.ekf.Localizer
    """
    from estimators.ekf import Localizer

    kw = {"q_scale": q_scale, "estimate_wheel_bias": True, "encoder_residual_state": True, **overrides}
    return Localizer(scenario.robot, scenario.sensor, scenario.marker_positions(), pose, P0, **kw)


def run_watch(world, i: int, follower: PurePursuit, dt_ctrl: float, wait_limit: float = math.inf,
              names: list[str] | None = None):
    """Build the :class:`~sim.episode.outcome.RunWatch` of robot ``i`` of ``world``, following ``follower``'s path."""
    from sim.episode.outcome import RunWatch, stuck_bound
    from sim.physics.contacts import ContactMonitor

    bound = stuck_bound(follower.max_yaw_rate, follower.max_yaw_accel, follower.max_speed, follower.max_accel)
    return RunWatch(ContactMonitor(world, i), follower.path, bound, dt_ctrl, wait_limit, names)


class RobotDriver:
    """One robot of an episode, driving its :class:`Mission` (see the module docstring).

    Parameters
    ----------
    i : int
        Its index among the world's robots (``world.robots[i]``).
    scenario : Scenario
        The scenario with this robot's declared and actual spec (planner and filter see the
        declared one, the physics the actual one).
    mission : Mission
    world : sim.physics.world.PhysicsWorld
    pef : planner.pef.map.PEF
    ss : numpy.random.SeedSequence
        Root of its random streams (:func:`streams`).
    n_max : int
        Rows of its step log (control ticks it may log).
    q_scale : float
        Multiplies its filter's process noise (negative controls).
    gate : optional
        The fleet's zone control for this robot (:class:`sim.episode.fleet.ZoneGate`): caps its
        command at each tick, and it stands at its final dock. None: the floor is its own.
    """

    def __init__(self, i: int, scenario: Scenario, mission: Mission, world, pef, ss: np.random.SeedSequence,
                 n_max: int, q_scale: float = 1.0, gate=None) -> None:
        from sim.physics.laser import LaserSensor

        self.i, self.sc, self.mission, self.world, self.pef, self.ss = i, scenario, mission, world, pef, ss
        self.q_scale, self.gate = q_scale, gate
        rng_start, self._rng_laser, self._rng_odo, self._rng_block = streams(ss)
        self._dock = scenario.dock(mission.plans[0].start)
        self._P0 = np.diag([START_POS_STD**2, START_POS_STD**2, START_YAW_STD**2])
        self.true_start = np.array(self._dock.pose) + rng_start.multivariate_normal(np.zeros(3), self._P0)
        self._phase = encoder_phases(rng_start)
        self.body = world.robots[i]
        self.laser = LaserSensor(world, scenario.sensor_actual, scenario.marker_positions(),
                                 scenario.marker_normals(), robot=i)
        # other robots' bodies hide lines of sight only in a world that has them
        self._robot_bodies = bool(world.body_ids)
        self.log = np.empty((n_max, LOG_COLUMNS))
        self.n = 0
        self.task_rows: list[int] = []
        self.q_block = scenario.sensor_actual.block_probability
        self.n_markers = len(scenario.markers)
        self.attempts: list[tuple[float, bool]] = []
        self.merged = 0
        self.reads = 0   # odometry reads outside the control ticks
        self.scheduled = 0
        self.robot_blocked = 0
        self.waited = 0.0   # [s] stood waiting for zones (the gate counts it)
        self.waiting = False   # stood at the end of its reservation at the last tick (the gate sets it)
        self.hold = scenario.montecarlo.hold
        self.hold_until: float | None = None   # when its hold at the final dock ends
        self.dwell_until: float | None = None  # when its dwell at a dock between two tasks ends
        self.arrival = math.nan
        self.wait_limit, self.names = math.inf, None   # a fleet sets them (sim.episode.outcome)
        self._drawn: frozenset[int] = frozenset()   # lines of sight blocked at the last fix start
        self.watch = None

    # -- set-up ---------------------------------------------------------------------------------

    def check_visible(self) -> None:
        """Raise :class:`SimulationError` unless the laser sees enough markers for a fix where it stands."""
        k = self.sc.sensor.markers_per_fix
        seen = int(self.laser.visible_all().sum())
        if seen < k:
            raise SimulationError(f"{self.sc.source}: {self.mission.where}: {seen} marker(s) visible from dock "
                                  f"{self.mission.plans[0].start} at {list(self._dock.position)}, a fix needs {k}")

    def begin(self, dt_ctrl: float) -> None:
        """After the world's reset: zero the encoders, build the filter, start the first task."""
        from sim.episode.fixes import FixRecorder
        from sim.physics.odometry import WheelOdometry

        angles0 = self.body.wheel_angles()
        pose = np.array(self._dock.pose)
        sc = self.sc
        self.loc = episode_localizer(sc, pose, self._P0, q_scale=self.q_scale, step_time=self.world.config.time_step)
        self.last_read = self.world.steps   # the physics step of the last odometry read
        # The simulated floor's random slip, per unit of travel, goes into the odometry readings
        # (bounded in a bounded-noise world); the odometry's dead reckoning carries the ranges of a
        # fix to its end (FixRecorder).
        self.odo = WheelOdometry(sc.robot, angles0, pose, slip_std=sc.robot_actual.odometry_noise, rng=self._rng_odo,
                                 bounded=sc.sensor_actual.noise is NoiseModel.UNIFORM, phase=self._phase)
        self.fixes = FixRecorder(sc, self.pef, self.laser, self.loc, self._rng_laser)
        self.dt_ctrl = dt_ctrl
        # The schedule spaces fix starts by the sensor's rate in planned time, but a start can only
        # happen at a control step: holding two starts a full period apart would delay each fix by
        # up to one control step more than the last, until a fix is skipped (the robot then fixes
        # ~0.2 s of travel away from where the plan promised). Starts may come up to one control
        # step closer, so each fix starts within one control step of its planned place.
        self.min_gap = 1.0 / sc.sensor.fix_rate_hz - dt_ctrl
        self.task = -1
        self.finished = False
        self._next_task()
        self.watch = run_watch(self.world, self.i, self.follower, dt_ctrl, self.wait_limit, self.names)

    def _follower(self, plan: Plan) -> PurePursuit:
        """Return the path follower of ``plan``, at the plan's speeds."""
        robot = self.sc.robot
        f = self.mission.speed_factor
        return PurePursuit(path=plan.path, speed=plan.speed if f == 1.0 else plan.speed * f, max_speed=robot.max_speed,
                           max_yaw_rate=robot.max_yaw_rate)

    def _next_task(self) -> None:
        self.task += 1
        plan = self.mission.plans[self.task]
        self.plan = plan
        self.offset = float(self.mission.offsets[self.task])
        self.follower = self._follower(plan)
        self.tick = ControlTick(self.odo, self.loc, self.follower, self.log, self.dt_ctrl)
        if self.watch is not None:
            self.watch.follow(plan.path, self.offset)
        self.fix_s = [f.s for f in plan.schedule.fixes]   # compared at every control step: floats
        # the plan's probability that robots hide a scheduled marker at each fix (the blocking check);
        # NaN where it hinges on the tracking errors, not on the timing (RobotBlocking.undecided)
        self.p_fix = [math.nan] * len(self.fix_s)
        b = self.mission.blocking
        if b is not None:
            mine = b.task == self.task
            p_mine = np.where(b.undecided[mine], math.nan, b.p_fix[mine]) if b.undecided is not None else b.p_fix[mine]
            for f, p in zip(b.fix[mine].tolist(), p_mine.tolist(), strict=True):
                self.p_fix[f] = p
        self.scheduled += len(self.fix_s)
        self.next_fix, self.last_fix_start = 0, -math.inf
        # the schedule's first fix is taken at standstill on the dock, before the robot leaves
        self.holding = len(self.fix_s) > 0 and self.fix_s[0] <= 1e-9
        self.s_now, self.done, self.at_goal = 0.0, False, False
        self.task_rows.append(self.n)

    # -- odometry and fixes ----------------------------------------------------------------------

    def read_span(self) -> tuple[float, int]:
        """Return a read's turn slip now (the physics' lag depends on the steps it spans) and its span."""
        steps, self.last_read = self.world.steps - self.last_read, self.world.steps
        return read_turn_slip(self.sc.robot.turn_slip, steps, CONTROL_STEPS), steps

    def read_odometry(self) -> None:
        """Read the encoders between control ticks (a measurement falls due) and predict."""
        d_left, d_right = self.odo.update(self.body.wheel_angle_pair())
        self.loc.predict(d_left, d_right, *self.read_span())
        self.reads += 1

    def measure_due(self) -> None:
        """Take the measurement of the fix under way that falls due now."""
        self.fixes.measure_due(self.odo.pose, self.body.true_pose_tuple(), self.world.time, self.n + self.reads,
                               self.odo.slip_weight, self.odo.wheel_paths)

    def _hidden(self, markers) -> dict[int, int]:
        """Markers of ``markers`` not blocked now whose line of sight another robot's body hides, to that robot."""
        laser = self.laser
        return {int(m): laser.blocked_by[m] for m in markers
                if m not in laser.blocked and not laser.visible(m) and m in laser.blocked_by}

    def start_fix(self, s_now: float, t: float) -> None:
        """Start the latest scheduled fix the robot has passed at ``s_now`` [m], when the laser is free again."""
        fix_s, fixes, laser = self.fix_s, self.fixes, self.laser
        if fixes.pending is not None or self.next_fix >= len(fix_s) or s_now < fix_s[self.next_fix] \
                or t - self.last_fix_start < self.min_gap - 1e-9:
            return
        f = bisect.bisect_right(fix_s, s_now) - 1
        # scheduled fixes the laser could not start in time are merged into this one: count them
        self.merged += f - self.next_fix
        sched = self.plan.schedule.fixes[f]
        if self.q_block > 0.0:
            # one draw per marker and fix start, whatever is scheduled: the stream stays aligned
            self._drawn = frozenset(np.flatnonzero(self._rng_block.random(self.n_markers) < self.q_block).tolist())
            fixes.blocked_markers += len(self._drawn & set(sched.markers))
        laser.blocked = self._drawn
        note = None
        if self._robot_bodies:
            # the scheduled lines of sight another robot's body hides now: blocked for this fix, as
            # a passer-by's are (the fallback, or an improvised fix the plan promised nothing for)
            hidden = self._hidden(sched.markers)
            self.robot_blocked += len(hidden)
            # every line of sight the others hide here, not only the scheduled ones (fixes table)
            note = FixNote(hidden, self.p_fix[f], laser.hidden_by_robots())
            laser.blocked = self._drawn | frozenset(hidden)
        # the single-failure test counts every line of sight lost at the fix, whoever blocked it:
        # with lines of sight blocked, the guarantee must survive one of them lost at any fix (a
        # redundancy-0 layout is held to it too; the schedule's one fallback per marker covers no more)
        self.attempts.append((t, lost_markers(laser.blocked, sched.markers, sched.fallbacks) > 1))
        subset = fixes.choose_subset(sched.markers, self.loc.x[:2], sched)
        if subset is None:
            fixes.skipped += 1
        else:
            fixes.start(subset, t, sched, note=note)
            self.last_fix_start = t
        self.next_fix = f + 1

    def _hold_fix(self, t: float) -> None:
        """Start a fix at the final dock during the hold, if the laser is free.

        The fix measures the schedule's last subset (its fallback where blocked), under that
        fix's promise, at most one per ``min_gap`` [s]. The lines of sight blocked at the last
        scheduled fix stay blocked; robots driving past hide more, which count as blocked for the
        fix as at a scheduled fix (:meth:`start_fix`), so that the fix measures the fallback or
        improvises beyond the plan instead of on a subset the plan never named.
        """
        schedule = self.plan.schedule
        if self.fixes.pending is not None or t - self.last_fix_start < self.min_gap - 1e-9 or not schedule.fixes:
            return
        sched = schedule.fixes[-1]
        note = None
        if self._robot_bodies:
            self.laser.blocked = self._drawn
            hidden = self._hidden(sched.markers)
            self.laser.blocked = self._drawn | frozenset(hidden)
            note = FixNote(hidden, math.nan, {})
        subset = self.fixes.choose_subset(sched.markers, self.loc.x[:2], sched)
        if subset is None:
            return
        self.fixes.start(subset, t, sched, note=note)
        self.last_fix_start = t

    # -- one control tick ---------------------------------------------------------------------

    def command(self, left: float, right: float) -> None:
        """Command the wheel rates [rad/s]: the motors, and the filter, which predicts each read's turn from them."""
        self.body.set_wheel_speeds(left, right)
        self.loc.set_command(left, right)

    def control(self, t: float) -> bool:
        """Read, predict, log, and command the wheels for the next control period.

        Returns True on the tick the follower is done with a task's path: the robot is at the
        goal (:attr:`at_goal`), its wheels not yet commanded; the episode goes on with
        :meth:`hold_at_goal` (a fleet at once, a lone robot at its next tick).
        """
        body = self.body
        released = t >= self.mission.start_time - 1e-9
        steer = not (self.holding or self.done or self.at_goal or self.finished or not released)
        pose = body.true_pose_tuple()
        v, omega, cmd_done, s_cmd = self.tick(body.wheel_angle_pair(), pose, t, self.n, self.s_now, steer,
                                              *self.read_span())
        waiting = steer and self.waiting
        holder = self.gate.holder() if self.gate is not None else -1
        self.watch.tick(t, pose, steer and not waiting, waiting, holder)
        self.waiting = False
        self.n += 1
        if self.finished or not released:
            self.command(0.0, 0.0)
            return False
        if self.at_goal:
            self.hold_at_goal(t)
            return False
        if self.holding:
            self.start_fix(0.0, t)
            self.holding = self.fixes.pending is not None
            if self.holding:
                self.command(0.0, 0.0)
                return False
            v, omega, cmd_done, s_cmd = self.follower.command(self.loc.x, self.dt_ctrl)
            self.log[self.n - 1, LOG_S] = s_cmd
        self.s_now, self.done = s_cmd, cmd_done
        if self.done:
            self.at_goal = True
            return True
        if self.gate is not None:
            v, omega = self.gate.limit(self, t, v, omega)
        self.start_fix(self.s_now, t)
        self.command(*wheel_speeds(v, omega, self.sc.robot.wheel_radius, self.sc.robot.wheel_base))
        return False

    def hold_at_goal(self, t: float) -> None:
        """Hold at the task's goal until the schedule's last fixes are taken, then go on.

        The follower is done within its goal tolerance of the path's end, short of fixes the
        schedule puts within a fix gap of it; the robot finishes the fix under way and takes each
        of them in turn, at the goal. At its final dock it parks
        (:meth:`sim.physics.robot.DiffDriveRobot.park`) and stands there ``montecarlo.hold`` s,
        fixing at the laser's rate, before it has finished.
        """
        self.command(0.0, 0.0)
        if self.fixes.pending is not None or self.next_fix < len(self.fix_s):
            if self.next_fix < len(self.fix_s):
                self.start_fix(self.fix_s[self.next_fix], t)
            return
        if self.task + 1 < len(self.mission.plans):
            # it dwells at the dock as long as its mission says, then drives its next task
            if self.dwell_until is None:
                self.dwell_until = t + (self.mission.dwell[self.task] if self.mission.dwell else 0.0)
            if t < self.dwell_until - 1e-9:
                return
            self.dwell_until = None
            self._next_task()
            return
        if self.hold_until is None:
            self.arrival, self.hold_until = t, t + self.hold
            if self.gate is not None:
                self.gate.stand()   # parked within the goal tolerance of its final dock: it keeps the dock's cells
            self.body.park(True)
        if t < self.hold_until - 1e-9:
            # held there (montecarlo.hold), re-localising at the laser's rate
            self._hold_fix(t)
            return
        self.finished = True

    def unreached(self) -> int:
        """Scheduled fixes the time limit left untaken (the one under way included)."""
        if self.finished:
            return 0
        later = sum(len(p.schedule.fixes) for p in self.mission.plans[self.task + 1:])
        return len(self.fix_s) - self.next_fix + int(self.fixes.pending is not None) + later

    # -- result ---------------------------------------------------------------------------------

    def result(self, scenario_name: str, extra: dict | None = None) -> EpisodeResult:
        """Return its episode over all its tasks: steps, fixes, certified bound and summary.

        ``extra`` (a fleet's columns: robot, waits) goes into the summary before what the run
        did (:meth:`sim.episode.outcome.RunWatch.summary`).
        """
        n, log, sc = self.n, self.log[:self.n], self.sc
        k = sc.sensor.markers_per_fix
        bounds = [*self.task_rows, n]
        pieces = []
        s_glob = np.empty(n)
        for j, (a, b) in enumerate(zip(bounds[:-1], bounds[1:], strict=True)):
            if b <= a:
                continue
            plan = self.mission.plans[j]
            pieces.append(step_log(log[a:b, LOG_T], log[a:b, LOG_TRUE], log[a:b, LOG_EST],
                                   log[a:b, LOG_COV].reshape(b - a, 3, 3), log[a:b, LOG_S], plan.schedule, self.pef))
            s_glob[a:b] = log[a:b, LOG_S] + float(self.mission.offsets[j])
        steps = pieces[0] if len(pieces) == 1 else \
            StepLog(**{f: np.concatenate([getattr(p, f) for p in pieces])
                       for f in ("t", "true_pose", "est_pose", "est_cov", "error", "predicted_tau", "pef_tau", "nees")})
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
        goal = np.array(sc.dock(self.mission.plans[-1].goal).position)
        outcome = self.watch.summary()
        # a robot that touched something, stuck or deadlocked did not do what was asked, wherever
        # it ended; one that got to its final goal reached it, held there or not
        arrived = self.at_goal and self.task == len(self.mission.plans) - 1
        reached = bool(arrived and np.hypot(*(steps.true_pose[-1, :2] - goal)) <=
                       self.follower.goal_tolerance + sc.planning.eps_max and outcome["status"] == "ok")
        summary = {**summarize(steps, fix_log, reached, sc.planning.eps_max, self.ss, self.fixes.skipped, self.merged),
                   "scheduled_fixes": self.scheduled, "blocked_markers": self.fixes.blocked_markers,
                   "fallback_fixes": int(np.sum(fix_log.fallback)), "failed_fixes": self.fixes.skipped,
                   "unreached_fixes": self.unreached(),
                   "certified_max": float(np.max(certified, initial=0.0)), "lost_guarantee": lost_guarantee,
                   **(extra or {}), **outcome}
        return EpisodeResult(scenario_name=scenario_name, task_index=int(self.mission.tasks[0]),
                             seed=seed_repr(self.ss), eps_max=sc.planning.eps_max, steps=steps, fixes=fix_log,
                             plan=self.mission.plans[0], summary=summary)


def advance(world, drivers: list[RobotDriver]) -> None:
    """One control period of physics, stopping at each physics step a measurement of any robot falls due."""
    dt_phys = world.config.time_step
    end = world.steps + CONTROL_STEPS
    # Every robot's control tick has just read its odometry at this physics step. A second read at
    # the same step reports zero travel, and the filter's predict would replace each wheel's
    # quantisation residual by an independent one, where the encoder's is unchanged: the estimate
    # lost what the fix's updates taught it about the residuals, and the filter turned
    # inconsistent (random-23-016, with a fix's reads all on control ticks: NEES 2.884, NIS 1.009).
    read_at = [world.steps] * len(drivers)
    while True:
        due = [(math.ceil(d.fixes.next_due / dt_phys - 1e-9), j) for j, d in enumerate(drivers)
               if d.fixes.pending is not None]
        first = min((s for s, _ in due), default=end)
        if first >= end:
            world.step(end - world.steps)
            return
        world.step(max(first - world.steps, 0))
        world.place_bodies()
        for s, j in due:
            if s <= world.steps:
                d = drivers[j]
                if read_at[j] != world.steps:
                    d.read_odometry()
                    read_at[j] = world.steps
                d.measure_due()


def step_log(t, true_pose, est_pose, est_cov, s_est, schedule, pef) -> StepLog:
    """Build the step log of one task's rows: errors, NEES, the plan's and the PEF's bounds at the true pose."""
    err_xy = true_pose[:, :2] - est_pose[:, :2]
    dth = (true_pose[:, 2] - est_pose[:, 2] + math.pi) % (2 * math.pi) - math.pi
    e = np.column_stack([err_xy, dth])
    nees = np.einsum("ti,ti->t", e, np.linalg.solve(est_cov, e[:, :, None])[:, :, 0])
    predicted = np.interp(s_est, schedule.s, schedule.predicted_error)
    if pef.model is PefModel.EXACT:
        # the exact diameter clips ~14 candidate subsets per step with shapely (45 s for a
        # 26 s episode); its linearisation is within ~rho / r of it (StepLog.pef_tau)
        pef = PEF(pef.scenario, model=PefModel.STRIPS, k=pef.k, redundancy=pef.redundancy)
    pef_tau = pef.at(true_pose[:, :2]).tau
    return StepLog(t=t, true_pose=true_pose, est_pose=est_pose, est_cov=est_cov,
                   error=np.hypot(err_xy[:, 0], err_xy[:, 1]), predicted_tau=predicted,
                   pef_tau=pef_tau, nees=nees)


def seed_repr(ss: np.random.SeedSequence) -> int | str:
    """Return the seed as the summary shows it: the entropy, with the spawn key after a colon."""
    if not ss.spawn_key:
        return int(ss.entropy)
    return f"{ss.entropy}:{'/'.join(str(k) for k in ss.spawn_key)}"


def summarize(steps: StepLog, fixes, reached: bool, eps_max: float, ss, skipped: int, merged: int) -> dict:
    """Return the summary's accuracy and count keys of one robot's episode."""
    err = steps.error
    acc = fixes.n_accepted.sum()
    return {
        "reached": reached,
        "duration": float(steps.t[-1]),
        "steps": int(len(steps.t)),
        "fixes": int(len(fixes.t)),
        "skipped_fixes": int(skipped),
        "merged_fixes": int(merged),
        "rmse": float(np.sqrt(np.mean(err**2))),
        "max_error": float(err.max()),
        "max_predicted_tau": float(np.max(steps.predicted_tau)),
        "eps_max": float(eps_max),
        "violations": int(np.sum(err > eps_max)),
        "seed": seed_repr(ss),
        "mean_nees": float(np.mean(steps.nees)),
        "mean_nis": float(fixes.nis.sum() / acc) if acc else math.nan,
    }
