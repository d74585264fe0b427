"""Predicted blocking of a fleet with a declared timing spread, from the spread's own draws.

A declared spread (:mod:`planner.fleet.timing`) is a few numbers per robot and run: a release delay
U J (U uniform on [0, 1]), a dwell per dock, a speed factor f uniform on [1 - s, 1]. The Gaussian
lag algebra of :mod:`planner.fleet.blocking` stands their sum in for a normal law and ties the
robots only through the waits the plan has; both fail where it matters: the difference of two
release delays is triangular, not normal, and a robot released 10 s late makes another wait
where the plan had no wait (``warehouse-fleet-spread`` with a 12 s spread: 234.7 fixes predicted
hidden in 200 runs, 76 were; with a 4 s one the 15.7 predicted and the 19 hidden were on other fixes).

So the prediction drives the fleet's own zone control (:func:`planner.fleet.zones.predict_timeline`,
the rule the simulation keeps) once per draw of the spread, :data:`DRAWS` independent draws from a
generator seeded from the scenario's seed (so that the prediction's own sampling error has the
plain variance the ``blocking`` check allows for), and averages what it sees. In each draw a robot

* leaves ``start_time + U J`` and drives its planned speed profile at f times the speed, with the
  follower's ramp from rest (it accelerates at :data:`planner.schedule.promise.FOLLOWER_MAX_ACCEL`
  where the plan starts at full speed: a lag of ``sqrt(2 s / a) - s / v`` after s metres, ``v / 2a``
  beyond ``v^2 / 2a``; measured on ``warehouse-fleet-spread``'s r3, 40 runs: 0.32, 0.59, 0.83,
  0.92 s at 0.02, 0.1, 0.3, 0.5 m against 0.26, 0.53, 0.80, 0.91 s) at each task's start, and
  stands its dwell at each dock between two tasks;
* restarts from each zone wait ``v f / 2a`` late (the same ramp; measured 0.88-1.10 s at 1 m/s);
* stands where the simulated robot stands: on its start dock until it leaves, STAND_BACK short
  of the timeline's place while waiting and on its final dock (:meth:`planner.fleet.blocking.Track.stand_back`).

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
estimate error it certifies there, :func:`planner.schedule.promise.offset_bound`), ``g_j`` that of
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
from planner.fleet.zones import Timeline, ZoneControl, predict_timeline
from planner.schedule.pathtime import Kinematics
from planner.schedule.promise import FOLLOWER_MAX_ACCEL, tracking_bound

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
#: Time step of the sampled timelines [s] (that of the plan's own timeline).
DT = 0.1
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
    """

    p_robot: list[np.ndarray]
    p_fix: list[np.ndarray]
    undecided: list[np.ndarray]
    count_mean: float = 0.0
    count_var: float = 0.0


class _Drive:
    """One robot's undisturbed drive in one draw: planned profile at f times the speed, ramps, dwells.

    Offers what :func:`planner.fleet.zones.predict_timeline` reads of a Kinematics: ``t_at``,
    ``s_at`` and ``t_v[-1]``.
    """

    def __init__(self, s_v: np.ndarray, speed: np.ndarray, starts: np.ndarray, dwell: np.ndarray,
                 factor: float, v_max: float, accel: float):
        base = Kinematics(s_v, speed)
        end = float(s_v[-1])
        # grid fine enough that linear interpolation of the quadratic profile errs < 1 mm
        grid = np.union1d(s_v, np.linspace(0.0, end, max(int(end / 0.02), 2)))
        v = v_max * factor
        t = base.t_at(grid) / factor
        for k, (a, w) in enumerate(zip(starts, dwell, strict=True)):
            past = np.maximum(grid - a, 0.0)
            ramp = np.where(past < v * v / (2.0 * accel), np.sqrt(2.0 * past / accel) - past / v, v / (2.0 * accel))
            t = t + np.where(grid > a, ramp, 0.0) + np.where(grid > a, w, 0.0) * (k > 0)
        self._s, self._t = grid, np.maximum.accumulate(t)
        self.factor = factor
        self.t_v = np.array([0.0, float(self._t[-1])])

    def t_at(self, s):
        return np.interp(s, self._s, self._t)

    def s_at(self, t):
        return np.interp(t, self._t, self._s)


