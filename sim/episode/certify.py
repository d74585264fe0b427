"""The error bound an episode's fixes actually certified: the plan's promise, as driven.

The plan promises ``err(s) = tau_i + drift(s - s_i)`` with every scheduled fix taken. When lines
of sight are blocked, some fixes are taken with a fallback subset (another promise) and some
not at all (the drift runs on from the previous fix). Each completed fix j certifies, from then
on, its promise plus the drift bound (:func:`planner.schedule.drift.drift_bound`, the planner's)
over the arc length and turning since it started; the position lies in all these regions at
once, so the *certified* bound at a control step is the smallest of them over the fixes
completed before it (a weak improvised fix does not undo a good earlier one, as in the
filter); the calibrated dock stands in for a fix at the start (promise 0). It depends only on
which fixes were taken and their promises, not on the noise: a run keeps its guarantee when the bound stays under
eps_max, which is what redundancy buys (the realised error is usually far smaller).
"""

from __future__ import annotations

import itertools

import numpy as np

from planner.schedule.drift import drift_bound
from scenarios.schema import RobotSpec

_CHUNK = 1 << 20
"""Fix-step pairs per vectorised pass (a few arrays of this many floats)."""


def heading_quantum(robot: RobotSpec) -> float:
    """Return the odometry's heading resolution [rad]: one encoder tick of one wheel over the wheel base."""
    return 2.0 * np.pi * robot.wheel_radius / robot.encoder_ticks / robot.wheel_base


def turning(heading: np.ndarray, quantum: float) -> np.ndarray:
    """Cumulative turning of an estimated heading, shape (N,) [rad], net of encoder quantisation.

    The estimate between fixes is integrated odometry: each wheel's count lags its true travel by
    less than a tick, so the estimated heading differs from the turning the wheels did by less than
    ``quantum`` (:func:`heading_quantum`), and on a straight it steps back and forth by a quantum
    from one control step to the next. Summing those steps counted turning the robot never did
    (0.049 rad in 2.3 s of straight aisle where the true heading turned 0.0015 rad), and the drift
    bound charged it: the certified bound passed eps_max with every scheduled fix taken. The
    turning counted here is the total variation of the *play* of the heading within
    ``+-quantum``: it moves only when the estimate leaves that band around it, which is the least
    turning any heading within a quantum of the estimate must have done.

    Parameters
    ----------
    heading : ndarray, shape (N,)
        Estimated heading at each control step [rad] (wrapped or not).
    quantum : float
        Half-width of the band [rad].
    """
    h = np.asarray(heading, float)
    if h.size == 0:
        return np.zeros(0)
    unwrapped = h[0] + np.concatenate([[0.0], np.cumsum(np.angle(np.exp(1j * np.diff(h))))])
    lo, hi = (unwrapped - quantum).tolist(), (unwrapped + quantum).tolist()
    played = np.fromiter(itertools.accumulate(range(1, h.size), lambda y, k: min(max(y, lo[k]), hi[k]),
                                              initial=unwrapped[0]), float, count=h.size)
    return np.concatenate([[0.0], np.cumsum(np.abs(np.diff(played)))])


def _dominated_from(tau: np.ndarray, s0: np.ndarray, turn0: np.ndarray, after: np.ndarray, n: int) -> np.ndarray:
    """For each fix (completion order), the first step of the first later fix dominating it, else n.

    Fix i dominates fix j < i when ``tau[i] <= tau[j]``, ``s0[i] >= s0[j]`` and ``turn0[i] >= turn0[j]``.
    """
    end = np.full(tau.size, n, dtype=np.intp)
    rows = 256  # a block of rows against all fixes: rows x F booleans
    for lo in range(0, tau.size, rows):
        j = np.arange(lo, min(lo + rows, tau.size))
        dom = ((tau[None, :] <= tau[j, None]) & (s0[None, :] >= s0[j, None]) & (turn0[None, :] >= turn0[j, None])
               & (np.arange(tau.size)[None, :] > j[:, None]))
        has = dom.any(axis=1)
        end[j[has]] = after[np.argmax(dom[has], axis=1)]
    return end


