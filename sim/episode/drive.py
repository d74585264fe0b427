"""A lone robot's episode: plan its task, drive it on the estimate, measure, estimate, record.

The robot is a :class:`sim.episode.driver.RobotDriver` (what every robot of every episode is:
its loop, fixes, hold at the goal, certified bound and summary live there) alone in the physics
world, with the floor to itself: no zone control, no other robots' bodies. This module schedules
it: one control tick after another, with the physics between them (:func:`sim.episode.driver.advance`),
until it has finished or the time limit runs out. Its random streams come from the episode's seed
(:func:`sim.episode.driver.streams`): the start pose, the laser noise, the odometry slip noise and
the blocked lines of sight (``sensor.block_probability``: at each fix start every marker is
blocked for that fix with that probability, independently; the laser reports a blocked marker
unseen and the robot measures the schedule's fallback subset instead).

Two things a lone episode does that a fleet's does not (:mod:`sim.episode.fleet`): on the tick
its follower is done the robot stops its wheels and its next control tick follows at the same
physics step (a fleet's robot goes on at once, its fleet mates drive on); and the episode ends at
the tick the robot has finished, where a fleet's steps on and logs a last row for every robot.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.pef.map import PEF
from planner.plan import Plan
from scenarios import PlanningError, Scenario, SimulationError
from sim.episode.driver import Mission, RobotDriver, advance, check_control_period
from sim.episode.types import EpisodeResult


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


def _drive(scenario, task_index, ss, world, prepared, time_limit, q_scale) -> EpisodeResult:
    dt_ctrl = check_control_period(world)
    plan = prepared.plan
    planned_time = float(np.sum(np.diff(plan.s) / np.maximum(plan.speed[1:], 0.05)))
    hold = scenario.montecarlo.hold
    t_max = time_limit if time_limit is not None else 3.0 * planned_time + 30.0 + hold
    n_max = int(t_max / dt_ctrl) + 2
    mission = Mission([plan], (task_index,), np.zeros(1), f"tasks[{task_index}]")
    robot = RobotDriver(0, scenario, mission, world, prepared.pef, ss, n_max, q_scale)
    world.reset(robot.true_start)
    robot.check_visible()
    robot.begin(dt_ctrl)
    n = 0
    while n < n_max:
        arrived = robot.control(world.time)
        n += 1
        if robot.finished:
            break
        if arrived:
            # stopped at the goal: the next tick, at this same physics step, goes on from there
            robot.command(0.0, 0.0)
            continue
        advance(world, [robot])
    return robot.result(scenario.name)