def _order(robots: Sequence) -> list[np.ndarray] | None:
    """Return the plan's order of passage when a dock lies on another's path (as ``plan_fleet`` records it)."""
    zones = _zones(robots, None, record=True)
    if zones.dock_conflict is None:
        return None
    predict_timeline(zones, [Kinematics(r.s, r.speed) for r in robots], [r.start_time for r in robots])
    return zones.precedence()


def _zones(robots: Sequence, order, record: bool = False) -> ZoneControl:
    return ZoneControl([r.path for r in robots], [r.robot.radius for r in robots], [r.name for r in robots],
                       after=order, record=record)


def _restarted(tl: Timeline, restart: float) -> tuple[np.ndarray, np.ndarray]:
    """Return a sampled timeline's times with each zone wait's restart added, and where it stands.

    Returns the shifted times (T,) and a bool (T,) that the robot stands at the sample (waiting).
    """
    t, waiting = np.asarray(tl.t, float).copy(), np.asarray(tl.waiting, bool)
    ends = np.flatnonzero(waiting[:-1] & ~waiting[1:]) + 1   # first sample driving again
    for e in ends:
        t[e:] += restart
    # the shift opens a gap in time at each restart: the robot stands there meanwhile
    return t, waiting


def _stand_bound(r, s: np.ndarray) -> np.ndarray:
    """Bound on where robot ``r`` standing at arc length(s) ``s`` is [m]: on its start dock, elsewhere."""
    return np.where(s <= 0.0, DOCK_BOUND, tracking_bound(r.path, r.s, r.speed, s) + STAND_BACK)


