"""The measurement schedule: where along a path to take fixes, and with which markers.

Between fixes the robot dead-reckons, so the predicted position error at arc length ``s`` is
the error of the last *completed* fix plus the drift since that fix started::

    err(s) = tau_i + drift_bound(s - s_i, turned(s_i -> s))   for s in (c_i, c_{i+1}]

where fix ``i`` starts at ``s_i`` and completes at ``c_i`` (it measures its ``k`` markers one
after another, ``k * measurement_time`` seconds, while the robot moves on), and ``tau_i`` is its
promise ``predicted_tau``: the fault-area diameter of that moving fix, its earlier ranges
carried to the last by odometry (:mod:`planner.schedule.promise`). A fix is admissible when its promise
is under ``eps_max / (1 + POLYGON_TOLERANCE)``.

Slowing down (the paper's compromise between speed and accuracy)
    Where no fix is admissible at the planned speed, the fix is taken slower (its earlier ranges
    are shifted less; :mod:`planner.schedule.promise`). Where no schedule exists at all, the stretch the
    search names is driven at half the speed and the search runs again: slower, the robot fixes
    more often per metre (the sensor's rate is in time), so drift between fixes shrinks too.
    Neither goes below ``planning.min_fix_speed``; a path is inadmissible only when that does
    not help. The schedule's ``speed`` is the resulting profile and ``slowdown_time`` its cost.

Fix starts are at least ``max(1 / fix_rate_hz, k * measurement_time)`` seconds apart. The first
fix is taken at standstill at the start of the path (before departure).

Schedule choice (:func:`make_schedule`)
    The path is sampled at a fine spacing; every sample is a candidate fix start. A backward
    pass marks the samples from which the rest of the path can be completed (using the best
    subset's ``tau`` at every sample, which is what reaches farthest), so the forward pass
    never walks into a dead end: it is complete on the sampled path (finds a schedule whenever
    one exists with fixes starting at samples). Forward policy ``"often"`` (default) starts
    each fix as early as the rate allows among the completable samples (lowest error);
    ``"sparse"`` as late as the drift allows (fewest fixes). A window's fixes at the planned
    speed are preferred to slowed ones, and slow-downs are only tried when no schedule exists
    without them.
    Subset policy: keep the previous fix's subset while its ``tau`` over the new stretch is
    within ``(1 + switch_tolerance)`` of the best subset's and the rest stays completable;
    otherwise take the best subset. ``switch`` marks the fixes whose subset differs from the
    previous fix's: the points where the robot must change the markers it measures.

The bound searched for, and what ``eps_max`` does
    The search is not run for ``eps_max`` itself but for the rungs of a fixed ladder
    (:func:`rungs`: 1, 2, 3, 5 times a power of ten, above what the sensor can certify, up to
    ``eps_max``; then ``eps_max`` when it is not a rung), in increasing order, and the first
    rung that has a schedule gives it; ``eps_max`` only judges it (every rung is at most
    ``eps_max``). The search for one bound is a greedy one (fix starts, subsets, certified
    errors and slow-downs all follow from the bound), and a schedule for a larger bound may lose
    a line of sight or promise more where one for a smaller bound did not. With the ladder,
    raising ``eps_max`` from one rung to a larger one only adds rungs above those tried before:
    a path that had a schedule keeps the same one (the same fixes, the same promise), and a
    path that had none may get one. Between rungs this holds up to the last step: an
    ``eps_max`` that is not a rung is tried after every rung below it, so it may give a schedule
    that the next rung does not. Rungs not above the largest static τ at the path's vertices are
    not searched (the error right after a fix is about the static τ there at least, and the
    failed searches of small rungs were most of a plan's time); what is skipped depends on the
    path alone, not on ``eps_max``, so the argument stands.
    The rungs are first tried at the planned speed, one attempt each, and the smallest rung with
    a schedule at speed gives it: a smaller error than asked for is not worth a slower drive
    (paper-docks at 10 mm took 44 s instead of 21 s at 20 mm), and the slow-down searches of the
    small rungs were most of a plan's time when they ran first (the hall's 10 mm rung: 59
    attempts, 91 s, for nothing). At speed only a rung's failure matters, so it is proven, where
    it can be, from lower bounds of the promises (:func:`planner.schedule.promise.lower_levels`)
    without computing them. Only when no rung has a schedule at speed are they searched
    again with slow-downs, in increasing order (each from its failure at speed): the first whose
    slow-downs cost at most :data:`SLOWDOWN_SHARE` of the planned time gives the schedule,
    otherwise the one that slows the drive least, the smaller rung on a tie. Each search first
    stops once its speeds cost more than the allowance; the least slow-down is then searched from
    the largest rung down, each search stopping once its speeds cost more than the least so far
    (a search's cost only grows, so no schedule that could be chosen is missed, and a small rung
    that crawls is cut after a few attempts). The admissible set only grows with ``eps_max``, and a schedule at
    speed stays the same; a schedule that had to slow down may give way, at a larger ``eps_max``, to
    one at speed with a larger promise (the paper's compromise between speed and accuracy).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from itertools import combinations

import numpy as np

from planner.pef.sight import estimate_floor
from planner.routes.smoothing import acceleration_limited
from planner.schedule import promise, sightcheck
from planner.schedule.drift import DEFAULT_INCREMENT, K_SIGMA, drift_bound
from planner.schedule.fallback import fallbacks
from planner.schedule.pathtime import Kinematics, mean_speed, sample_track
from planner.schedule.promise import MAX_SUBSETS
from planner.schedule.search import StretchError, Windows, search
from scenarios.errors import PlanningError
from scenarios.schema import Scenario

BlockRisk = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""``block(s, xy) -> (M, n)``: probability that each marker's line of sight is hidden at arc lengths
``s`` [m], positions ``xy`` [m]."""

