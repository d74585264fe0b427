"""One episode: plan, drive on the estimate, measure, estimate, and record what happened.

The loop runs at the control rate (a whole number of physics steps); fixes interrupt it at the
physics step each measurement falls due, so every measurement happens at its own time while
the robot keeps moving. Randomness comes from four generators spawned from the episode's
seed: the start pose, the laser noise, the odometry slip noise and the blocked lines of sight
(``sensor.block_probability``: at each fix start every marker is blocked for that fix with
that probability, independently; the laser reports a blocked marker unseen and the robot
measures the schedule's fallback subset instead).

Every scheduled fix is accounted for in the summary: taken (a row of the fix log), merged into a
later one (``merged_fixes``: the laser was still busy when it fell due), failed (``failed_fixes``:
too few markers seen, or one lost mid-fix) or unreached (``unreached_fixes``: the time limit ran
out first). The follower is done within its goal tolerance of the path's end, short of the
schedule's last fixes; the robot then holds at the goal and takes them there, one after another.
With ``montecarlo.hold`` it then stands at the goal that long, parked
(:meth:`sim.physics.robot.DiffDriveRobot.park`), fixing at the laser's rate (:func:`hold_fix`).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np

from planner.pef.map import PEF
from planner.plan import Plan
from planner.schedule.promise import POLYGON_TOLERANCE, START_LAG
from scenarios import PlanningError, Scenario, SimulationError
from scenarios.schema import NoiseModel, PefModel
from sim.episode.certify import certified_bound, lost_markers, single_failure_excused
from sim.episode.control_tick import LOG_COLUMNS, LOG_COV, LOG_EST, LOG_S, LOG_T, LOG_TRUE, ControlTick
from sim.episode.follower import PurePursuit, wheel_speeds
from sim.episode.types import EpisodeResult, StepLog
from sim.physics.turn_lag import read_turn_slip

CONTROL_STEPS = 4
"""Physics steps per control step: 60 Hz control at pybullet's 240 Hz. An odometry increment
is then at most 1.7 cm at 1 m/s, inside the 2 cm the planner's drift bound assumes."""

START_POS_STD = 0.001
"""Standard deviation of the start position about the dock [m]: docks are calibrated."""
START_YAW_STD = math.radians(0.1)
"""Standard deviation of the start heading about the dock's [rad]."""


@dataclass
class Prepared:
    """What an episode needs that does not depend on its seed: the plan and the PEF.

    Build it once per scenario and task (:func:`prepare`) and pass it to every run.
    """

    task_index: int
    plan: Plan
    pef: PEF


def check_task(scenario: Scenario, task_index: int) -> None:
    """Raise :class:`SimulationError` unless ``task_index`` names a task of ``scenario``."""
    n = len(scenario.tasks)
    if not (isinstance(task_index, (int, np.integer)) and 0 <= task_index < n):
        raise SimulationError(f"{scenario.source}: task {task_index}: expected a task index in 0..{n - 1} "
                              f"({n} tasks)" if n else f"{scenario.source}: tasks: the scenario has no task")


def check_markers(scenario: Scenario) -> None:
    """Raise :class:`SimulationError` when the scenario has too few markers for any fix (so no plan)."""
    k = scenario.sensor.markers_per_fix
    if len(scenario.markers) < k:
        raise SimulationError(f"{scenario.source}: markers: the scenario has {len(scenario.markers)} markers, a fix "
                              f"needs {k}: no plan is possible (pefsim place finds where to put reflectors)")


def prepare(scenario: Scenario, task_index: int = 0, pef=None) -> Prepared:
    """Plan task ``task_index`` of ``scenario`` once (raises PlanningError if it cannot)."""
    from planner.pef.map import PEF
    from planner.plan import plan_task

    check_task(scenario, task_index)
    check_markers(scenario)
    pef = pef if pef is not None else PEF(scenario)
    task = scenario.tasks[task_index]
    where = f"{scenario.source}: tasks[{task_index}] ({task.start} -> {task.goal})"
    dock = scenario.dock(task.start)
    k = scenario.sensor.markers_per_fix
    seen = int(pef.visible(np.array([dock.position])).sum())
    if seen < k:
        raise SimulationError(f"{where}: {seen} marker(s) visible from dock {task.start} at "
                              f"{list(dock.position)}, a fix needs {k}")
    try:
        plan = plan_task(scenario, task_index, pef=pef)
    except PlanningError as exc:
        raise PlanningError(f"{where}: {exc}") from None
    if plan.schedule is None:
        raise PlanningError(f"{scenario.source}: task {task_index}: the plan has no measurement schedule")
    return Prepared(task_index=task_index, plan=plan, pef=pef)