def _at(t: np.ndarray, xy: np.ndarray, stand: np.ndarray, when: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where a robot is at times ``when`` (F,) along its sampled track: (F, 2) place, (F,) standing."""
    k = np.clip(np.searchsorted(t, when, side="right"), 1, len(t) - 1)
    t0, t1 = t[k - 1], t[k]
    u = np.clip((when - t0) / np.where(t1 > t0, t1 - t0, 1.0), 0.0, 1.0)
    # standing at either end of the step (a wait, or the restart's gap): at the earlier place
    still = stand[k] | stand[k - 1] | (when <= t[0]) | (when >= t[-1])
    u = np.where(still, 0.0, u)
    k0 = np.where(when >= t[-1], len(t) - 1, k - 1)
    place = xy[k0] + u[:, None] * (xy[np.minimum(k0 + 1, len(t) - 1)] - xy[k0])
    return place, still


def predict_sampled(scenario, robots: Sequence, draws: int = DRAWS) -> SampledBlocking:
    """Predict every scheduled fix's blocking from the declared spread's draws (module docstring).

    Parameters
    ----------
    scenario : Scenario
        The fleet's scenario (its markers, their heights, its seed).
    robots : sequence of FleetRobotPlan
        The planned fleet, each with its ``declared`` ``[[robots]]`` table.
    draws : int
        Draws of the spread.

    Returns
    -------
    SampledBlocking
    """
    n_rob = len(robots)
    m_pos, h = scenario.marker_positions(), scenario.marker_heights()
    docks = [len(r.offsets) for r in robots]
    dim = sum(2 + d for d in docks)
    rng = np.random.default_rng(np.random.SeedSequence(scenario.seed, spawn_key=(SPREAD_KEY,)))
    cube = rng.random((draws, dim))
    order = _order(robots)
    accel = FOLLOWER_MAX_ACCEL
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
        g = tracking_bound(r.path, r.s, r.speed, s) + np.asarray(est, float)
        fixes.append((s, np.asarray(xy, float).reshape(-1, 2), mk, g))
    free_ray = [np.zeros((draws, len(f[0]), f[2].shape[1])) for f in fixes]
    free_fix = [np.zeros((draws, len(f[0]))) for f in fixes]
    undecided = [np.zeros((draws, len(f[0])), bool) for f in fixes]
    for n in range(draws):
        col, drives, starts = 0, [], []
        for r in robots:
            fr = r.declared
            d = len(r.offsets)
            u = cube[n, col:col + 2 + d]
            col += 2 + d
            f = 1.0 - fr.speed_spread * u[1]
            dwell = fr.dwell * u[2:2 + d]
            drives.append(_Drive(r.s, r.speed, np.asarray(r.offsets, float), dwell, f, r.robot.max_speed, accel))
            starts.append(r.start_time + fr.start_jitter * u[0])
        tls = predict_timeline(_zones(robots, order), drives, starts, dt=DT)
        tracks = []
        for r, tl, dr in zip(robots, tls, drives, strict=True):
            t, stand = _restarted(tl, r.robot.max_speed * dr.factor / (2.0 * accel))
            s_tl = np.asarray(tl.s, float)
            end = float(tl.end_time) + (t[-1] - tl.t[-1])
            parked = t >= end - 1e-9
            stand = stand | parked | (s_tl <= 0.0)
            # waiting and parked: STAND_BACK short of the timeline's place (where the simulated robot stops)
            back = np.where(stand & (s_tl > 0.0), np.maximum(s_tl - STAND_BACK, 0.0), s_tl)
            xy = np.column_stack([np.interp(back, r.s, r.path[:, 0]), np.interp(back, r.s, r.path[:, 1])])
            tracks.append((t, s_tl, xy, stand, back))
        for i, (s_f, xy_f, mk, g_i) in enumerate(fixes):
            t_i, s_i = tracks[i][0], tracks[i][1]
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
                t_j, _, xy_j, stand_j, back_j = tracks[j]
                place, still = _at(t_j, xy_j, stand_j, when)
                s_place = np.interp(when, t_j, back_j)
                a, b, some = low_segment(origin, robots[i].robot.height, m_pos[mk.reshape(-1)], h[mk.reshape(-1)],
                                         robots[j].robot.height)
                p = np.repeat(place, q, axis=0)
                dvec, w = b - a, p - a
                L2 = np.einsum("qi,qi->q", dvec, dvec)
                uu = np.clip(np.einsum("qi,qi->q", w, dvec) / np.where(L2 > 0, L2, 1.0), 0.0, 1.0)
                dist = np.hypot(*(w - uu[:, None] * dvec).T).reshape(len(s_f), q)
                some = some.reshape(len(s_f), q)
                sd = np.where(still, STAND_SD, POS_SD)[:, None]
                cover = np.where(some, ndtr((robots[j].robot.radius - dist) / sd), 0.0)
                free_r *= 1.0 - cover
                free_f *= 1.0 - cover.max(axis=1)
                band = (g_i + _stand_bound(robots[j], s_place))[:, None]
                und |= still & np.any(some & (np.abs(dist - robots[j].robot.radius) < band), axis=1)
            free_ray[i][n], free_fix[i][n], undecided[i][n] = free_r, free_f, und
    share = [u.mean(axis=0) for u in undecided]
    # one run's count of hidden decided fixes: per draw its mean and its spread about that mean
    hit = [np.where(sh > UNDECIDED, 0.0, 1.0 - ff) for sh, ff in zip(share, free_fix, strict=True)]
    per_draw = sum(x.sum(axis=1) for x in hit)
    spread = sum((x * (1.0 - x)).sum(axis=1) for x in hit)
    return SampledBlocking(p_robot=[1.0 - fr.mean(axis=0) for fr in free_ray],
                           p_fix=[1.0 - ff.mean(axis=0) for ff in free_fix], undecided=share,
                           count_mean=float(per_draw.mean()), count_var=float(per_draw.var() + spread.mean()))