LADDER = (1.0, 2.0, 3.0, 5.0)
"""Mantissas of the error bounds a schedule is searched for (:func:`rungs`): 1, 2, 3, 5 times a power of ten [-]."""
SLOWDOWN_SHARE = 0.05
"""Where no rung has a schedule at speed, one whose slow-downs cost at most this share of the
planned time is taken at once; when every rung's cost more, the one that slows least (module docstring)."""
UNSEEN_ROUNDS = 20
"""Searches tried, each without a subset that lost sight of a marker where a fix was chosen
(:mod:`planner.schedule.sightcheck`), before the stretch is slowed down."""
ESTIMATE_ROUNDS = 4
"""Rounds of computing the promises from the estimate errors the plan certifies and those from the
promises (:func:`certified_estimate`), until every fix's is at least what the plan certifies;
if they do not settle, every fix keeps ``eps_max`` (the search's bound)."""


@dataclass(frozen=True)
class ScheduledFix:
    """One fix of the schedule.

    Attributes
    ----------
    s : float
        Arc length along the path where the fix starts [m].
    position : tuple of float
        (x, y) where the fix starts [m].
    markers : tuple of int
        Indices into ``scenario.markers`` measured, in order.
    tau : float
        The static PEF (the paper's, a robot standing still) of this subset, largest over the
        stretch the fix is taken over [m].
    switch : bool
        The subset differs from the previous fix's (always False for the first fix).
    predicted_tau : float
        The fix's promise: a bound on the fault-area diameter of the moving fix the robot makes,
        its ranges measured one after another near ``poses`` and carried to the last one by
        odometry, over every pose the robot may take (:mod:`planner.schedule.promise`) [m].
    speed : float
        Mean planned speed over the fix [m/s] (0 for the standstill fix before departure).
    slowed : bool
        The fix is taken below the planned speed: slowed for its own promise (it would break
        at the cruising speed), or on a stretch slowed because no schedule existed at full speed.
    poses : tuple of (x, y)
        Planned position at each measurement, in order [m].
    fallbacks : tuple of tuple of int
        ``fallbacks[q]``: the subset to measure instead when ``markers[q]`` is blocked, in
        measurement order (:mod:`planner.schedule.fallback`); () when there is none.
    fallback_tau : tuple of float
        The promise of each fallback [m] (inf where there is none).
    estimate : float
        Bound on the estimate's error while the fix is taken, which its promises assume: what
        the plan certifies there (:func:`certified_estimate`) [m].
    """

    s: float
    position: tuple[float, float]
    markers: tuple[int, ...]
    tau: float
    switch: bool
    predicted_tau: float = math.inf
    speed: float = 0.0
    slowed: bool = False
    poses: tuple[tuple[float, float], ...] = ()
    fallbacks: tuple[tuple[int, ...], ...] = ()
    fallback_tau: tuple[float, ...] = ()
    estimate: float = math.nan


@dataclass(frozen=True, eq=False)
class Schedule:
    """A measurement schedule along a path.

    Attributes
    ----------
    fixes : tuple of ScheduledFix
        The fixes, in path order.
    s : ndarray, shape (N,)
        Arc length of the input path's points [m].
    predicted_error : ndarray, shape (N,)
        Predicted position error (last completed fix's tau + drift) at those points [m].
    worst : float
        Largest predicted error along the whole path, checked at the fine spacing and at every
        fix completion point [m].
    speed : ndarray, shape (N,)
        Speed at the path's points with the slow-downs for fixes [m/s].
    slowdown_time : float
        Time the slow-downs add to the drive [s].
    """

    fixes: tuple[ScheduledFix, ...]
    s: np.ndarray
    predicted_error: np.ndarray
    worst: float
    speed: np.ndarray
    slowdown_time: float = 0.0


def _candidate_subsets(pef, xy: np.ndarray, k: int) -> list[tuple[int, ...]]:
    vis = np.asarray(pef.visible(xy), dtype=bool)
    seen = np.flatnonzero(vis.any(axis=0))
    if math.comb(len(seen), k) <= MAX_SUBSETS:
        # only subsets seen together from some sample can ever be used
        return [tuple(int(m) for m in c) for c in combinations(seen, k) if vis[:, list(c)].all(axis=1).any()]
    res = pef.at(xy)
    best = np.asarray(res.best)
    if res.fallback is not None:
        # with redundancy, each best subset's fallbacks too: the fixes name them for blocked markers
        best = np.vstack([best, np.asarray(res.fallback).reshape(-1, best.shape[1])])
    ok = (best >= 0).all(axis=1)
    return [tuple(int(m) for m in row) for row in np.unique(np.sort(best[ok], axis=1), axis=0)]


def _stretch_tau(tau: np.ndarray, tau_c: np.ndarray, c_idx: np.ndarray) -> np.ndarray:
    """Largest tau over each sample's fix stretch (samples j .. c_idx[j] - 1 and the completion).

    ``tau`` (C, n) at the samples, ``tau_c`` (C, n) at the exact completion points.
    """
    n = tau.shape[1]
    j = np.arange(n)
    out = np.maximum(tau, tau_c)
    for off in range(1, int((c_idx - j).max(initial=0)) + 1):
        idx = np.minimum(j + off, n - 1)
        out = np.where(j + off < c_idx, np.maximum(out, tau[:, idx]), out)
    return out


