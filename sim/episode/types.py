"""What one episode returns: per-step and per-fix arrays and a summary.

Kept apart from the episode loop so that recording, Monte-Carlo and validation can depend on
the result's shape without importing pybullet.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # the type only: results readers need not import the planner
    from planner.plan import Plan


@dataclass
class StepLog:
    """Per control step arrays, T steps (the control rate, not the physics rate).

    Attributes
    ----------
    t : (T,) float
        Simulation time [s].
    true_pose : (T, 3) float
        True pose (x [m], y [m], theta [rad]) from the physics world.
    est_pose : (T, 3) float
        EKF estimate.
    est_cov : (T, 3, 3) float
        EKF covariance [m^2, m rad, rad^2].
    error : (T,) float
        Position error |true - estimate| [m].
    predicted_tau : (T,) float
        Planner's predicted error bound at the true position: the PEF τ of the scheduled
        subset's last fix plus the drift since it (the schedule's promise at this arc length) [m].
    pef_tau : (T,) float
        PEF τ (best visible subset) at the true position [m]; inf where not enough markers.
        Under the ``exact`` model it is the linearised region's (``strips``): within ~rho / r
        (~1e-3) of the exact diameter, which costs ~30 ms a step of shapely clipping.
    nees : (T,) float
        Normalised estimation error squared of the full pose (3 dof).
    certified : (T,) float or None
        The bound the fixes actually taken certify (:mod:`sim.episode.certify`) [m].
    excused : (T,) bool or None
        Steps the single-failure test does not judge: a fix lost more lines of sight than it
        allows (:func:`sim.episode.certify.single_failure_excused`); None without blocking.
    """

    t: np.ndarray
    true_pose: np.ndarray
    est_pose: np.ndarray
    est_cov: np.ndarray
    error: np.ndarray
    predicted_tau: np.ndarray
    pef_tau: np.ndarray
    nees: np.ndarray
    certified: np.ndarray | None = None
    excused: np.ndarray | None = None


@dataclass
class FixLog:
    """Per fix arrays, F fixes of k markers each.

    Attributes
    ----------
    t : (F,) float
        Time the fix completed (its last measurement) [s].
    markers : (F, k) int
        Marker indices measured, in order.
    ranges : (F, k) float
        Measured ranges [m].
    rho : (F, k) float
        Declared range bounds ρ = Re·r + ρ0 used by the filter and the fault area [m].
    true_position : (F, 2) float
        True position when the fix completed [m].
    snapshot : (F, 2) float
        Snapshot least-squares position from this fix alone [m] (earlier measurements of the
        fix are carried to the completion time by odometry).
    snapshot_cov : (F, 2, 2) float
        Its least-squares covariance [m^2].
    fault_diameter : (F,) float
        Diameter of the realised exact fault area [m] (nan if empty: inconsistent data).
    fault_polygons : list of (n_i, 2) float arrays
        Exterior rings of the realised exact fault areas [m].
    contained : (F,) bool
        True position inside the realised fault area (within the polygonisation tolerance).
    predicted_tau : (F,) float
        The plan's promise for the fix: fault-area diameter of the moving fix at the planned
        poses (``planner.schedule.schedule.ScheduledFix.predicted_tau``, or the same construction for a
        fallback subset) [m].
    static_tau : (F,) float
        The paper's static PEF τ of the fix's subset at the true position [m].
    nis : (F,) float
        Sum over the fix's accepted updates of the normalised innovation squared.
    n_accepted : (F,) int
        Updates that passed the gate.
    fallback : (F,) bool
        The fix measured the schedule's fallback subset (a scheduled marker was blocked).
    beyond_redundancy : (F,) bool
        Blocked lines of sight left neither the scheduled subset nor its fallback: the robot
        improvised with the best visible subset, which the plan promised nothing for.
    unplanned : (F,) bool
        The fix measured a subset the plan did not schedule (neither the fix's subset nor its
        fallback): a substitute, for blocked lines of sight (then ``beyond_redundancy`` too) or
        because the laser did not see a marker the plan counted on. ``predicted_tau`` is then
        the promise of what it measured, at the scheduled poses.
    notes : list or None
        What the episode noted with each fix (a fleet's episode: a :class:`FixNote`); None where
        nothing was noted.
    """

    t: np.ndarray
    markers: np.ndarray
    ranges: np.ndarray
    rho: np.ndarray
    true_position: np.ndarray
    snapshot: np.ndarray
    snapshot_cov: np.ndarray
    fault_diameter: np.ndarray
    fault_polygons: list[np.ndarray]
    contained: np.ndarray
    predicted_tau: np.ndarray
    static_tau: np.ndarray
    nis: np.ndarray
    n_accepted: np.ndarray
    fallback: np.ndarray | None = None
    beyond_redundancy: np.ndarray | None = None
    unplanned: np.ndarray | None = None
    notes: list | None = None


@dataclass(frozen=True)
class FixNote:
    """What a fleet's episode notes with a fix.

    Attributes
    ----------
    hidden : dict of int to int
        Each scheduled marker whose line of sight another robot's body hid at the fix start,
        to that robot's index.
    p_block_robot : float
        The plan's probability that another robot hides at least one of the scheduled markers
        at the fix start (:attr:`planner.fleet.exposure.RobotBlocking.p_fix`); NaN: none made (a
        fix on the final dock, or one whose blocking hinges on the tracking errors:
        :attr:`planner.fleet.exposure.RobotBlocking.undecided`).
    sight_hidden : dict of int to int
        Every marker, scheduled or not, whose line of sight another robot's body hid at the fix
        start while the laser would have seen it without the robots (in range, facing, no wall on
        the way: :meth:`sim.physics.laser.LaserSensor.hidden_by_robots`), to that robot's index.
        ``hidden`` is its part among the scheduled markers.
    """

    hidden: dict[int, int]
    p_block_robot: float = math.nan
    sight_hidden: dict[int, int] = field(default_factory=dict)


@dataclass
class EpisodeResult:
    """Everything one episode produced. ``summary`` is JSON-ready (see :func:`summary_keys`)."""

    scenario_name: str
    task_index: int
    seed: int
    eps_max: float
    steps: StepLog
    fixes: FixLog
    plan: Plan
    summary: dict[str, Any] = field(default_factory=dict)
    written: list[Path] = field(default_factory=list)
    """The files written of this run (TUM trajectories, then the recording), in that order;
    ``pefsim.run_episode`` fills it, the run itself writes none."""

    # A lone robot's run is a fleet of one: what reads a run's results reads both the same way.

    @property
    def robots(self) -> list[RobotResult]:
        """Return the run's robots: this episode's robot alone, without a name."""
        return [RobotResult(None, self, 0.0)]

    @property
    def names(self) -> list[str]:
        """Return the names of the run's robots: none (a lone robot has no name)."""
        return []

    def to_dict(self) -> dict[str, Any]:
        """Return the summary with JSON numbers (NaN and infinities as null), as ``pefsim run --json`` prints it."""
        from scenarios.jsonable import json_number

        return {k: json_number(v) for k, v in self.summary.items()}

    def lines(self, scenario: Any) -> list[str]:
        """Return the text ``pefsim run`` prints of this episode of ``scenario``."""
        from sim.episode.printout import episode_lines

        return episode_lines(scenario, self.task_index, self.summary)


@dataclass
class RobotResult:
    """One robot of a fleet episode: its episode over all its tasks, and what the fleet did to it.

    Attributes
    ----------
    name : str or None
        None for a lone robot (``[[robots]]`` names a fleet's).
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

    name: str | None
    result: EpisodeResult
    wait_time: float
    reserved: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    path: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))


@dataclass
class FleetResult:
    """A fleet's run: each robot's episode, and how often their footprints overlapped.

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
    written : list of Path
        The files written of this run, as :attr:`EpisodeResult.written`.
    """

    robots: list[RobotResult]
    collisions: int
    duration: float
    names: list[str] = field(default_factory=list)
    written: list[Path] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        """Return the run as ``pefsim run --json`` prints it: overlaps, duration and each robot's summary."""
        from scenarios.jsonable import json_number

        return {"collisions": self.collisions, "duration": self.duration,
                "robots": [{k: json_number(v) for k, v in r.result.summary.items()} for r in self.robots]}

    def lines(self, scenario: Any) -> list[str]:
        """Return the text ``pefsim run`` prints of this run of ``scenario``."""
        from sim.episode.printout import fleet_lines

        return fleet_lines(scenario, [(r.name, r.result.summary) for r in self.robots], self.collisions, self.duration)


SUMMARY_KEYS = ("reached", "duration", "steps", "fixes", "rmse", "max_error", "max_predicted_tau",
                "eps_max", "violations", "seed", "mean_nees", "mean_nis", "blocked_markers", "fallback_fixes",
                "failed_fixes", "certified_max", "lost_guarantee")
"""Keys of :attr:`EpisodeResult.summary` (``pefsim run --json`` prints them)."""

RUN_STATUSES = ("ok", "collided", "stuck", "deadlocked")
"""What a run that ran to its end did, from best to worst (:mod:`sim.episode.outcome`); a run that
did not run to its end has the status ``crashed: <error>``."""


def ran(status: str | None) -> bool:
    """Tell whether a run with ``status`` ran to its end (any of :data:`RUN_STATUSES`, not crashed)."""
    return status in RUN_STATUSES
