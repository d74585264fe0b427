"""Predicted blocking of a fleet with a declared timing spread, from the spread's own draws.

A declared spread (:mod:`planner.fleet.timing`) is a few numbers per robot and run: a release delay
U J (U uniform on [0, 1]), a dwell per dock, a speed factor f uniform on [1 - s, 1]. The Gaussian
lag algebra of :mod:`planner.fleet.blocking` stands their sum in for a normal law and ties the
robots only through the waits the plan has; both fail where it matters: the difference of two
release delays is triangular, not normal, and a robot released 10 s late makes another wait
where the plan had no wait (``warehouse-fleet-spread`` with a 12 s spread: 234.7 fixes predicted
hidden in 200 runs, 76 were; with a 4 s one the 15.7 predicted and the 19 hidden were on other fixes).

So the prediction drives the fleet once per draw of the spread, :data:`DRAWS` independent draws
from a generator seeded from the scenario's seed (so that the prediction's own sampling error has
the plain variance the ``blocking`` check allows for), and averages what it sees. Each draw drives
the fleet kinematically through its zone control with the simulation's own gate
(:mod:`planner.fleet.drive`): a robot waits where and as long as the simulated one does. (The plan's
own timeline, :func:`planner.fleet.zones.predict_timeline`, reserves step by step and stands at the
reservation's end: on ``warehouse-fleet-spread`` with a 30 s spread it had r1 waiting 1-4 m short of
where the simulated r1 waits, at (25.0, 11.8), and r3's fixes near dock F that r1 hides there in one
run in ten were predicted never hidden.)

Against that sweep's episodes, each run's own draws driven at :data:`planner.fleet.drive.DT`
(``benchmarks/fleet_timelines.py``, first 40 runs): the model's robots are within 0.4 cm of the
simulated ones half the time and 0.15 m at the 95th percentile (0.63 m before the follower's
corner cutting was modelled, :data:`planner.fleet.drive.CORNER_GAIN`), each scheduled fix 0.11 s
early in the median (5-95 %
-0.29 .. +0.02 s), and every zone wait of the episodes is one of the model's, at the same place
within 1.5 cm, -0.18 .. +0.30 s as long (docs/benchmarks.md, ``fleet_timelines``).

The measurement schedule's risk comes from the same draws (:func:`sampled_risk`,
:mod:`planner.fleet.traffic`), so that a fix the spread leaves likely hidden gets a fallback where
one exists (a stretch where none does is left unprotected, and the plan says so).

Robot i measures fix f when its drive reaches the fix's arc length; robot j then covers the fix's
ray q with probability ``Phi((r_j - d_q) / sd)``, d_q the distance of j's centre to the ray's low
part (:func:`planner.fleet.blocking.low_segment`), sd :data:`planner.fleet.blocking.STAND_SD`
standing, :data:`planner.fleet.blocking.POS_SD` driving. A fix's probability is the mean over the
draws of ``1 - prod_j (1 - max_q cover_jq)`` (one body, one place, hides a fix's rays together).

**Undecided fixes.** Whether a ray that passes a *standing* robot within a few centimetres of its
body is hidden does not vary with the timing: it is decided by where the measuring robot is at
the fix and where the other one stands to the centimetre, i.e. by the path followers' tracking
errors, the same in every run and not known to the plan. A draw leaves a fix undecided when a
robot stands with the edge of its body within ``g_i + g_j`` of one of the fix's rays: ``g_i`` the
plan's bound on the measuring robot's offset from its path at the fix (tracking bound plus the
estimate error it certifies there, :func:`planner.schedule.promise.tracking_bound`), ``g_j`` that of
the standing robot (the start pose's 3 x 1 mm on its start dock; elsewhere its tracking bound plus
STAND_BACK, how far its stop may fall along the path). A fix undecided in more than
:data:`UNDECIDED` of the draws gets no probability the runs could test (``RobotBlocking.undecided``):
the simulation leaves its ``p_block_robot`` NaN and the ``blocking`` check counts it apart.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr

from planner.fleet.blocking import POS_SD, STAND_BACK, STAND_SD, low_segment
from planner.fleet.drive import drive_timings, iter_drives
from planner.fleet.gate import GOAL_TOLERANCE
from planner.schedule.promise import tracking_bound, turn_bias

#: Draws of the timing spread. The prediction's own sampling error enters the check as a bias: the
#: prediction of one run's count is the mean of DRAWS independent draws of a variable whose
#: variance is at most that of the count itself, so over R runs it errs with a variance of at most
#: R / DRAWS times the runs' own: the check's sd grows by sqrt(1 + R / DRAWS), 1.18 at R = 200.
DRAWS = 512
#: Spawn key (under the scenario's seed) of the draws' generator.
SPREAD_KEY = 17
#: Share of the draws above which a fix is undecided (module docstring): its prediction may be off by
#: at most that much, and the undecided mass left in decided fixes is reported.
UNDECIDED = 0.01
#: Draws of the spread behind the measurement schedule's risk (:func:`sampled_drives`): the risk is
#: compared with a limit of a few per cent (:func:`planner.fleet.traffic.block_limit`, 0.025 on
#: ``warehouse-fleet``); a share of 128 draws errs by at most 3 sqrt(0.025 x 0.975 / 128) = 0.041
#: there (false alarm 0.3 %), and a fix hidden in one run in ten (the case that matters) is told apart.
RISK_DRAWS = 128
#: Bound on where a robot stands on its start dock [m]: three times the start pose's 1 mm
#: (``sim.episode.driver.START_POS_STD``).
DOCK_BOUND = 0.003


@dataclass(frozen=True)
class SampledBlocking:
    """Per robot, the sampled prediction of its scheduled fixes (F fixes of k markers each).

    Attributes
    ----------
    p_robot : list of ndarray, shape (F, k)
        Probability another robot hides each scheduled marker.
    p_fix : list of ndarray, shape (F,)
        Probability another robot hides at least one.
    undecided : list of ndarray, shape (F,)
        Share of the draws in which the fix was undecided (module docstring).
    count_mean, count_var : float
        Mean and variance of one run's count of hidden decided fixes (the fleet's, every robot's):
        over the draws, the variance of each draw's expected count plus the mean of its
        ``sum p (1 - p)`` (the fixes' place spreads taken independent within a draw).
    hits : ndarray, shape (D, F), optional
        Per draw, the probability that each decided fix is hidden (0 at an undecided one), the
        robots' fixes one after another: the law of one run's count the moments above summarise
        (:func:`validation.blocking.model_powers` draws runs from it).
    """

    p_robot: list[np.ndarray]
    p_fix: list[np.ndarray]
    undecided: list[np.ndarray]
    count_mean: float = 0.0
    count_var: float = 0.0
    hits: np.ndarray | None = None


def _path_bounds(robots: Sequence) -> list[np.ndarray]:
    """Each robot's tracking bound at its path's samples [m] (:func:`planner.schedule.promise.tracking_bound`)."""
    return [tracking_bound(r.path, r.s, r.speed, np.asarray(r.s, float), turn_bias(r.robot)) for r in robots]


def _stand_bound(r, bound: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Bound on where robot ``r`` standing at arc length(s) ``s`` is [m]: on its start dock, elsewhere.

    ``bound``: its tracking bound at its path's samples (:func:`_path_bounds`); between two samples
    the larger of the two.
    """
    k = np.clip(np.searchsorted(r.s, s), 1, len(r.s) - 1)
    return np.where(s <= 0.0, DOCK_BOUND, np.maximum(bound[k - 1], bound[k]) + STAND_BACK)


def _at(t: np.ndarray, s: np.ndarray, stand: np.ndarray, when: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Arc length and standing of a robot at times ``when`` (F,) along its sampled drive: (F,), (F,) bool."""
    k = np.clip(np.searchsorted(t, when, side="right"), 1, len(t) - 1)
    # standing during the tick that ends at sample k (or before its first, after its last sample)
    still = stand[k] | (when <= t[0]) | (when >= t[-1])
    return np.interp(when, t, s), still


def _timings(scenario, robots: Sequence, draws: int) -> list[tuple[list, list, list]]:
    """Draw the declared spread ``draws`` times: per draw each robot's release [s], speed factor, dwells [s].

    From a generator seeded from the scenario's seed (spawn key :data:`SPREAD_KEY`): the same draws
    for the schedule's risk (:func:`sampled_drives`) and the prediction (:func:`predict_sampled`).
    """
    docks = [len(r.offsets) for r in robots]
    rng = np.random.default_rng(np.random.SeedSequence(scenario.seed, spawn_key=(SPREAD_KEY,)))
    cube = rng.random((draws, sum(2 + d for d in docks)))
    out = []
    for n in range(draws):
        col, factors, dwells, starts = 0, [], [], []
        for r, d in zip(robots, docks, strict=True):
            fr = r.declared
            u = cube[n, col:col + 2 + d]
            col += 2 + d
            factors.append(1.0 - fr.speed_spread * u[1])
            dwells.append(fr.dwell * u[2:1 + d])    # at the end of each task but the last
            starts.append(r.start_time + fr.start_jitter * u[0])
        out.append((starts, factors, dwells))
    return out


@dataclass(frozen=True)
class SampledDrives:
    """The fleet's drives in D draws of its declared spread (:mod:`planner.fleet.drive`), for the schedule's risk.

    ``drives[n][i]`` is robot i's (t, s, stand) in draw n; ``bounds[i]`` its tracking bound at its
    path's samples.
    """

    drives: list[list[tuple[np.ndarray, np.ndarray, np.ndarray]]]
    bounds: list[np.ndarray]


def sampled_drives(scenario, robots: Sequence, draws: int = RISK_DRAWS) -> SampledDrives:
    """Drive the fleet in ``draws`` draws of its declared spread (the first of :func:`predict_sampled`'s)."""
    return SampledDrives(drive_timings(scenario, robots, _timings(scenario, robots, draws)), _path_bounds(robots))


def _covers(r_j, track: tuple, when: np.ndarray, a: np.ndarray, dvec: np.ndarray, m: int
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Where robot ``r_j`` is at times ``when`` (n,) of its drive, and how likely its body covers m rays.

    ``track``: its (t, s, stand) in one draw (:func:`planner.fleet.drive.drive_draw`); ``a``,
    ``dvec`` (n m, 2) [m]: each ray's low part from ``a`` along ``dvec``
    (:func:`planner.fleet.blocking.low_segment`), the m rays of each time in a row.

    Returns
    -------
    dist : ndarray, shape (n, m)
        Distance of its centre to each ray's low part [m].
    cover : ndarray, shape (n, m)
        ``Phi((radius - dist) / sd)``: sd ``STAND_SD`` standing, ``POS_SD`` driving.
    still : ndarray of bool, shape (n,)
        Standing then.
    s_place : ndarray, shape (n,)
        Its arc length then [m].
    """
    t_j, s_j, stand_j = track
    s_place, still = _at(t_j, s_j, stand_j, when)
    place = np.column_stack([np.interp(s_place, r_j.s, r_j.path[:, 0]), np.interp(s_place, r_j.s, r_j.path[:, 1])])
    w = np.repeat(place, m, axis=0) - a
    L2 = np.einsum("qi,qi->q", dvec, dvec)
    uu = np.clip(np.einsum("qi,qi->q", w, dvec) / np.where(L2 > 0, L2, 1.0), 0.0, 1.0)
    dist = np.hypot(*(w - uu[:, None] * dvec).T).reshape(len(when), m)
    sd = np.where(still, STAND_SD, POS_SD)[:, None]
    return dist, ndtr((r_j.robot.radius - dist) / sd), still, s_place


def sampled_risk(scenario, robots: Sequence, drives: SampledDrives, i: int, s: np.ndarray, xy: np.ndarray,
                 eps: float) -> np.ndarray:
    """Probability per marker that another robot hides its line of sight from robot i at arc length(s) ``s``.

    For the measurement schedule (:mod:`planner.fleet.traffic`): the share of the draws in which
    another robot's body covers the ray's low part when robot ``i`` passes ``s`` (its whole path's
    arc length [m], at ``xy`` (n, 2) [m]), the body's place spread as in :func:`predict_sampled`.
    A ray within the two robots' bounds of a *standing* robot's edge counts as hidden: whether it
    is hinges on the tracking errors, the same in every run, so the schedule must not lean on it
    (``eps`` [m] stands in for the estimate's bound, which a fix not yet scheduled has not got).

    Returns
    -------
    ndarray, shape (M, n)
        M markers (0 for those with no part low enough for a robot to hide).
    """
    s = np.asarray(s, float).reshape(-1)
    xy = np.asarray(xy, float).reshape(-1, 2)
    m_pos, h = scenario.marker_positions(), scenario.marker_heights()
    low = np.flatnonzero(np.isfinite(h))
    out = np.zeros((len(m_pos), len(s)))
    if len(low) == 0 or len(s) == 0:
        return out
    r_i = robots[i]
    g_i = tracking_bound(r_i.path, r_i.s, r_i.speed, s, turn_bias(r_i.robot)) + eps
    origin = np.repeat(xy, len(low), axis=0)
    target = np.tile(m_pos[low], (len(s), 1))
    ht = np.tile(h[low], len(s))
    segs = {}
    free = np.zeros((len(s), len(low)))
    for run in drives.drives:
        t_i, s_i, _ = run[i]
        when = np.interp(s, s_i, t_i)   # s_i never decreases: the first time it is there
        keep = np.ones((len(s), len(low)))
        for j, r_j in enumerate(robots):
            if j == i:
                continue
            if j not in segs:
                a, b, some = low_segment(origin, r_i.robot.height, target, ht, r_j.robot.height)
                segs[j] = (a, b - a, some.reshape(len(s), len(low)))
            a, dvec, some = segs[j]
            dist, cover, still, s_place = _covers(r_j, run[j], when, a, dvec, len(low))
            band = (g_i + _stand_bound(r_j, drives.bounds[j], s_place))[:, None]
            cover = np.where(still[:, None] & (np.abs(dist - r_j.robot.radius) < band), 1.0, cover)
            keep *= 1.0 - np.where(some, cover, 0.0)
        free += keep
    out[low] = (1.0 - free / len(drives.drives)).T
    return out


def predict_sampled(scenario, robots: Sequence, draws: int = DRAWS, timing: Sequence | None = None
                    ) -> SampledBlocking:
    """Predict every scheduled fix's blocking from the declared spread's draws (module docstring).

    Parameters
    ----------
    scenario : Scenario
        The fleet's scenario (its markers, their heights, its seed).
    robots : sequence of FleetRobotPlan
        The planned fleet, each with its ``declared`` ``[[robots]]`` table.
    draws : int
        Draws of the spread.
    timing : sequence of (starts, factors, dwells), optional
        Given draws instead (each robot's release [s], speed factor and dwells [s]): e.g. one run's
        own, to set the model against that run (``benchmarks/fleet_timelines.py``).

    Returns
    -------
    SampledBlocking
    """
    n_rob = len(robots)
    m_pos, h = scenario.marker_positions(), scenario.marker_heights()
    timing = _timings(scenario, robots, draws) if timing is None else list(timing)
    draws = len(timing)
    bounds = _path_bounds(robots)
    # the fixes of each robot: arc length, rays, and the bound on the measuring robot's offset
    fixes = []
    for r in robots:
        s, xy, mk, est = [], [], [], []
        for plan, off in zip(r.plans, r.offsets, strict=True):
            for fx in plan.schedule.fixes:
                s.append(off + fx.s)
                xy.append(fx.position)
                mk.append(fx.markers)
                est.append(fx.estimate if np.isfinite(fx.estimate) else 0.0)
        s = np.asarray(s, float)
        mk = np.asarray(mk, int).reshape(len(s), -1) if len(s) else np.zeros((0, 1), int)
        g = tracking_bound(r.path, r.s, r.speed, s, turn_bias(r.robot)) + np.asarray(est, float)
        # a fix within the goal tolerance of a task's end is taken where the robot stops there
        ends = np.append(np.asarray(r.offsets, float)[1:], r.s[-1])
        reach = np.minimum(s, ends[np.clip(np.searchsorted(ends, s, side="left"), 0, len(ends) - 1)] - GOAL_TOLERANCE)
        fixes.append((np.maximum(reach, 0.0), np.asarray(xy, float).reshape(-1, 2), mk, g))
    free_ray = [np.zeros((draws, len(f[0]), f[2].shape[1])) for f in fixes]
    free_fix = [np.zeros((draws, len(f[0]))) for f in fixes]
    undecided = [np.zeros((draws, len(f[0])), bool) for f in fixes]
    for n, runs in enumerate(iter_drives(scenario, robots, timing)):
        starts = timing[n][0]
        for i, (s_f, xy_f, mk, g_i) in enumerate(fixes):
            t_i, s_i, _ = runs[i]
            # the first time its drive reaches each fix's arc length
            k = np.clip(np.searchsorted(np.maximum.accumulate(s_i), s_f, side="left"), 1, len(s_i) - 1)
            ds = s_i[k] - s_i[k - 1]
            frac = np.clip((s_f - s_i[k - 1]) / np.where(ds > 0, ds, 1.0), 0.0, 1.0)
            when = t_i[k - 1] + frac * (t_i[k] - t_i[k - 1])
            # the standstill fix on the start dock is taken as the robot is released
            when = np.where(s_f <= 0.0, starts[i], when)
            q = mk.shape[1]
            origin = np.repeat(xy_f, q, axis=0)
            free_r = np.ones((len(s_f), q))
            free_f = np.ones(len(s_f))
            und = np.zeros(len(s_f), bool)
            for j in range(n_rob):
                if j == i:
                    continue
                a, b, some = low_segment(origin, robots[i].robot.height, m_pos[mk.reshape(-1)], h[mk.reshape(-1)],
                                         robots[j].robot.height)
                dist, cover, still, s_place = _covers(robots[j], runs[j], when, a, b - a, q)
                some = some.reshape(len(s_f), q)
                cover = np.where(some, cover, 0.0)
                free_r *= 1.0 - cover
                free_f *= 1.0 - cover.max(axis=1)
                band = (g_i + _stand_bound(robots[j], bounds[j], s_place))[:, None]
                und |= still & np.any(some & (np.abs(dist - robots[j].robot.radius) < band), axis=1)
            free_ray[i][n], free_fix[i][n], undecided[i][n] = free_r, free_f, und
    share = [u.mean(axis=0) for u in undecided]
    # one run's count of hidden decided fixes: per draw its mean and its spread about that mean
    hit = [np.where(sh > UNDECIDED, 0.0, 1.0 - ff) for sh, ff in zip(share, free_fix, strict=True)]
    per_draw = sum(x.sum(axis=1) for x in hit)
    spread = sum((x * (1.0 - x)).sum(axis=1) for x in hit)
    return SampledBlocking(p_robot=[1.0 - fr.mean(axis=0) for fr in free_ray],
                           p_fix=[1.0 - ff.mean(axis=0) for ff in free_fix], undecided=share,
                           count_mean=float(per_draw.mean()), count_var=float(per_draw.var() + spread.mean()),
                           hits=np.concatenate(hit, axis=1) if hit else np.zeros((draws, 0)))