def make_schedule(scenario: Scenario, pef, path: np.ndarray, speed: np.ndarray | None = None, *,
                  spacing: float | None = None, policy: str = "often",
                  switch_tolerance: float = 0.2, k_sigma: float = K_SIGMA,
                  heading_error: float = 0.0, increment: float | None = DEFAULT_INCREMENT,
                  block: BlockRisk | None = None, block_limit: float = 1.0, protect: bool = True) -> Schedule:
    """Choose fixes along ``path`` so that the predicted error stays under ``eps_max``.

    Parameters
    ----------
    scenario : Scenario
        Uses ``sensor`` (fix rate, measurement time, k), ``robot`` (drift, max speed) and
        ``planning.eps_max``.
    pef : planner.pef.map.PEF
        PEF over ``scenario`` (its ``visible``, ``tau_subset`` and ``at`` are used).
    path : ndarray, shape (N, 2)
        Path vertices [m], in driving order.
    speed : ndarray, shape (N,), optional
        Speed at the vertices [m/s], constant acceleration between them (see
        :class:`Kinematics`); default the robot's ``max_speed`` everywhere.
    spacing : float, optional
        Sampling step of the check and of candidate fix starts [m]; default the smaller of
        the PEF resolution and a quarter of the distance covered between two fixes.
    policy : {"often", "sparse"}
        Fix as early as the rate allows, or as late as the drift allows.
    switch_tolerance : float
        Keep the previous subset while its tau is within this fraction of the best's.
    k_sigma, heading_error, increment
        Passed to :func:`planner.schedule.drift.drift_bound`.
    block : callable, optional
        ``block(s, xy)``: the probability (M, n) that each marker's line of sight is hidden when
        the robot is at arc lengths ``s`` (n,), positions ``xy`` (n, 2) (other robots of a
        fleet, :func:`planner.fleet.exposure.risk`). With it the schedule avoids *risky*
        subsets (probability that one of their markers is hidden above ``block_limit``) where a
        subset that is not risky serves, and, with ``protect``, holds every fix that stays risky
        to the single-failure test of ``planning.redundancy`` (a fallback for each marker, or the
        neighbouring fixes covering its loss), slowing down where it cannot: more fixes per
        metre where the others are near. None: no blocking known (the schedule of one robot).
    block_limit : float
        Probability above which a subset is risky.
    protect : bool
        Hold risky fixes to the single-failure test.

    Returns
    -------
    Schedule

    Raises
    ------
    PlanningError
        If no schedule keeps the error under ``eps_max``; names the worst stretch.
    """
    if policy not in ("often", "sparse"):
        raise PlanningError(f"schedule policy: expected 'often' or 'sparse', got {policy!r}")
    path = np.asarray(path, dtype=float).reshape(-1, 2)
    if len(path) == 0:
        raise PlanningError("schedule: empty path")
    sensor, robot = scenario.sensor, scenario.robot
    k = int(getattr(pef, "k", None) or sensor.markers_per_fix)
    v = (np.full(len(path), robot.max_speed) if speed is None
         else np.asarray(speed, dtype=float).reshape(-1))
    if v.shape != (len(path),) or np.any(v < 0) or not np.all(np.isfinite(v)):
        raise PlanningError(f"schedule: expected {len(path)} finite speeds >= 0, got shape {v.shape}")
    eps_max = scenario.planning.eps_max
    # no bound under the static PEF somewhere on the path is worth a search (module docstring)
    tau = np.asarray(pef.at(path).tau, dtype=float)
    floor = max(estimate_floor(sensor) * (1.0 + promise.POLYGON_TOLERANCE),
                float(np.max(np.where(np.isnan(tau), np.inf, tau))))
    s_v = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(path, axis=0).T))])
    allowed = SLOWDOWN_SHARE * Kinematics(s_v, v).t_v[-1]
    ladder = rungs(eps_max, floor)
    memo = _Memo()  # what the rungs' attempts at the same speeds share (_Memo)
    failed = None
    at_speed = {}  # each rung's failure at speed, where computed: the slow-down search's first attempt
    # at the planned speed first: one attempt a rung, no slow-downs (module docstring)
    for rung in ladder:
        try:
            return _schedule_for(_at(scenario, rung), pef, path, v, k, spacing, policy, switch_tolerance, k_sigma,
                                 heading_error, increment, block, block_limit, protect, slow=False, memo=memo)
        except PlanningError as exc:
            failed = exc
            if not isinstance(exc, _Proven):
                at_speed[rung] = _bare(exc)
    # The slow-down searches give the first rung (in increasing order) whose schedule slows the
    # drive by at most `allowed`, else the one that slows it least (the smallest rung on a tie).
    # A search's slow-downs only grow attempt by attempt (_schedule_for's `beat`), so a search
    # cut once its speeds cost more than `allowed` finds every such schedule; and where none
    # has one, the least is searched from the largest rung down, each search cut once it costs
    # more than the least so far: the small rungs, which crawl (seed 23's world 20: 5 mm with
    # ever more of its 24 m halved, hundreds of attempts), are cut after a few attempts instead
    # of searched to the end before the larger ones give them a bound to beat.
    for rung in ladder:
        try:
            sched = _schedule_for(_at(scenario, rung), pef, path, v, k, spacing, policy, switch_tolerance, k_sigma,
                                  heading_error, increment, block, block_limit, protect, beat=_past(allowed),
                                  first=at_speed.get(rung), memo=memo)
        except PlanningError:
            continue
        if sched.slowdown_time <= allowed:
            return sched
    # none plans within the allowance: the one that slows the drive least; a smaller rung that
    # crawls (paper-two-markers: +47 s for 2 mm against +0.6 s for 3 mm) is a worse plan, and
    # its hundreds of slowed fixes left the filter overconfident
    slow = None
    failed = None
    for rung in reversed(ladder):
        try:
            sched = _schedule_for(_at(scenario, rung), pef, path, v, k, spacing, policy, switch_tolerance, k_sigma,
                                  heading_error, increment, block, block_limit, protect,
                                  beat=None if slow is None else _past(slow.slowdown_time),
                                  first=at_speed.get(rung), memo=memo)
        except PlanningError as exc:
            # what is raised when no rung has a schedule: the largest rung's failure, searched
            # without a bound (no schedule was found before it)
            failed = exc if failed is None else failed
            continue
        if slow is None or sched.slowdown_time <= slow.slowdown_time:
            slow = sched
    if slow is not None:
        return slow
    raise failed