def seed_sequence(seed: int | np.random.SeedSequence) -> np.random.SeedSequence:
    """Return the episode's SeedSequence from an int or a SeedSequence (used as is)."""
    if isinstance(seed, np.random.SeedSequence):
        return seed
    if isinstance(seed, (bool, float)) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise SimulationError(f"seed: expected a non-negative integer, got {seed!r}")
    return np.random.SeedSequence(int(seed))


def _streams(ss: np.random.SeedSequence) -> tuple[np.random.Generator, ...]:
    # Children are derived from (entropy, spawn_key) rather than ss.spawn(), which counts
    # calls: the same seed must give the same streams however often it is used.
    keys = ("start", "laser", "odometry", "block")
    return tuple(np.random.default_rng(np.random.SeedSequence(ss.entropy, spawn_key=(*ss.spawn_key, j)))
                 for j, _ in enumerate(keys))


def run_episode(scenario: Scenario, task_index: int = 0, seed: int | np.random.SeedSequence = 0,
                world=None, prepared: Prepared | None = None, time_limit: float | None = None,
                q_scale: float = 1.0) -> EpisodeResult:
    """Drive task ``task_index`` once and return every array of interest.

    Parameters
    ----------
    scenario : Scenario
    task_index : int
        Index into ``scenario.tasks``.
    seed : int or numpy.random.SeedSequence
        Root of the episode's random streams.
    world : sim.physics.world.PhysicsWorld, optional
        A world built for ``scenario`` to reuse (it is reset); by default one is built and closed.
    prepared : Prepared, optional
        The plan and PEF from :func:`prepare` (computed here when not given).
    time_limit : float, optional
        Give up after this many simulated seconds [s]; default 3x the planned time + 30 s.
    q_scale : float
        Multiplies the filter's process noise (1 = the declared model; negative controls).

    Returns
    -------
    EpisodeResult
    """
    from sim.physics.world import PhysicsWorld

    check_task(scenario, task_index)
    ss = seed_sequence(seed)
    prepared = prepared if prepared is not None else prepare(scenario, task_index)
    own_world = world is None
    world = PhysicsWorld(scenario) if own_world else world
    try:
        return _drive(scenario, task_index, ss, world, prepared, time_limit, q_scale)
    finally:
        if own_world:
            world.close()


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


def encoder_phases(rng: np.random.Generator) -> np.ndarray:
    """Draw where each encoder's tick edges sit on its wheel at a run's start, shape (2,) [ticks].

    Uniform in ``[0, 1)``, left then right (:class:`sim.physics.odometry.WheelOdometry`'s
    ``phase``). A fleet's missions start with the wheels wherever they stopped; the same
    sub-tick phase in every run of a sweep would make the encoders' count errors, which the
    filter treats as random, the same in every run, and the N-run tests, which average
    independent runs, would see them as a bias.
    """
    return rng.uniform(0.0, 1.0, 2)


