"""The error bound an episode's fixes actually certified: the plan's promise, as driven.

The plan promises ``err(s) = tau_i + drift(s - s_i)`` with every scheduled fix taken. When lines
of sight are blocked, some fixes are taken with a fallback subset (another promise) and some
not at all (the drift runs on from the previous fix). The *certified* bound at a control step
is the promise of the last fix completed before it plus the drift bound
(:func:`planner.schedule.drift.drift_bound`, the planner's) over the arc length and turning
since that fix started; before the first fix the calibrated dock stands in for one (promise 0,
the robot is held there until the first fix completes). It depends only on which fixes were taken
and their promises, not on the noise: a run keeps its guarantee when the bound stays under
eps_max, which is what redundancy buys (the realised error is usually far smaller).
"""

from __future__ import annotations

import numpy as np

from planner.schedule.drift import drift_bound
from scenarios.schema import RobotSpec


def certified_bound(robot: RobotSpec, t: np.ndarray, s: np.ndarray, heading: np.ndarray,
                    fix_t: np.ndarray, fix_tau: np.ndarray, fix_time: float) -> np.ndarray:
    """Certified position error bound at each control step, shape (N,) [m].

    Parameters
    ----------
    robot : RobotSpec
        The declared robot (the drift model the plan used).
    t : ndarray, shape (N,)
        Step times [s], ascending.
    s : ndarray, shape (N,)
        Arc length along the path at each step [m].
    heading : ndarray, shape (N,)
        Estimated heading at each step [rad].
    fix_t : ndarray, shape (F,)
        Completion time of each fix taken [s], ascending.
    fix_tau : ndarray, shape (F,)
        Each fix's promise [m] (inf when none was made).
    fix_time : float
        Duration of a fix, k * measurement_time [s]: a fix's drift runs from its start.
    """
    t, s = np.asarray(t, float), np.asarray(s, float)
    turn = np.concatenate([[0.0], np.cumsum(np.abs(np.angle(np.exp(1j * np.diff(np.asarray(heading, float))))))])
    # the dock as fix -1: completed at t[0], promise 0
    fix_t = np.concatenate([[t[0] + fix_time], np.asarray(fix_t, float)])
    fix_tau = np.concatenate([[0.0], np.asarray(fix_tau, float)])
    li = np.maximum(np.searchsorted(fix_t, t, side="right") - 1, 0)
    start_t = fix_t[li] - fix_time
    # arc length and turning at each fix's start, interpolated on the step times
    s0 = np.interp(start_t, t, s)
    turn0 = np.interp(start_t, t, turn)
    drift = drift_bound(robot, np.maximum(s - s0, 0.0), np.maximum(turn - turn0, 0.0))
    return fix_tau[li] + drift