def _chunks(lengths: np.ndarray, limit: int):
    """Consecutive ranges ``(lo, hi)`` of ``lengths`` whose sum stays within ``limit`` (one at least)."""
    lo, total = 0, 0
    for i, n in enumerate(lengths.tolist()):
        if total and total + n > limit:
            yield lo, i
            lo, total = i, 0
        total += n
    if lo < lengths.size:
        yield lo, lengths.size


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
    turn = turning(heading, heading_quantum(robot))
    # the dock as fix -1: completed at t[0] (its start clamps to t[0] too), promise 0
    fix_t = np.concatenate([[t[0]], np.asarray(fix_t, float)])
    fix_tau = np.concatenate([[0.0], np.asarray(fix_tau, float)])
    # arc length and turning at each fix's start, interpolated on the step times
    s0 = np.interp(fix_t - fix_time, t, s)
    turn0 = np.interp(fix_t - fix_time, t, turn)
    out = np.full(t.shape, np.inf)
    after = np.searchsorted(t, fix_t, side="left")
    use = np.flatnonzero((after < t.size) & np.isfinite(fix_tau))
    # A fix is evaluated only until a later one completes that dominates it from then on: a
    # promise no larger, started no earlier in arc length and turning. The drift bound does not
    # decrease in distance or turning (nor does its floating-point evaluation: each operation
    # rounds monotonically), so from there the later fix's bound is at most the earlier one's,
    # and the minimum is the same number. Most fixes are dominated by the next ones: the work is
    # about the steps of the episode, not fixes x steps (7 % of an episode's non-physics time).
    end = _dominated_from(fix_tau[use], s0[use], turn0[use], after[use], t.size)
    start, lengths = after[use], end - after[use]
    for lo, hi in _chunks(lengths, _CHUNK):
        js, n = use[lo:hi], lengths[lo:hi]
        which = np.repeat(np.arange(js.size), n)
        steps = np.arange(which.size) - np.repeat(np.cumsum(n) - n, n) + np.repeat(start[lo:hi], n)
        b = fix_tau[js][which] + drift_bound(robot, np.maximum(s[steps] - s0[js][which], 0.0),
                                             np.maximum(turn[steps] - turn0[js][which], 0.0))
        np.minimum.at(out, steps, b)
    return out


def single_failure_excused(t: np.ndarray, attempt_t: np.ndarray, beyond: np.ndarray, done_t: np.ndarray,
                           planned: np.ndarray, fix_time: float) -> np.ndarray:
    """Mark the steps the single-failure test does not judge (too many lines of sight lost before).

    A fix attempt is *beyond* the test when more than one of the markers the plan counted on at
    it (the scheduled subset and, with one of them blocked, its fallback) were blocked
    (:func:`lost_markers`). From such an attempt's start, the certified bound is not judged
    until a fix *completes* that was started by a later attempt within the test and measured
    what the plan named (the scheduled subset or its fallback): an attempt that started no fix,
    lost a marker mid-fix or improvised leaves the robot on fixes older than the excused one.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Step times [s], ascending.
    attempt_t : ndarray, shape (A,)
        Start time of each fix attempt [s], ascending (attempts that started no fix included).
    beyond : ndarray of bool, shape (A,)
        The attempt lost more lines of sight than the test allows.
    done_t : ndarray, shape (F,)
        Completion time of each fix completed [s], ascending.
    planned : ndarray of bool, shape (F,)
        The completed fix measured the scheduled subset or its fallback.
    fix_time : float
        Duration of a fix [s]; a fix completes no earlier than its attempt's start plus this.

    Returns
    -------
    ndarray of bool, shape (N,)
    """
    t = np.asarray(t, float)
    attempt_t, beyond = np.asarray(attempt_t, float), np.asarray(beyond, bool)
    done_t, planned = np.asarray(done_t, float), np.asarray(planned, bool)
    out = np.zeros(t.shape, dtype=bool)
    if not beyond.any():
        return out
    # each completed fix's attempt: the last one started at least a fix's duration before it
    of = np.searchsorted(attempt_t, done_t - fix_time * (1.0 - 1e-9), side="right") - 1
    closes = planned & (of >= 0)
    closes[closes] &= ~beyond[of[closes]]
    close_t, close_of = done_t[closes], of[closes]
    for a in np.flatnonzero(beyond).tolist():
        later = np.flatnonzero(close_of > a)
        end = close_t[later[0]] if later.size else np.inf
        out[(t >= attempt_t[a]) & (t <= end)] = True
    return out


def lost_markers(blocked: frozenset[int], scheduled: tuple[int, ...], fallbacks: tuple[tuple[int, ...], ...]) -> int:
    """Lines of sight lost at a fix among the markers the plan counted on.

    The scheduled subset's blocked markers; with exactly one of them blocked and a fallback named
    for it, plus the fallback's own blocked markers (the robot would measure those next).
    """
    lost = [q for q, m in enumerate(scheduled) if m in blocked]
    n = len(lost)
    if n == 1 and len(fallbacks) == len(scheduled) and fallbacks[lost[0]]:
        n += sum(1 for m in fallbacks[lost[0]] if m in blocked and m not in scheduled)
    return n