def _drive(scenario, task_index, ss, world, prepared, time_limit, q_scale) -> EpisodeResult:
    from sim.episode.fixes import FixRecorder
    from sim.physics.laser import LaserSensor
    from sim.physics.odometry import WheelOdometry

    rng_start, rng_laser, rng_odo, rng_block = _streams(ss)
    task = scenario.tasks[task_index]
    plan, pef = prepared.plan, prepared.pef
    robot, actual = scenario.robot, scenario.robot_actual
    k = scenario.sensor.markers_per_fix
    dock = scenario.dock(task.start)

    P0 = np.diag([START_POS_STD**2, START_POS_STD**2, START_YAW_STD**2])
    true_start = np.array(dock.pose) + rng_start.multivariate_normal(np.zeros(3), P0)
    phase = encoder_phases(rng_start)
    world.reset(true_start)
    laser = LaserSensor(world, scenario.sensor_actual, scenario.marker_positions(), scenario.marker_normals())
    n_visible = int(laser.visible_all().sum())
    if n_visible < k:
        raise SimulationError(
            f"{scenario.source}: tasks[{task_index}]: {n_visible} marker(s) visible from dock {task.start} "
            f"at {list(dock.position)}, a fix needs {k}")

    angles0 = world.robot.wheel_angles()
    loc = episode_localizer(scenario, np.array(dock.pose), P0, q_scale=q_scale, step_time=world.config.time_step)
    # The simulated floor's random slip, per unit of travel, goes into the odometry readings
    # (bounded in a bounded-noise world); the odometry's dead reckoning carries the ranges of a
    # fix to its end (FixRecorder).
    odo = WheelOdometry(robot, angles0, np.array(dock.pose), slip_std=actual.odometry_noise, rng=rng_odo,
                        bounded=scenario.sensor_actual.noise is NoiseModel.UNIFORM, phase=phase)
    fixes = FixRecorder(scenario, pef, laser, loc, rng_laser)
    q_block, n_markers = scenario.sensor_actual.block_probability, len(scenario.markers)
    follower = PurePursuit(path=plan.path, speed=plan.speed, max_speed=robot.max_speed,
                           max_yaw_rate=robot.max_yaw_rate)
    schedule = plan.schedule
    fix_s = np.array([f.s for f in schedule.fixes])
    # The schedule spaces fix starts by the sensor's rate in planned time, but a start can only
    # happen at a control step: holding two starts a full period apart would delay each fix by up
    # to one control step more than the last, until a fix is skipped (the robot then fixes
    # ~0.2 s of travel away from where the plan promised). Starts may come up to one control
    # step closer, so each fix starts within one control step of its planned place.
    min_gap = 1.0 / scenario.sensor.fix_rate_hz - CONTROL_STEPS * world.config.time_step

    dt_phys = world.config.time_step
    dt_ctrl = CONTROL_STEPS * dt_phys
    if dt_ctrl + dt_phys > START_LAG * (1.0 + 1e-9):
        # a fix starts up to a control tick late and measures up to a physics step late: the
        # plan's promises hold for starts up to START_LAG late only
        raise SimulationError(f"physics time_step {dt_phys:g} s: a fix may start {dt_ctrl + dt_phys:.4g} s late, "
                              f"the plan's promises allow {START_LAG:.4g} s")
    planned_time = float(np.sum(np.diff(plan.s) / np.maximum(plan.speed[1:], 0.05)))
    hold = scenario.montecarlo.hold
    t_max = time_limit if time_limit is not None else 3.0 * planned_time + 30.0 + hold
    n_max = int(t_max / dt_ctrl) + 2
    log = np.empty((n_max, LOG_COLUMNS))
    tick = ControlTick(odo, loc, follower, log, dt_ctrl)
    watch = run_watch(world, 0, follower, dt_ctrl)

    wheel_angles, predict = world.robot.wheel_angle_pair, loc.predict

    def read_span() -> tuple[float, int]:
        # a read now: its turn slip (the physics' lag depends on the steps it spans) and span
        steps, counts["last_read"] = world.steps - counts["last_read"], world.steps
        return read_turn_slip(robot.turn_slip, steps, CONTROL_STEPS), steps

    def read_odometry() -> None:
        d_left, d_right = odo.update(wheel_angles())
        predict(d_left, d_right, *read_span())
        counts["reads"] += 1

    next_fix, last_fix_start, done, n = 0, -math.inf, False, 0
    hold_until: float | None = None   # when the hold at the goal ends (montecarlo.hold)
    # reads: odometry reads outside the control ticks; last_read: the physics step of the last read
    counts = {"merged": 0, "reads": 0, "last_read": world.steps}

    fix_s_list = fix_s.tolist()  # compared at every control step: floats, not numpy scalars
    # the single-failure test: with lines of sight blocked, the guarantee must survive one of
    # them lost at any fix (a redundancy-0 layout is held to it too; the schedule's one
    # fallback per marker covers no more, whatever planning.redundancy says)
    attempts: list[tuple[float, bool]] = []

    def start_fix(s_now: float, t: float) -> None:
        # Start the latest scheduled fix the robot has passed, when the laser is free again.
        nonlocal next_fix, last_fix_start
        if fixes.pending is not None or next_fix >= len(fix_s_list) or s_now < fix_s_list[next_fix] \
                or t - last_fix_start < min_gap - 1e-9:
            return
        f = bisect.bisect_right(fix_s_list, s_now) - 1
        # scheduled fixes the laser could not start in time are merged into this one: count them
        counts["merged"] += f - next_fix
        if q_block > 0.0:
            # one draw per marker and fix start, whatever is scheduled: the stream stays aligned
            laser.blocked = frozenset(np.flatnonzero(rng_block.random(n_markers) < q_block).tolist())
            fixes.blocked_markers += len(laser.blocked & set(schedule.fixes[f].markers))
            lost = lost_markers(laser.blocked, schedule.fixes[f].markers, schedule.fixes[f].fallbacks)
            attempts.append((t, lost > 1))
        subset = fixes.choose_subset(schedule.fixes[f].markers, loc.x[:2], schedule.fixes[f])
        if subset is None:
            fixes.skipped += 1
        else:
            fixes.start(subset, t, schedule.fixes[f])
            last_fix_start = t
        next_fix = f + 1

    step, pose_now = world.step, world.robot.true_pose_tuple

    def advance() -> None:
        # One control period, stopping at each physics step a measurement falls due.
        if fixes.pending is None:
            step(CONTROL_STEPS)
            return
        end = world.steps + CONTROL_STEPS
        # The control tick has just read the odometry at this physics step. A second read at the
        # same step reports zero travel, and the filter's predict would replace each wheel's
        # quantisation residual by an independent one, where the encoder's is unchanged: the
        # estimate lost what the fix's updates taught it about the residuals, and the filter
        # turned inconsistent (random-23-016, with a fix's reads all on control ticks: NEES
        # 2.884, NIS 1.009).
        read_at = world.steps
        while world.steps < end:
            due = fixes.next_due
            due_step = math.ceil(due / dt_phys - 1e-9) if due < math.inf else end
            if due_step < end:
                world.step(max(due_step - world.steps, 0))
                if world.steps != read_at:
                    read_odometry()
                    read_at = world.steps
                # every control tick reads the odometry once: n of them so far
                fixes.measure_due(odo.pose, pose_now(), world.time, n + counts["reads"], odo.slip_weight,
                                  odo.wheel_paths)
            else:
                world.step(end - world.steps)

    # The schedule's first fix is taken at standstill on the dock, before the robot leaves.
    holding = len(fix_s) > 0 and fix_s[0] <= 1e-9
    s_now = 0.0
    true_pose = world.robot.true_pose_tuple

    def set_wheel_speeds(left: float, right: float) -> None:
        # the motors, and the filter, which predicts each read's turn from what they were told
        world.robot.set_wheel_speeds(left, right)
        loc.set_command(left, right)
    radius, base = robot.wheel_radius, robot.wheel_base
    while n < n_max:
        t = world.time
        # odometry, predict, log row n (the arc length of this step's estimate) and, unless the
        # robot is held or done, the follower's command from this step's estimate
        pose = true_pose()
        v, omega, cmd_done, s_cmd = tick(wheel_angles(), pose, t, n, s_now, not (holding or done), *read_span())
        watch.tick(t, pose, not (holding or done))
        n += 1
        if done:
            if fixes.pending is None and next_fix >= len(fix_s_list):
                if hold_until is None:
                    hold_until = t + hold
                if t >= hold_until - 1e-9:
                    break
                # held at the goal (montecarlo.hold): parked, re-localising at the laser's rate
                world.robot.park(True)
                set_wheel_speeds(0.0, 0.0)
                last_fix_start = hold_fix(fixes, schedule, loc.x[:2], t, last_fix_start, min_gap)
                advance()
                continue
            # Stopped at the goal short of the schedule's last fixes (they lie within a fix gap
            # of it, where the follower is done): held there, the robot finishes the fix under
            # way and takes each of them in turn, at the goal, as the laser's rate allows.
            set_wheel_speeds(0.0, 0.0)
            if next_fix < len(fix_s_list):
                start_fix(fix_s_list[next_fix], t)
            advance()
            continue
        if holding:
            start_fix(0.0, t)
            holding = fixes.pending is not None
            if holding:
                set_wheel_speeds(0.0, 0.0)
                advance()
                continue
            v, omega, cmd_done, s_cmd = follower.command(loc.x, dt_ctrl)
            log[n - 1, LOG_S] = s_cmd
        s_now, done = s_cmd, cmd_done
        if done:
            set_wheel_speeds(0.0, 0.0)
            continue
        start_fix(s_now, t)
        set_wheel_speeds(*wheel_speeds(v, omega, radius, base))
        advance()

    # the time limit ran out before these were taken (the one under way included)
    unreached = len(fix_s_list) - next_fix + int(fixes.pending is not None)
    log = log[:n]
    steps = _step_log(log[:, LOG_T], log[:, LOG_TRUE], log[:, LOG_EST], log[:, LOG_COV].reshape(n, 3, 3),
                      log[:, LOG_S], schedule, pef)
    fix_log = fixes.log()
    certified = certified_bound(robot, steps.t, log[:, LOG_S], steps.est_pose[:, 2], fix_log.t,
                                fix_log.predicted_tau, k * scenario.sensor.measurement_time)
    steps.certified = certified
    lost_guarantee = 0
    if q_block > 0.0:
        at = np.array(attempts, dtype=float).reshape(-1, 2)
        planned = ~np.asarray(fix_log.beyond_redundancy, bool) & np.isfinite(fix_log.predicted_tau)
        excused = single_failure_excused(steps.t, at[:, 0], at[:, 1] > 0.5, fix_log.t, planned,
                                         k * scenario.sensor.measurement_time)
        lost_guarantee = int(np.sum((certified > scenario.planning.eps_max * (1.0 + POLYGON_TOLERANCE)) & ~excused))
        steps.excused = excused
    goal = np.array(scenario.dock(task.goal).position)
    outcome = watch.summary()
    # a run that touched something, or stuck, did not do what was asked, wherever it ended
    reached = bool(done and np.hypot(*(steps.true_pose[-1, :2] - goal)) <=
                   follower.goal_tolerance + scenario.planning.eps_max and outcome["status"] == "ok")
    return EpisodeResult(
        scenario_name=scenario.name, task_index=task_index, seed=_seed_repr(ss),
        eps_max=scenario.planning.eps_max, steps=steps, fixes=fix_log, plan=plan,
        summary={**_summary(steps, fix_log, reached, scenario.planning.eps_max, ss, fixes.skipped,
                            counts["merged"]), "scheduled_fixes": len(fix_s),
                 "blocked_markers": fixes.blocked_markers, "fallback_fixes": int(np.sum(fix_log.fallback)),
                 "failed_fixes": fixes.skipped, "unreached_fixes": unreached,
                 "certified_max": float(np.max(certified, initial=0.0)), "lost_guarantee": lost_guarantee,
                 **outcome})


