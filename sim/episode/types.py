"""What one episode returns: per-step and per-fix arrays and a summary.

Kept apart from the episode loop so that recording, Monte-Carlo and validation can depend on
the result's shape without importing pybullet.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
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
        at the fix start (:attr:`planner.fleet.exposure.RobotBlocking.p_fix`); NaN: none made.
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