def _past(t: float) -> float:
    """Return a search's ``beat`` [s] that lets it find every schedule slowing the drive by at most ``t`` [s].

    A little more than ``t``: the cut compares the speeds' slow-down, the choice the schedule's,
    each summed its own way; cutting later only costs an attempt or two, never an answer.
    """
    return t * (1.0 + 1e-9) + 1e-9


def _at(scenario: Scenario, rung: float) -> Scenario:
    """Return ``scenario`` with ``planning.eps_max`` set to ``rung`` [m] (itself when equal)."""
    if rung == scenario.planning.eps_max:
        return scenario
    return replace(scenario, planning=replace(scenario.planning, eps_max=rung))


def rungs(eps_max: float, floor: float) -> list[float]:
    """Return the error bounds a schedule is searched for, in increasing order [m] (module docstring).

    Parameters
    ----------
    eps_max : float
        The plan's bound [m] (> 0).
    floor : float
        No schedule keeps an error at or under this [m]; rungs not above it are left out.

    Returns
    -------
    list of float
        ``m 10^e`` for ``m`` in :data:`LADDER` with ``floor < m 10^e <= eps_max``, then
        ``eps_max`` itself when it is not one of them (always last; never empty).
    """
    if not floor < eps_max:
        return [float(eps_max)]
    out = []
    for e in range(math.floor(math.log10(max(floor, 1e-12))) - 1, math.floor(math.log10(eps_max)) + 1):
        for m in LADDER:
            r = float(f"{m}e{e}")   # exactly the decimal 2e-2, not 2 * 10 ** -2
            if floor < r <= eps_max * (1.0 + 1e-12):
                out.append(r)
    if not out or not math.isclose(out[-1], eps_max, rel_tol=1e-12):
        out.append(float(eps_max))
    else:
        out[-1] = float(eps_max)
    return out


def _schedule_for(scenario, pef, path, v, k, spacing, policy, switch_tolerance, k_sigma, heading_error, increment,
                  block, block_limit, protect, slow: bool = True, beat: float | None = None,
                  first: PlanningError | None = None, memo: _Memo | None = None) -> Schedule:
    """Return the schedule of :func:`make_schedule` for the bound ``scenario.planning.eps_max`` alone.

    With ``slow`` False the drive keeps the planned speeds ``v``: the first stretch without a
    schedule raises instead of being slowed down. With ``beat`` [s], the search gives up (raises)
    as soon as the speeds it tries cost at least that much time: every later attempt only slows
    them further (:func:`_slow_stretch` lowers caps), and the schedule's own slow-downs for its
    fixes only lower them again (:func:`planner.schedule.promise.slowed_speeds`), so a schedule
    it could still find would slow the drive by at least ``beat``, and :func:`make_schedule`
    would not take it. ``first``: what the attempt at the planned speeds ``v`` raised before (an
    attempt is a function of its arguments; the ladder at speed made it), raised again instead
    of making it again. ``memo``: shared with the other rungs' searches (:class:`_Memo`).
    """
    sensor, robot = scenario.sensor, scenario.robot
    fix_time = k * sensor.measurement_time
    gap = max(1.0 / sensor.fix_rate_hz, fix_time)
    if spacing is None:
        spacing = min(scenario.planning.resolution, 0.25 * max(v.max(), 1e-9) * gap)
    if spacing <= 0:
        raise PlanningError(f"schedule: spacing must be > 0, got {spacing}")

    drift = functools.partial(drift_bound, robot, k_sigma=k_sigma, heading_error=heading_error,
                              increment=increment)
    s_v = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(path, axis=0).T))])
    t_planned = Kinematics(s_v, v).t_v[-1]
    v_try = v
    while True:
        if beat is not None and v_try is not v and not Kinematics(s_v, v_try).t_v[-1] - t_planned < beat:
            raise PlanningError(f"schedule: slowed by {Kinematics(s_v, v_try).t_v[-1] - t_planned:.3g} s, "
                                f"not less than the {beat:.3g} s of the schedule already found")
        tried = None
        try:
            if first is not None and v_try is v:
                raise first
            tried = None if memo is None or not slow else memo.tried(scenario.planning.eps_max, v_try)
            sched = tried.outcome() if tried is not None and tried.known else _attempt(
                scenario, pef, path, v_try, spacing, k, gap, policy, switch_tolerance, drift, t_planned, block,
                block_limit, protect, prove=not slow, memo=memo)
            if tried is not None:
                tried.keep(sched)
            return sched if v_try is v else _mark_slowed(sched, s_v, v, v_try)
        except StretchError as exc:
            if not slow:
                raise
            if tried is not None:
                tried.keep(_bare(exc))
            slower, moved = v_try, False
            for stretch in (exc.stretch, *exc.more):
                cand = _slow_stretch(s_v, slower, stretch, scenario.planning.min_fix_speed)
                if cand is not None:
                    slower, moved = cand, True
            if not moved:
                raise
            v_try = slower


def _mark_slowed(sched: Schedule, s_v: np.ndarray, v: np.ndarray, v_try: np.ndarray) -> Schedule:
    """Mark as slowed the fixes that start on a stretch driven below the planned speed ``v``.

    ``slowdown_time`` counts every slow-down, also those of whole stretches made when no
    schedule existed at ``v``; a fix taken there is slowed down for as much as one slowed for
    its own promise, and the count of slowed fixes must say so.
    """
    s_fix = np.array([f.s for f in sched.fixes])
    slower = np.interp(s_fix, s_v, v_try) < np.interp(s_fix, s_v, v) * (1.0 - 1e-9)
    fixes = tuple(replace(f, slowed=f.slowed or bool(b)) for f, b in zip(sched.fixes, slower, strict=True))
    return replace(sched, fixes=fixes)