def run_watch(world, i: int, follower: PurePursuit, dt_ctrl: float, wait_limit: float = math.inf,
              names: list[str] | None = None):
    """Build the :class:`~sim.episode.outcome.RunWatch` of robot ``i`` of ``world``, following ``follower``'s path."""
    from sim.episode.outcome import RunWatch, stuck_bound
    from sim.physics.contacts import ContactMonitor

    bound = stuck_bound(follower.max_yaw_rate, follower.max_yaw_accel, follower.max_speed, follower.max_accel)
    return RunWatch(ContactMonitor(world, i), follower.path, bound, dt_ctrl, wait_limit, names)


def hold_fix(fixes, schedule, est_xy: np.ndarray, t: float, last_start: float, min_gap: float,
             note=None) -> float:
    """Start a fix at the goal of a robot held there, if the laser is free; return the last fix start [s].

    The fix measures the schedule's last subset (its fallback where blocked), under that fix's
    promise, at most one per ``min_gap`` [s]; ``note`` is kept with its row (``FixRecorder.start``).
    """
    if fixes.pending is not None or t - last_start < min_gap - 1e-9 or not schedule.fixes:
        return last_start
    sched = schedule.fixes[-1]
    subset = fixes.choose_subset(sched.markers, est_xy, sched)
    if subset is None:
        return last_start
    fixes.start(subset, t, sched, note=note)
    return t


def _step_log(t, true_pose, est_pose, est_cov, s_est, schedule, pef) -> StepLog:
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


def _seed_repr(ss: np.random.SeedSequence) -> int | str:
    if not ss.spawn_key:
        return int(ss.entropy)
    return f"{ss.entropy}:{'/'.join(str(k) for k in ss.spawn_key)}"


def _summary(steps: StepLog, fixes, reached: bool, eps_max: float, ss, skipped: int, merged: int) -> dict:
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
        "seed": _seed_repr(ss),
        "mean_nees": float(np.mean(steps.nees)),
        "mean_nis": float(fixes.nis.sum() / acc) if acc else math.nan,
    }
