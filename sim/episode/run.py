"""One run of a scenario, whoever drives it: a lone robot one of its tasks, or a fleet all its robots' tasks.

Every robot of every run is a :class:`sim.episode.driver.RobotDriver`; what differs is how the
run schedules them, and that is chosen here, once: a scenario without ``[[robots]]`` is a fleet
of its one robot, with the floor to itself (:mod:`sim.episode.drive`); one with ``[[robots]]``
drives them together under zone control (:mod:`sim.episode.fleet`). :func:`run` returns the
lone robot's :class:`~sim.episode.types.EpisodeResult` or the fleet's
:class:`~sim.episode.types.FleetResult`; both give their ``robots`` (one
:class:`~sim.episode.types.RobotResult` each, a lone robot's without a name) and ``names``, and
print themselves (``to_dict``, ``lines``), so that what reads a run (sweeps, recordings, the
command line) has one path.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from scenarios import Scenario, ScenarioError
from sim.episode import drive, fleet
from sim.episode.types import EpisodeResult, FleetResult


def task_choices(scenario: Scenario) -> int:
    """Return how many different runs ``scenario`` has: one per task of a lone robot, one for a fleet.

    A fleet's run drives every robot through all its tasks (run index 0 names it).
    """
    return 1 if scenario.robots else len(scenario.tasks)


def check_task(scenario: Scenario, task: int | None) -> None:
    """Raise a one-line ScenarioError unless ``task`` (None: each in turn) names one of ``scenario``'s runs."""
    if task is None:
        return
    if scenario.robots:
        raise ScenarioError(f"task: {scenario.source} is a fleet ([[robots]]): every run drives all its robots' "
                            f"tasks, got task {task}")
    if not 0 <= task < len(scenario.tasks):
        raise ScenarioError(f"task: expected 0 .. {len(scenario.tasks) - 1} "
                            f"({len(scenario.tasks)} tasks in {scenario.source}), got {task}")


def check_episode_task(scenario: Scenario, task: int | None) -> int:
    """Return the task index a run of ``scenario`` is given: the lone robot's ``task`` (default 0), 0 for a fleet.

    Raises a one-line error for a task a lone robot does not have, or any task given for a fleet.
    """
    if scenario.robots:
        if task is not None:
            raise ScenarioError(f"task: {scenario.source} is a fleet ([[robots]]): every run drives all its "
                                f"robots' tasks, got task {task}")
        return 0
    task = 0 if task is None else task
    drive.check_task(scenario, task)
    return task


def prepare(scenario: Scenario, task_index: int = 0, *, traffic: bool = True, pef=None) -> Any:
    """Plan a run once (what does not depend on its seed): task ``task_index``, or the whole fleet.

    ``traffic`` False plans each fleet robot's measurement schedule as if it drove alone (a
    negative control; a lone robot drives alone anyway).
    """
    if scenario.robots:
        return fleet.prepare_fleet(scenario, pef=pef, traffic=traffic)
    return drive.prepare(scenario, task_index, pef=pef)


def make_world(scenario: Scenario):
    """Build the physics world of ``scenario``'s runs (with every robot's body for a fleet)."""
    from sim.physics.world import PhysicsWorld

    return PhysicsWorld(scenario, fleet=bool(scenario.robots))


def run(scenario: Scenario, task_index: int = 0, seed: int | np.random.SeedSequence = 0, world=None,
        prepared: Any = None, time_limit: float | None = None, q_scale: float = 1.0) -> EpisodeResult | FleetResult:
    """Drive one run of ``scenario`` and return each robot's episode.

    Parameters
    ----------
    scenario : Scenario
    task_index : int
        The lone robot's task (a fleet's robots drive theirs).
    seed : int or numpy.random.SeedSequence
        Root of the run's random streams (robot 0 draws what a lone robot would).
    world : sim.physics.world.PhysicsWorld, optional
        A world from :func:`make_world` to reuse (it is reset); by default one is built and closed.
    prepared : optional
        From :func:`prepare` (computed here when not given).
    time_limit : float, optional
        Give up after this many simulated seconds [s].
    q_scale : float
        Multiplies every filter's process noise (negative controls).

    Returns
    -------
    EpisodeResult or FleetResult
        The lone robot's episode, or every robot's (``robots``) and the fleet's overlaps.
    """
    if scenario.robots:
        return fleet.run_fleet_episode(scenario, seed=seed, world=world, prepared=prepared, time_limit=time_limit,
                                       q_scale=q_scale)
    return drive.run_episode(scenario, task_index, seed=seed, world=world, prepared=prepared, time_limit=time_limit,
                             q_scale=q_scale)