def _slow_stretch(s_v: np.ndarray, v: np.ndarray, stretch: tuple[float, float], v_min: float) -> np.ndarray | None:
    """Halve the speed over a stretch (not below ``v_min``), braking into it; None if it is at ``v_min``.

    Slower, the robot fixes more often per metre (the sensor's rate is in time) and each fix's
    earlier ranges are shifted less: drift and promise both shrink.
    """
    a, b = stretch
    lo = max(int(np.searchsorted(s_v, a, side="right")) - 1, 0)
    hi = min(int(np.searchsorted(s_v, b, side="left")), len(s_v) - 1)
    cap = np.array(v, dtype=float)
    part = cap[lo:hi + 1]
    if np.all(part <= v_min * (1.0 + 1e-9)):
        return None
    cap[lo:hi + 1] = np.minimum(part, np.maximum(0.5 * part, v_min))
    return acceleration_limited(s_v, cap)


def _subset_risk(block: BlockRisk, subsets: list[tuple[int, ...]], tr) -> np.ndarray:
    """Probability (C, n) that at least one marker of each subset is hidden at each sample (independent markers)."""
    pm = np.clip(np.asarray(block(tr.s, tr.xy), dtype=float), 0.0, 1.0)         # (M, n)
    return 1.0 - np.prod(1.0 - pm[np.asarray(subsets, dtype=np.int64)], axis=1)  # (C, n)


def _avoid(levels: promise.Levels, risky: np.ndarray, limit: float) -> promise.Levels:
    """Levels with risky subsets out (tau inf) at the samples where a subset that is not risky is usable."""
    def edit(lv):
        safe = (~risky & (lv.tau < limit)).any(axis=0)
        return replace(lv, tau=np.where(risky & safe[None, :], np.inf, lv.tau))
    return levels.map(edit)


@dataclass
class _Static:
    """What an attempt at given speeds computes before its bound ``eps_max`` enters.

    Attributes
    ----------
    tr : Track
        The samples of the path at those speeds.
    subsets : list of tuple of int
        Candidate marker subsets (C).
    tau_s : ndarray, shape (C, n)
        The static PEF over each sample's fix stretch [m].
    lower : ndarray, shape (C, n), or None
        :func:`planner.schedule.promise.lower_levels` once computed [m].
    """

    tr: object
    subsets: list
    tau_s: np.ndarray
    lower: np.ndarray | None = None


class _Memo:
    """The :class:`_Static` part of the last attempt of one :func:`make_schedule`, reused at the same speeds.

    The rungs of the ladder differ in ``eps_max`` only: each rung's attempt at the planned speeds
    samples the same track, scores the same subsets and (with ``prove``) bounds the same promises
    from below. Each is a function of the path, the speeds, the sampling and the PEF, none of
    ``eps_max`` (the scenarios of one :func:`make_schedule` differ in nothing else); the arrays
    are kept read-only, so an attempt cannot change what the next reads. One entry: a slowed
    attempt's speeds are new, and an entry holds two (C, n) arrays (~12 MB on the hall).
    """

    def __init__(self):
        self._key = None
        self._static: _Static | None = None
        self._tried: dict[tuple, _Tried] = {}

    def tried(self, eps: float, v: np.ndarray) -> _Tried:
        """Return the outcome of the slow-down attempt for bound ``eps`` [m] at vertex speeds ``v`` [m/s].

        An attempt is a function of the bound and the speeds (the rest is fixed within one
        :func:`make_schedule`): the searches of the allowance and of the least slow-down
        (:func:`make_schedule`) make the same attempts again.
        """
        return self._tried.setdefault((float(eps), np.asarray(v, dtype=float).tobytes()), _Tried())

    def static(self, pef, path, v, spacing, fix_time, gap, k) -> _Static:
        """Return the :class:`_Static` part of an attempt at vertex speeds ``v``, computed once per speeds.

        Parameters
        ----------
        pef : PEF
            The map the attempt scores subsets with (held by the :func:`make_schedule` call).
        path : ndarray, shape (P, 2)
            The path's vertices [m].
        v : ndarray, shape (P,)
            Speed at each vertex [m/s].
        spacing : float or None
            Sample spacing of the track [m] (:func:`sample_track`).
        fix_time : float
            Time one fix takes [s].
        gap : float
            Least time between two fixes [s].
        k : int
            Markers per fix.

        Returns
        -------
        _Static
            Read-only: the same object while the arguments stay the same.
        """
        key = (id(pef), path.tobytes(), np.asarray(v, dtype=float).tobytes(), spacing, fix_time, gap, k)
        if self._static is not None and key == self._key:
            return self._static
        tr = sample_track(path, v, spacing, fix_time, gap, measurements=k)
        n = len(tr.s)
        subsets = _candidate_subsets(pef, tr.xy, k)
        if not subsets:
            tau = np.full((1, 2 * n), np.inf)
            subsets = [tuple(range(k))]
        else:
            # tau at the samples and at the exact completion points of fixes started there
            both = np.vstack([tr.xy, tr.xy_c])
            tau = np.asarray(pef.tau_subset(both, np.asarray(subsets)), dtype=float)
        tau_s = _stretch_tau(tau[:, :n], tau[:, n:], tr.c_idx)  # the static PEF over each stretch
        # the pef lives as long as the make_schedule call that holds this memo: its id is its own
        for a in vars(tr).values():
            if isinstance(a, np.ndarray):
                _frozen(a)
        self._key, self._static = key, _Static(tr, subsets, _frozen(tau_s))
        return self._static


class _Tried:
    """What one slow-down attempt gave: its schedule or its :class:`StretchError` once :attr:`known`."""

    def __init__(self):
        self.known = False
        self._outcome: Schedule | StretchError | None = None

    def keep(self, outcome: Schedule | StretchError) -> None:
        """Hold the attempt's schedule, or its error (without its traceback: :func:`_bare`)."""
        self.known, self._outcome = True, outcome

    def outcome(self) -> Schedule:
        """Return the schedule held, or raise the error held."""
        if isinstance(self._outcome, StretchError):
            raise self._outcome
        return self._outcome


