"""A fleet's exposure to blocking: per robot and fix, the chance its lines of sight are hidden.

Built on the model of :mod:`planner.fleet.blocking` and the fleet's predicted timelines:
:func:`predict` gives each scheduled fix's probability per counted marker (and that at least
one is hidden) from the other robots, and from traffic that is not simulated (for a fleet that
declares a timing spread, from the spread's own draws, :mod:`planner.fleet.sampled`); :func:`risk`
gives the measurement schedule (:func:`planner.schedule.schedule.make_schedule`, its ``block``
argument) the probability per marker along a task's path, for the robot's place in the fleet.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from planner.fleet.blocking import (
    TimingModel,
    Track,
    block_probability,
    lag_difference,
    tie,
    traffic_probability,
)
from planner.fleet.sampled import UNDECIDED, SampledDrives, predict_sampled, sampled_risk
from planner.fleet.timing import declared_model
from scenarios.schema import Scenario


@dataclass(frozen=True)
class RobotBlocking:
    """Predicted blocking of one robot's scheduled fixes, F fixes of k markers in driving order.

    Attributes
    ----------
    task : ndarray of int, shape (F,)
        Index of the fix's plan in the robot's plans.
    fix : ndarray of int, shape (F,)
        Index of the fix in that plan's schedule.
    time : ndarray, shape (F,)
        Planned time of the fix (the fleet's clock) [s].
    s : ndarray, shape (F,)
        Arc length along the robot's whole path [m].
    markers : ndarray of int, shape (F, k)
        The scheduled markers, in measurement order.
    p_robot : ndarray, shape (F, k)
        Probability that another robot's body hides each scheduled marker at the fix.
    p_fix : ndarray, shape (F,)
        Probability that another robot hides at least one of them.
    p_traffic : ndarray, shape (F, k)
        Probability that traffic not simulated (``routes.traffic``) hides each.
    protected : ndarray of bool, shape (F,)
        The fix names a fallback for every marker (one lost line of sight keeps the promise).
    undecided : ndarray of bool, shape (F,), optional
        Whether the fix's lines of sight are hidden hinges on the path followers' tracking errors,
        not on the timing (:mod:`planner.fleet.sampled`): ``p_robot`` and ``p_fix`` are then the
        plan's geometry's, not a chance the runs can test (None: every fix decided).
    """

    task: np.ndarray
    fix: np.ndarray
    time: np.ndarray
    s: np.ndarray
    markers: np.ndarray
    p_robot: np.ndarray
    p_fix: np.ndarray
    p_traffic: np.ndarray
    protected: np.ndarray
    undecided: np.ndarray | None = None

    def of(self, task: int, fix: int) -> tuple[np.ndarray, float]:
        """Return the predictions of fix ``fix`` of plan ``task``: p per scheduled marker (k,), p of the fix."""
        i = int(np.flatnonzero((self.task == task) & (self.fix == fix))[0])
        return self.p_robot[i], float(self.p_fix[i])

    @property
    def expected_blocked_los(self) -> float:
        """Expected number of scheduled lines of sight another robot hides."""
        return float(self.p_robot.sum())

    @property
    def expected_blocked_fixes(self) -> float:
        """Expected number of fixes with at least one scheduled line of sight hidden by a robot."""
        return float(self.p_fix.sum())

    @property
    def expected_unprotected(self) -> float:
        """Expected number of blocked fixes without a fallback for every marker."""
        return float(self.p_fix[~self.protected].sum())


def tracks_of(robots: Sequence, timing: TimingModel | None = None) -> list[Track]:
    """Each robot's refined timeline, its lags tied through its zone waits (``robots``: ``FleetRobotPlan``).

    Each track carries its robot's lag model: the simulated robots' own (:data:`planner.fleet.blocking.TIMING`) with the
    robot's declared timing spread (``FleetRobotPlan.declared``, :func:`planner.fleet.timing.declared_model`);
    ``timing`` given is used for every robot instead.
    """
    tracks = []
    for r in robots:
        tr = Track.of(r.timeline, r.start_time, r.robot.radius, r.robot.height)
        declared = getattr(r, "declared", None)
        if timing is None and declared is not None:
            # the docks it dwells at: where each of its tasks but the first begins
            docks = np.interp(tr.at_s(np.asarray(r.offsets[1:], float)), tr.t, tr.drive)
            tr = replace(tr, timing=declared_model(declared, docks))
            if tr.timing.tie_wait:
                # with a spread, the waits decide who hides what: placed where the robots stand
                tr = tr.stand_back(r.timeline, r.path, r.s)
        tracks.append(tr)
    return tie(tracks, [r.timeline for r in robots], timing)


def _heights(scenario: Scenario) -> np.ndarray:
    return scenario.marker_heights()


def _segment_density(scenario: Scenario, xy: np.ndarray) -> np.ndarray:
    """``routes.traffic`` density of the network segment nearest each point, 0 farther than 0.5 m from any."""
    net = scenario.routes
    xy = np.asarray(xy, float).reshape(-1, 2)
    if net is None or not net.traffic:
        return np.zeros(len(xy))
    best_d = np.full(len(xy), np.inf)
    dens = np.zeros(len(xy))
    for a, b in net.segments:
        pa, pb = np.asarray(net.nodes[a], float), np.asarray(net.nodes[b], float)
        d = pb - pa
        L2 = max(float(d @ d), 1e-12)
        u = np.clip((xy - pa) @ d / L2, 0.0, 1.0)
        dist = np.hypot(*(xy - pa - u[:, None] * d).T)
        closer = dist < best_d
        best_d = np.where(closer, dist, best_d)
        dens = np.where(closer, net.traffic_of(a, b), dens)
    return np.where(best_d <= 0.5, dens, 0.0)


def marker_risk(scenario: Scenario, tracks: list[Track], i: int, xy: np.ndarray, when: np.ndarray,
                timing: TimingModel | None = None, traffic_block: float | None = None) -> np.ndarray:
    """Probability per marker that its line of sight from ``xy`` at planned time ``when`` is hidden.

    Parameters
    ----------
    scenario : Scenario
    tracks : list of Track
        The fleet (``tracks[i]`` is the measuring robot).
    i : int
        The measuring robot.
    xy : ndarray, shape (n, 2)
        Laser positions [m].
    when : ndarray, shape (n,)
        Planned times [s].
    timing : TimingModel
    traffic_block : float, optional
        Blocking per unit of ``routes.traffic`` density (default
        :data:`planner.fleet.blocking.TRAFFIC_BLOCK`); 0 leaves traffic that is not simulated out.

    Returns
    -------
    ndarray, shape (M, n)
        Robots and traffic together (independent).
    """
    xy = np.asarray(xy, float).reshape(-1, 2)
    when = np.asarray(when, float).reshape(-1)
    n, m_pos, h = len(xy), scenario.marker_positions(), _heights(scenario)
    low = np.flatnonzero(np.isfinite(h))
    out = np.zeros((len(m_pos), n))
    if len(low) == 0 or n == 0:
        return out
    origin = np.repeat(xy, len(low), axis=0)
    target = np.tile(m_pos[low], (n, 1))
    ht = np.tile(h[low], n)
    w = np.repeat(when, len(low))
    free = np.ones(len(origin))
    for j, tr in enumerate(tracks):
        if j != i:
            mu, v = lag_difference(tracks, i, j, when, timing)
            free *= 1.0 - block_probability(tr, origin, tracks[i].height, target, ht, w, np.repeat(mu, len(low)),
                                            np.repeat(v, len(low)))
    tops = max(t.height for t in tracks)
    dens = np.repeat(_segment_density(scenario, xy), len(low))
    kw = {} if traffic_block is None else {"traffic_block": traffic_block}
    free *= 1.0 - traffic_probability(dens, ht, tops, **kw)
    out[low] = (1.0 - free).reshape(n, len(low)).T
    return out


def risk(scenario: Scenario, tracks: list[Track], i: int, offset: float,
         timing: TimingModel | None = None) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """Make the ``block`` argument of :func:`planner.schedule.schedule.make_schedule` for robot i's task.

    ``offset`` is where the task's path begins along the robot's whole path [m]. The returned
    function maps the task's arc lengths (n,) and positions (n, 2) to the probability per marker
    (M, n) that another robot (or traffic) hides its line of sight when the robot is there.
    """
    track = tracks[i]
    cache: dict[bytes, np.ndarray] = {}

    def block(s: np.ndarray, xy: np.ndarray) -> np.ndarray:
        # the schedule asks again for each slow-down it tries, mostly at the same samples; within a
        # round the others' timelines and this robot's time at each place are fixed
        s = np.asarray(s, float)
        key = s.tobytes()
        if key not in cache:
            cache[key] = marker_risk(scenario, tracks, i, xy, track.at_s(offset + s), timing)
        return cache[key]

    return block


def risk_sampled(scenario: Scenario, robots: Sequence, drives: SampledDrives, i: int, offset: float
                 ) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """Make the ``block`` argument of the schedule for robot i's task from its fleet's sampled drives.

    As :func:`risk`, for a fleet that declares a timing spread: the robots' blocking from the
    spread's own draws driven through the fleet's zone gate (:func:`planner.fleet.sampled.sampled_risk`,
    the model the plan's prediction and the ``blocking`` check use), traffic that is not simulated
    as :func:`marker_risk` has it. ``drives``: :func:`planner.fleet.sampled.sampled_drives` of
    ``robots``; ``offset``: where the task's path begins along robot i's whole path [m]. The returned
    function maps the task's arc lengths (n,) [m] and positions (n, 2) [m] to the probability per
    marker (M, n).
    """
    cache: dict[bytes, np.ndarray] = {}
    h = _heights(scenario)
    tops = max(r.robot.height for r in robots)

    def block(s: np.ndarray, xy: np.ndarray) -> np.ndarray:
        s = np.asarray(s, float)
        key = s.tobytes()
        if key not in cache:
            p = sampled_risk(scenario, robots, drives, i, offset + s, xy, scenario.planning.eps_max)
            low = np.flatnonzero(np.isfinite(h))
            dens = _segment_density(scenario, xy)
            if len(low) and np.any(dens > 0):
                traffic = traffic_probability(np.repeat(dens, len(low)), np.tile(h[low], len(s)), tops)
                p[low] = 1.0 - (1.0 - p[low]) * (1.0 - traffic.reshape(len(s), len(low)).T)
            cache[key] = p
        return cache[key]

    return block


def declares_spread(robots: Sequence) -> bool:
    """Whether the fleet declares a timing spread (every robot its ``[[robots]]`` table, one a spread)."""
    declared = [getattr(r, "declared", None) for r in robots]
    return all(d is not None for d in declared) and any(
        d.start_jitter > 0 or d.dwell > 0 or d.speed_spread > 0 for d in declared)


def predict(scenario: Scenario, robots: Sequence, tracks: list[Track] | None = None,
            timing: TimingModel | None = None) -> list[RobotBlocking]:
    """Predicted blocking of every scheduled fix of every robot (``robots``: ``FleetRobotPlan``).

    A fleet that declares a timing spread (and no ``tracks`` or ``timing`` given) is predicted from
    the spread's draws (:func:`planner.fleet.sampled.predict_sampled`), which also names the fixes
    whose blocking hinges on the tracking errors (``RobotBlocking.undecided``); otherwise from the
    Gaussian lag model of :mod:`planner.fleet.blocking`.
    """
    sampled = predict_sampled(scenario, robots) if tracks is None and timing is None and declares_spread(robots) \
        else None
    tracks = tracks_of(robots, timing) if tracks is None else tracks
    m_pos, h = scenario.marker_positions(), _heights(scenario)
    tops = max(t.height for t in tracks)
    out = []
    for i, r in enumerate(robots):
        task, fix, s, xy, markers, prot = [], [], [], [], [], []
        for q, (plan, off) in enumerate(zip(r.plans, r.offsets, strict=True)):
            for f, fx in enumerate(plan.schedule.fixes):
                task.append(q)
                fix.append(f)
                s.append(off + fx.s)
                xy.append(fx.position)
                markers.append(fx.markers)
                prot.append(len(fx.fallbacks) == len(fx.markers) and all(fx.fallbacks))
        s, xy, markers = np.array(s, float), np.array(xy, float).reshape(-1, 2), np.array(markers, int)
        n_fix, k = markers.shape if markers.size else (0, scenario.sensor.markers_per_fix)
        when = tracks[i].at_s(s)
        origin = np.repeat(xy, k, axis=0)
        target, ht = m_pos[markers.reshape(-1)], h[markers.reshape(-1)]
        w = np.repeat(when, k)
        free_ray, free_fix = np.ones(n_fix * k), np.ones(n_fix)
        for j, tr in enumerate(tracks):
            if j == i or sampled is not None:
                continue
            mean, var = lag_difference(tracks, i, j, when, timing)
            mu, v = np.repeat(mean, k), np.repeat(var, k)
            free_ray *= 1.0 - block_probability(tr, origin, tracks[i].height, target, ht, w, mu, v)
            # at least one of the fix's rays: the union of their regions under the same lag
            free_fix *= 1.0 - block_probability(tr, origin, tracks[i].height, target, ht, w, mu, v,
                                                group=np.repeat(np.arange(n_fix), k))
        dens = np.repeat(_segment_density(scenario, xy), k)
        p_robot, p_fix, undecided = (1.0 - free_ray).reshape(n_fix, k), 1.0 - free_fix, None
        if sampled is not None:
            p_robot, p_fix = sampled.p_robot[i].reshape(n_fix, k), sampled.p_fix[i]
            undecided = sampled.undecided[i] > UNDECIDED
        out.append(RobotBlocking(task=np.array(task, int), fix=np.array(fix, int), time=when, s=s, markers=markers,
                                 p_robot=p_robot, p_fix=p_fix,
                                 p_traffic=traffic_probability(dens, ht, tops).reshape(n_fix, k),
                                 protected=np.array(prot, bool), undecided=undecided))
    return out