def _frozen(a: np.ndarray) -> np.ndarray:
    """Make ``a`` read-only and return it (shared between attempts)."""
    a.flags.writeable = False
    return a


def _attempt(scenario, pef, path, v, spacing, k, gap, policy, switch_tolerance, drift, t_planned,
             block=None, block_limit=1.0, protect=True, prove=False, memo: _Memo | None = None) -> Schedule:
    """One schedule at vertex speeds ``v``, or a :class:`StretchError` naming where none exists.

    With ``prove``, where lower bounds of the promises (:func:`planner.schedule.promise.lower_levels`)
    already leave no schedule, the error raised names the stretch of those bounds, not of the
    promises: only for a caller that uses the failure, not its stretch (the ladder at speed).
    """
    sensor, eps = scenario.sensor, scenario.planning.eps_max
    fix_time = k * sensor.measurement_time
    static = (memo or _Memo()).static(pef, path, v, spacing, fix_time, gap, k)
    tr, subsets, tau_s = static.tr, static.subsets, static.tau_s
    n = len(tr.s)
    limit = eps / (1.0 + promise.POLYGON_TOLERANCE)
    if prove and block is None and k == 2 and np.isfinite(tau_s).any():
        # With promises no smaller than these bounds every sample is usable at most where it is
        # here, and reaches at most as far (the search's windows shrink as a promise grows): if
        # the search fails on the bounds, it fails on the promises, at every speed level. (Bounds
        # of every visible subset: the sight check below only takes subsets out.)
        if static.lower is None:
            static.lower = _frozen(promise.lower_levels(scenario, subsets, tr, path, tau_s))
        try:
            search(Windows(tr, drift, eps, gap), static.lower[None], limit, k, policy, switch_tolerance)
        except PlanningError as exc:
            raise _Proven(str(exc)) from None
    # the map sees with the smallest pose bound the plan can certify (planner.pef.sight); the search
    # counts a subset at a sample only where it stays in sight within the pose bound it assumes
    # there: the tracking bound and eps (the bound searched for) as the estimate's error
    bias = promise.turn_bias(scenario.robot)
    seen = sightcheck.seen_within(scenario, tr.xy, eps + promise.tracking_bound(path, tr.kin.s_v, v, tr.s, bias))
    sub_idx = np.asarray(subsets, dtype=np.int64)
    tau_s = np.where(seen[:, sub_idx].all(axis=2).T, tau_s, np.inf)
    lv = (promise.levels(scenario, subsets, tr, path, tau_s, k, eps) if np.isfinite(tau_s).any()
          else promise.Levels(promise.Level(tau_s, np.zeros(tau_s.shape, bool), np.full(n, np.nan))))
    risky = None
    if block is not None:
        risky = _subset_risk(block, subsets, tr) > block_limit
        lv = _avoid(lv, risky, limit)

    pl = Windows(tr, drift, eps, gap)
    for _ in range(UNSEEN_ROUNDS):
        try:
            chosen, fix_level, pred, poses, kin, v_new, order, fb, fb_tau, est = _chosen(
                scenario, path, v, tr, lv, pl, subsets, tau_s, limit, k, policy, switch_tolerance)
            break
        except _Unseen as exc:
            # the subset is out where the fix stood: a line of sight lost within the fix's pose
            # bound may be lost from the samples within that bound of it too
            j, c = exc.sample, exc.subset
            out = np.hypot(*(tr.xy - tr.xy[j]).T) <= exc.reach
            drop = out[None, :] & (np.arange(len(subsets)) == c)[:, None]
            lv = lv.map(lambda x, drop=drop: replace(x, tau=np.where(drop, np.inf, x.tau)))
            last = exc
    else:
        j = last.sample
        x, y = tr.xy[j]
        raise StretchError(
            f"no measurement schedule keeps its markers in sight: the fix at s = {tr.s[j]:.2f} m "
            f"({x:.2f}, {y:.2f}) may lose marker(s) {subsets[last.subset]} within its pose bound, "
            f"and {UNSEEN_ROUNDS} searches found no other", (float(tr.s[j]), float(tr.s[j]) + 0.1))
    starts = np.array([j for j, _, _ in chosen])
    judged = np.full(len(starts), scenario.planning.redundancy > 0)
    if risky is not None and protect:
        judged |= risky[[c for _, c, _ in chosen], starts]
    if judged.any():
        holes = [i for i in range(len(starts))
                 if judged[i] and not all(fb[i]) and not _covered_without(pl, starts, pred, fb, fb_tau, i)]
        if holes:
            # a marker whose blocking the plan cannot survive here: slower, the fallback's
            # earlier ranges shift less and the drift to the next fix shrinks
            ends = [float(tr.c[starts[i + 1]]) if i + 1 < len(starts) else float(tr.s[-1]) for i in holes]
            i = holes[0]
            x, y = tr.xy[starts[i]]
            why = (f"planning.redundancy = {scenario.planning.redundancy}" if scenario.planning.redundancy > 0
                   else f"other robots likely (> {block_limit:.3g}) to hide a marker")
            raise StretchError(
                f"{why}: the fix at s = {tr.s[starts[i]]:.2f} m "
                f"({x:.2f}, {y:.2f}) has no fallback that keeps the error under eps_max = {eps:.4g} m "
                f"with marker {order[i][fb[i].index(())]} blocked, even at "
                f"{scenario.planning.min_fix_speed:g} m/s",
                (float(tr.s[starts[i]]), ends[0]),
                more=tuple((float(tr.s[starts[j]]), e) for j, e in zip(holes[1:], ends[1:], strict=True)))

    fix_speed = _fix_speeds(kin, tr.s[starts], k, sensor.measurement_time)
    fixes = tuple(
        ScheduledFix(s=float(tr.s[j]), position=(float(tr.xy[j, 0]), float(tr.xy[j, 1])),
                     markers=order[i], tau=float(tau_s[c, j]), switch=i > 0 and c != chosen[i - 1][1],
                     predicted_tau=float(pred[i]), speed=float(fix_speed[i]),
                     slowed=bool(fix_level[i] > 0), poses=tuple(tuple(map(float, q)) for q in poses[i]),
                     fallbacks=fb[i], fallback_tau=fb_tau[i], estimate=float(est[i]))
        for i, (j, c, _) in enumerate(chosen))
    completes = tr.c[starts]
    active = np.maximum(np.searchsorted(completes, tr.s, side="left") - 1, 0)
    fj = starts[active]
    err = pred[active] + drift(tr.s - tr.s[fj], tr.turn_in - tr.turn_ex[fj])
    # just before each later fix completes, the previous fix still holds
    handover = [pl.err_at_completion(starts[i], pred[i], starts[i + 1]) for i in range(len(starts) - 1)]
    worst = float(max([err.max(), *handover]))
    if not worst < eps:
        i = int(np.argmax(err))
        f = int(np.searchsorted(starts, i, side="right")) - 1
        raise StretchError(f"no measurement schedule keeps the error under eps_max = {eps:.4g} m: the exact "
                           f"promises of the chosen fixes reach {worst:.4g} m near s = {tr.s[i]:.2f} m",
                           (float(tr.s[starts[max(f, 0)]]), float(tr.s[i])))
    return Schedule(fixes=fixes, s=tr.s[tr.vertex_idx].copy(), predicted_error=err[tr.vertex_idx].copy(),
                    worst=worst, speed=v_new, slowdown_time=float(kin.t_v[-1] - t_planned))


def _bare(exc: BaseException) -> BaseException:
    """Return ``exc`` with its traceback, and those of the exceptions it was raised in, dropped.

    A traceback holds its frames' locals: an attempt's samples, promises and levels (the hall:
    ~100 MB an attempt), which an exception kept for later would keep alive.
    """
    seen, e = set(), exc
    while e is not None and id(e) not in seen:
        seen.add(id(e))
        e.__traceback__ = None
        e = e.__cause__ or e.__context__
    return exc


class _Proven(PlanningError):
    """No schedule at speed, proven from the promises' lower bounds (:func:`_attempt`'s ``prove``)."""


class _Unseen(Exception):
    """A chosen fix has no promise at any speed: a marker may be hidden within its pose bound.

    Attributes
    ----------
    sample : int
        The fix's start sample.
    subset : int
        Its candidate subset.
    reach : float
        Radius around the fix's start within which the subset is dropped [m]: the largest
        estimate error assumed plus the tracking bound there (its pose bound but for the small
        start-lag and speed terms).
    """

    def __init__(self, sample: int, subset: int, reach: float):
        super().__init__(sample, subset, reach)
        self.sample, self.subset, self.reach = sample, subset, reach


def _chosen(scenario, path, v, tr, lv, pl, subsets, tau_s, limit, k, policy, switch_tolerance):
    """Search the fixes and settle their promises and fallbacks (raises :class:`_Unseen`)."""
    eps = scenario.planning.eps_max
    try:
        chosen, level = search(pl, np.stack([lv[0].tau]), limit, k, policy, switch_tolerance)  # no slow-down
    except PlanningError:
        if len(lv) == 1:
            raise
        chosen, level = search(pl, np.stack([x.tau for x in lv]), limit, k, policy, switch_tolerance)
    starts = np.array([j for j, _, _ in chosen])
    fix_level = level[starts].copy()
    # a fallback's area is in force until the next fix completes, as the fix's own
    margin = np.array([pl.err_at_completion(starts[i], 0.0, starts[i + 1]) for i in range(len(starts) - 1)]
                      + [pl.err_at_end(starts[-1], 0.0)])
    # The search scored every candidate with eps_max as the estimate's error (what the windows
    # keep every error under), so these promises bound the final ones; then each fix gets the
    # error the plan certifies where it is taken (promise.py, "Derived promise").
    est = np.full(len(starts), eps)
    for r in range(ESTIMATE_ROUNDS):
        pred, poses, kin, v_new, order = _settle(scenario, path, v, tr, lv, chosen, fix_level, subsets, limit, k,
                                                 est)
        fb, fb_tau = fallbacks(scenario, path, v_new, tr.s[starts], order, subsets, tau_s, starts, margin, est)
        cert = certified_estimate(pl, starts, pred, fb, fb_tau, scenario.planning.redundancy > 0)
        if r > 0 and np.all(cert <= est):
            break  # every promise assumes at least what the promises before it certify
        est = cert if np.all(cert[1:] < eps) else np.maximum(est, cert)  # cert[0]: the dock's fix, eps_max
    else:
        est = np.full(len(starts), eps)  # not settled: the search's bound, which holds whatever the chain
        pred, poses, kin, v_new, order = _settle(scenario, path, v, tr, lv, chosen, fix_level, subsets, limit, k,
                                                 est)
        fb, fb_tau = fallbacks(scenario, path, v_new, tr.s[starts], order, subsets, tau_s, starts, margin, est)
    return chosen, fix_level, pred, poses, kin, v_new, order, fb, fb_tau, est


def certified_estimate(pl: Windows, starts: np.ndarray, pred: np.ndarray, fb: list, fb_tau: list,
                       redundant: bool) -> np.ndarray:
    """Bound on the estimate's error while each fix is taken, as the plan certifies it [m], shape (F,).

    The error the fix before leaves until this fix completes: its promise, or the largest of its
    fallbacks' (a blocked line of sight makes the robot take one), plus the drift since it
    started (:meth:`Windows.err_at_completion`). With redundancy, the fix before may also be
    lost altogether where it has no fallback for some marker; the one before it then stays in
    force (:func:`_covered_without`; the calibrated dock, promise 0, before the first). The
    first fix is taken at standstill on the dock: ``eps_max`` (:func:`planner.schedule.promise.pose_bound`
    does not use it there).

    This bounds the estimate's error by induction along the schedule: it holds when the fixes
    before kept their promises and the drift bound held.

    Parameters
    ----------
    pl : planner.schedule.search.Windows
        The sampled track with its drift bound and ``eps`` (``eps_max``) [m].
    starts : ndarray of int, shape (F,)
        Sample index of each fix's start.
    pred : ndarray, shape (F,)
        Each fix's promise [m].
    fb : list (F) of tuple (k) of tuple of int
        Each fix's fallback subset per marker, () where it has none
        (:func:`planner.schedule.fallback.fallbacks`).
    fb_tau : list (F) of tuple (k) of float
        Their promises [m], inf where there is none.
    redundant : bool
        ``planning.redundancy > 0``: a fix without a fallback for some marker may be lost.

    Returns
    -------
    numpy.ndarray, shape (F,)
        The bound for each fix [m]; ``eps_max`` for the first.
    """
    n = len(starts)
    out = np.full(n, pl.eps)
    weakest = [max([float(pred[i]), *[t for t in fb_tau[i] if math.isfinite(t)]]) for i in range(n)]
    for i in range(1, n):
        e = pl.err_at_completion(starts[i - 1], weakest[i - 1], starts[i])
        if redundant and not all(fb[i - 1]):
            j, tau = (starts[i - 2], weakest[i - 2]) if i >= 2 else (0, 0.0)
            e = max(e, pl.err_at_completion(j, tau, starts[i]))
        out[i] = e
    return out


def _covered_without(pl: Windows, starts: np.ndarray, pred: np.ndarray, fb: list, fb_tau: list, i: int) -> bool:
    """Whether the plan keeps the error under eps_max with fix ``i`` not taken at all.

    The fix before it then stays in force until the fix after it completes. It may itself have
    been taken with a fallback (each fix may lose one line of sight), so its weakest promise
    counts, and it must have a fallback for every marker: two lost fixes in a row are more than
    one lost line of sight per fix allows for. The calibrated dock (promise 0) stands before the
    first fix.
    """
    if i > 0 and not all(fb[i - 1]):
        return False
    j, tau = (starts[i - 1], max(pred[i - 1], *fb_tau[i - 1])) if i > 0 else (0, 0.0)
    err = pl.err_at_completion(j, tau, starts[i + 1]) if i + 1 < len(starts) else pl.err_at_end(j, tau)
    return bool(err < pl.eps)


def _fix_speeds(kin, s0: np.ndarray, k: int, mt: float) -> np.ndarray:
    """Mean planned speed over each fix started at ``s0`` (F,) [m/s] (0 for the standstill fix, the first)."""
    if mt > 0.0:
        speed = (kin.s_at(kin.t_at(s0) + k * mt) - s0) / (k * mt)
    else:  # an instantaneous fix: the speed where it is taken
        speed = mean_speed(kin, kin.t_at(s0), 0.0)
    speed[:1] = 0.0
    return speed


def _settle(scenario, path, v, tr, lv, chosen, fix_level, subsets, limit, k, estimate):
    """Slow the chosen fixes down until each exact promise is under ``limit``.

    The search scores fixes with the construction's parallelogram; the exact promise
    (:func:`planner.schedule.promise.predict`) can differ a little, and at the final speed profile the
    robot may still be braking: a fix over the limit is taken at the next slower level.
    """
    mt = scenario.sensor.measurement_time
    s_v = tr.kin.s_v
    while True:
        order = [tuple(reversed(subsets[c])) if lv[fix_level[i]].flipped[c, j] else subsets[c]
                 for i, (j, c, _) in enumerate(chosen)]
        slow = []
        for i, (j, _, _) in enumerate(chosen):
            if fix_level[i] > 0:
                vf = float(lv[fix_level[i]].speed[j])
                a, b = float(tr.s[j]), float(tr.s[j]) + vf * k * mt * 1.01
                # the robot's speed follows the planned one near its estimate (promise.speed_reach)
                track = promise.tracking_bound(path, s_v, v, np.array([a, b]), promise.turn_bias(scenario.robot))
                off = float(np.max(estimate)) + float(np.max(track))
                reach = float(promise.speed_reach(s_v, off))
                slow.append((a - reach, b + reach, vf))
        v_new = promise.slowed_speeds(s_v, v, slow)
        pred, poses, kin = promise.predict(scenario, path, v_new, tr.s[[j for j, _, _ in chosen]], order, estimate)
        bad = np.flatnonzero(~(pred < limit))
        if len(bad) == 0:
            return pred, poses, kin, v_new, order
        for i in bad:
            j, c, _ = chosen[i]
            slower = [lvl for lvl in range(fix_level[i] + 1, len(lv)) if np.isfinite(lv[lvl].tau[c, j])]
            if not slower and not np.isfinite(pred[i]):
                # no promise at any speed: a marker may be hidden (sightcheck)
                a = float(tr.s[j])
                track = promise.tracking_bound(path, s_v, v, np.array([a]), promise.turn_bias(scenario.robot))
                off = float(np.max(estimate)) + float(np.max(track))
                raise _Unseen(j, c, off)
            if not slower:
                x, y = tr.xy[j]
                raise StretchError(
                    f"no measurement schedule keeps the error under eps_max = {scenario.planning.eps_max:.4g} m: "
                    f"the fix at s = {tr.s[j]:.2f} m ({x:.2f}, {y:.2f}) promises {pred[i]:.4g} m even at "
                    f"{scenario.planning.min_fix_speed:g} m/s (limit {limit:.4g} m = eps_max / "
                    f"{1 + promise.POLYGON_TOLERANCE:g})", (float(tr.s[j]), float(tr.s[j]) + 0.1))
            fix_level[i] = slower[0]
