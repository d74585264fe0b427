"""Predicted blocking of a fleet's lines of sight: the chance another robot's body hides a reflector.

**Geometry (3D).** Robot i's laser sits on top of it (``robot.height`` h_i, at the robot's
centre p). Its ray to marker m runs from (p, h_i) to the reflector's centre (m, h_m). Another
robot j is a cylinder of radius r_j and height H_j on the floor (what the simulation builds);
it blocks the ray where the ray passes over its footprint below its top: the ray's height
``z(u) = h_i + u (h_m - h_i)`` (u in [0, 1] along the ray) is at most H_j on an interval of u,
whose floor projection is a *low segment* of the ray, and robot j blocks the ray exactly when
its centre lies within r_j of that segment (:func:`low_segment`). A marker without a height
(above every robot) is never blocked.

**Timing (the uncertainty).** The plan says where each robot is when
(:func:`planner.fleet.zones.predict_timeline`, waits included); real robots are not there on
time. Each robot's *lag* delta (actual minus planned time at which it passes a place on its
path) is Gaussian. From its departure it is the robot's own: mean ``lag0 + lag_rate * d``,
variance ``base_var + var_rate * d`` over the planned time d it has driven. A zone wait ties it
to the robot it waited for (:attr:`planner.fleet.zones.Timeline.holder`): the waiting robot
leaves when the holder has passed, ``release_lag`` (variance ``release_var``) after it, so from
the wait's end its lag is the holder's lag at the planned release time plus that restart, plus
its own drift since (``lag_rate``, ``var_rate`` per second driven), unless it arrived so late
that the holder had gone (its own lag, less the planned wait, is the larger mean: it did not
stop). Tied lags are correlated: robot i measuring at planned time T and robot j tied to i's lag
at time t differ by i's drift between t and T and j's restart and drift, not by two independent
lags (:func:`lag_difference`; the built-in fleet's robot r1, waiting five times for r3, hid a
reflector of r3's fixes in every run where independent lags, each wait adding a second, gave
0.2-1.7 %). Robot i measures at planned time T (its fix is triggered by arc length,
so it is where the plan says, at time T + delta_i); robot j is then where its plan has it at
time ``T + delta_i - delta_j``. The probability that robot j blocks the ray is the mass of
``T + delta_i - delta_j`` over the planned times at which j's centre is in the blocking region
(robot j's timeline; before its start and after its end it stands on its docks), each time
weighted by the chance that j's centre, spread by :data:`POS_SD` about its planned place, lies
in the region (a robot waiting at a stop stands a few centimetres from where the timeline has
it: timing alone would make its shadow's edge sharp).
Several robots block independently: ``p = 1 - prod_j (1 - p_j)``.

**Limit.** The geometry is the plan's: where the measuring robot is at its fix and where a robot
stands, to the spread that varies between runs (:data:`STAND_SD`). A ray that passes within a
centimetre or two of a standing robot's body is hidden or not by the path follower's tracking
error, which is the same in every run and not modelled here; and the normal law stands in for
uniform release delays whose difference is triangular (``warehouse-fleet-spread`` with a 12 s,
0.8-1.0 spread at 200 runs: 234.7 fixes predicted hidden, 76 were; ``docs/benchmarks.md``). The
schedule's risk (:func:`planner.fleet.exposure.risk`) still comes from this model; a fleet that
declares a timing spread has its prediction from the spread's own draws, with such rays set apart
(:mod:`planner.fleet.sampled`).

**Traffic that is not simulated** (``routes.traffic``, a density in [0, 1] per segment): it adds,
for a fix on a segment of density d, ``traffic_block * d`` for each of its lines of sight to a
reflector mounted below the robots' tops (:func:`traffic_probability`; ``traffic_block`` is
:data:`TRAFFIC_BLOCK` unless given): the chance a person or a forklift of the density's traffic
stands in the ray, independent of the robots. It is planned for, and reported apart from the
robots' blocking (the simulation does not draw it, so the calibration check compares only the
robots').
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy.special import ndtr

from planner.fleet.zones import Timeline

#: Time step the timelines are refined to before the blocking regions are sampled [s]: a robot
#: at 1 m/s moves 2.5 cm, against a body of tens of cm and a timing spread of tenths of a second.
FINE_DT = 0.025
#: Standard deviations of the timing spread beyond which a sample's mass is neglected (Phi(-8) ~ 6e-16).
WINDOW_SD = 8.0
#: Spread of where a body stands across the edge of a blocking region [m]. The simulated robots
#: stop STOP_MARGIN = 5 cm short of their reservation's end (sim.episode.fleet), where the
#: timeline stops them on it; the timeline's path samples are 0.1 m apart (a uniform error of
#: 0.1 m, variance 0.1^2 / 12); the path follower tracks within ~2 cm; and the measuring robot's
#: own place moves the ray by as much again: sqrt(2 (0.05^2 + 0.1^2 / 12 + 0.02^2)) = 0.087 m.
POS_SD = float(np.sqrt(2.0 * (0.05 ** 2 + 0.1 ** 2 / 12.0 + 0.02 ** 2)))
#: Position spreads beyond the radius a sample is still looked at (Phi(-5) ~ 3e-7).
POS_REACH = 5.0
#: How far short of the timeline's place a simulated robot waiting for a zone stands [m]: it
#: stops STOP_MARGIN = 5 cm short of its reservation's end (sim.episode.fleet), where the
#: timeline stops it. A declared timing spread's tracks place their waits there (:meth:`Track.stand_back`).
STAND_BACK = 0.05
#: Spread of a waiting or parked robot's place across the edge of a blocking region [m], once
#: placed STAND_BACK short: what varies from run to run. The measuring robot starts its fix at the
#: first control tick past the fix's place (uniform over 1/60 s at up to 1 m/s: sd 0.48 cm along
#: its path), and the robots' true places vary by about 2 mm across their paths and 1 mm where
#: they stand (warehouse-fleet-spread at 200 runs: across-run sd of the measuring robot's place at
#: a fix, median 2.1 mm; of a parked robot's, 0.6-1.3 mm). The path follower's tracking error is
#: the same in every run and is left out: a spread that does not vary between runs is not a
#: chance of the run (with 2.9 cm, tracking included, a ray grazing a parked robot 1 cm clear was
#: predicted hidden in 36 % of the runs and was in none of 45).
STAND_SD = float(np.sqrt((1.0 / 60.0) ** 2 / 12.0 + 0.0021 ** 2 + 0.001 ** 2))
#: A ray within this fraction of the marker's height of level is treated as level.
_LEVEL = 1e-12
#: Blocking probability per unit of ``routes.traffic`` density of a line of sight below the
#: robots' tops (default of :func:`traffic_probability`): a segment of density 1 is one on which,
#: half the time, somebody stands in the way of a line of sight to a low reflector.
TRAFFIC_BLOCK = 0.5


@dataclass(frozen=True)
class TimingModel:
    """A robot's lag against its planned timeline: Gaussian, growing with its drive, reset by zone waits.

    Attributes
    ----------
    lag0 : float
        Mean lag at departure [s].
    lag_rate : float
        Mean lag gained per second of planned driving [s/s].
    release_lag : float
        Mean delay of a robot leaving a zone wait after the robot it waited for has passed [s].
    base_var : float
        Variance of the lag at departure [s^2].
    var_rate : float
        Variance gained per second of planned driving [s^2/s].
    release_var : float
        Variance of that delay [s^2].
    var_quad : float
        Variance gained per squared second of planned driving [s^2/s^2]: a lag proportional to
        the time driven, one factor per run (a declared speed spread, :mod:`planner.fleet.timing`).
    docks : tuple of float
        Planned time driven [s] at which the robot reaches each dock where it dwells.
    dwell_mean, dwell_var : float
        Mean [s] and variance [s^2] of each dwell, independent.
    tie_wait : bool
        Tie the robot's lag to the holder's from the start of a zone wait, not from its end
        (:func:`tie`): a robot that waits stands where the plan has it until the holder has
        passed, whenever it arrived, so that against the holder (and against whoever the holder
        is tied to) it is where the plan has it, not where its own lag would put it. The
        declared timing spread's models set it (:func:`planner.fleet.timing.declared_model`).
    """

    lag0: float
    lag_rate: float
    release_lag: float
    base_var: float
    var_rate: float
    release_var: float
    var_quad: float = 0.0
    docks: tuple[float, ...] = ()
    dwell_mean: float = 0.0
    dwell_var: float = 0.0
    tie_wait: bool = False

    def dwells(self, drive: np.ndarray) -> np.ndarray:
        """Count of docks passed after ``drive`` seconds driven (a robot at a dock has not dwelt yet)."""
        return np.searchsorted(np.asarray(self.docks, float), np.asarray(drive, float), side="left")

    def mean(self, drive: np.ndarray) -> np.ndarray:
        """Mean of a robot's own lag [s] after ``drive`` seconds driven (planned), before any wait."""
        d = np.asarray(drive, float)
        return self.lag0 + self.lag_rate * d + self.dwell_mean * self.dwells(d)

    def var(self, drive: np.ndarray) -> np.ndarray:
        """Variance of a robot's own lag [s^2] after ``drive`` seconds driven (planned), before any wait."""
        d = np.asarray(drive, float)
        return self.base_var + self.var_rate * d + self.var_quad * d * d + self.dwell_var * self.dwells(d)

    def drift(self, d1: np.ndarray, d2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mean [s] and variance [s^2] of the lag a robot gains from ``d1`` to ``d2`` seconds driven (planned)."""
        d1, d2 = np.asarray(d1, float), np.asarray(d2, float)
        gap, docks = d2 - d1, self.dwells(d2) - self.dwells(d1)
        return (self.lag_rate * gap + self.dwell_mean * docks,
                self.var_rate * np.abs(gap) + self.var_quad * gap * gap + self.dwell_var * np.abs(docks))

    def cov(self, d1: np.ndarray, d2: np.ndarray) -> np.ndarray:
        """Covariance [s^2] of a robot's own lags after ``d1`` and ``d2`` seconds driven (planned).

        The drift and the dwells up to the earlier are shared; the speed factor's part is one
        factor times each drive (fully correlated).
        """
        d1, d2 = np.asarray(d1, float), np.asarray(d2, float)
        lo = np.minimum(d1, d2)
        return self.base_var + self.var_rate * lo + self.var_quad * d1 * d2 + self.dwell_var * self.dwells(lo)




#: Measured with ``python benchmarks/timing_spread.py --seeds 4`` (warehouse-fleet's three tasks,
#: each driven alone, 4 seeds; lag at every metre of the path): the robot is 1.05 s late at the
#: first metre (the standstill fix and the follower's acceleration from rest at 0.5 m/s^2, which
#: the plan does not ramp), and catches up 0.0046 s per second driven (pooled line
#: 0.989 s - 0.0046 t); over seeds the lag varies by at most 0.0096 s (var 2.4e-5 s^2 + 1.6e-6
#: s^2/s t): the physics is deterministic but for the start pose and the odometry noise. The
#: measured lag departs from its line by 0.044 s rms: that model error is part of the variance.
_MEASURED = {"lag0": 0.989, "lag_rate": -0.0046, "base_var": 2.4e-5, "var_rate": 1.6e-6, "line_error_var": 0.044 ** 2}
# Floors the simulation sets whatever the seed: a fix starts at a control tick (1/60 s) after its
# planned place is passed and measures at physics steps (1/240 s), and the timeline is a grid of
# predict_timeline's 0.1 s: each a uniform error of its width, variance width^2 / 12.
_FLOOR_VAR = (1.0 / 60.0) ** 2 / 12.0 + (1.0 / 240.0) ** 2 / 12.0 + 0.1 ** 2 / 12.0
# A zone wait's release, derived: the timeline restarts the robot at once when the holder has
# passed; the follower restarts from rest at max_accel 0.5 m/s^2 (sim.episode.follower),
# v / (2 a) = 1 s later at 1 m/s, and may have braked before the release or not: the delay is
# taken uniform on [0, v / a] = [0, 2 s], mean 1 s, variance (2 s)^2 / 12. (Three warehouse-fleet
# episodes: r1 left its waits for r3 0.88-1.10 s after r3's lag, the same in every seed.)
_RELEASE = {"lag": 1.0, "var": 2.0 ** 2 / 12.0}

TIMING = TimingModel(lag0=_MEASURED["lag0"], lag_rate=_MEASURED["lag_rate"], release_lag=_RELEASE["lag"],
                     base_var=_MEASURED["base_var"] + _MEASURED["line_error_var"] + _FLOOR_VAR,
                     var_rate=_MEASURED["var_rate"], release_var=_RELEASE["var"])
"""The timing model of the simulated robots (the comments above give each number's source)."""


def model_of(timing: TimingModel | Sequence[TimingModel] | None, tracks: Sequence[Track], r: int) -> TimingModel:
    """Robot r's timing model: ``timing`` itself, its r-th entry, or (None) its track's own."""
    if timing is None:
        own = tracks[r].timing
        return own if own is not None else TIMING
    return timing if isinstance(timing, TimingModel) else timing[r]


@dataclass(frozen=True)
class Track:
    """One robot's predicted drive, refined, with its lag model: what blocks the others' rays.

    A sample's lag is ``delta_root(root_t) + X``, X independent of every robot's own lag, Gaussian
    with mean ``x_mean`` and variance ``x_var``: the root's own lag at its time (the robot's own
    lag there, before any wait, :meth:`TimingModel.mean`). A sample before the robot's first tied
    wait is its own (``root`` -1, X = 0).

    Attributes
    ----------
    t : ndarray, shape (T,)
        Planned time [s] (the fleet's clock), every :data:`FINE_DT`.
    xy : ndarray, shape (T, 2)
        Planned centre [m].
    s : ndarray, shape (T,)
        Arc length along the robot's whole path [m].
    drive : ndarray, shape (T,)
        Planned time driven so far [s].
    radius, height : float
        The robot's body [m].
    root : ndarray of int, shape (T,)
        The robot whose own lag the sample's lag is tied to (-1: its own, at the sample).
    root_t : ndarray, shape (T,)
        Planned time of the root's lag [s] (the sample's own time for -1).
    x_mean, x_var : ndarray, shape (T,)
        Mean [s] and variance [s^2] of X.
    timing : TimingModel, optional
        The robot's own lag model (None: :data:`TIMING`).
    pos_sd : ndarray, shape (T,), optional
        Spread of the robot's place about ``xy`` across a blocking region's edge [m] (None:
        :data:`POS_SD` everywhere).
    parent, parent_t, p_mean, p_var : ndarray, shape (T,), optional
        With :attr:`TimingModel.tie_wait`: the robot the sample's last zone wait waited for
        (-1: none), the planned release [s], and the mean [s] and variance [s^2] of the sample's
        lag less that robot's lag at the release (the restart and the drift since), for
        :func:`lag_difference` of the two robots.
    """

    t: np.ndarray
    xy: np.ndarray
    s: np.ndarray
    drive: np.ndarray
    radius: float
    height: float
    root: np.ndarray
    root_t: np.ndarray
    x_mean: np.ndarray
    x_var: np.ndarray
    timing: TimingModel | None = None
    pos_sd: np.ndarray | None = None
    parent: np.ndarray | None = None
    parent_t: np.ndarray | None = None
    p_mean: np.ndarray | None = None
    p_var: np.ndarray | None = None

    @classmethod
    def of(cls, timeline: Timeline, start_time: float, radius: float, height: float, dt: float = FINE_DT,
           timing: TimingModel | None = None) -> Track:
        """Refine ``timeline`` to steps of ``dt`` [s] and count its driving time; every lag its own."""
        t0 = np.asarray(timeline.t, float)
        t = np.arange(t0[0], t0[-1] + 0.5 * dt, dt)
        s = np.interp(t, t0, timeline.s)
        xy = np.column_stack([np.interp(t, t0, timeline.xy[:, 0]), np.interp(t, t0, timeline.xy[:, 1])])
        step = np.diff(t0, prepend=t0[0])
        waiting = np.asarray(timeline.waiting, bool)
        driving = ~waiting & (t0 > start_time) & (t0 <= timeline.end_time + 1e-9)
        drive = np.interp(t, t0, np.cumsum(np.where(driving, step, 0.0)))
        zero = np.zeros(len(t))
        return cls(t, xy, s, drive, float(radius), float(height), np.full(len(t), -1), t.copy(), zero, zero.copy(),
                   timing)

    def stand_back(self, timeline: Timeline, path: np.ndarray, path_s: np.ndarray) -> Track:
        """Place the robot's zone waits where a simulated robot stands: STAND_BACK short, spread STAND_SD.

        On its start dock (before it leaves) and parked on its final one it is spread STAND_SD too.

        ``path`` (N, 2) and ``path_s`` (N,) are the robot's whole path and its arc lengths [m].
        """
        t0 = np.asarray(timeline.t, float)
        # a refined sample lies in the timeline's step ending at the first sample at or after it
        step = np.clip(np.searchsorted(t0, self.t, side="left"), 0, len(t0) - 1)
        # waiting for a zone, or parked on its final dock (the follower stops within its goal
        # tolerance, 5 cm, short of it: as far as STAND_BACK)
        wait = (np.asarray(timeline.waiting, bool)[step] & (self.t > t0[0])) | (self.t > timeline.end_time)
        s_back = np.maximum(self.s - STAND_BACK, 0.0)
        back = np.column_stack([np.interp(s_back, path_s, path[:, 0]), np.interp(s_back, path_s, path[:, 1])])
        xy = np.where(wait[:, None], back, self.xy)
        # on its start dock until it leaves: where the dock is, within the start pose's 1 mm
        # (sim.episode.drive.START_POS_STD), whenever it leaves
        still = wait | (self.s <= 0.0)
        return replace(self, xy=xy, pos_sd=np.where(still, STAND_SD, POS_SD))

    def at_s(self, s: np.ndarray) -> np.ndarray:
        """Planned time [s] at which the robot first reaches arc length(s) ``s`` [m]."""
        s = np.asarray(s, float)
        k = np.clip(np.searchsorted(self.s, s, side="left"), 1, len(self.s) - 1)
        s0, s1 = self.s[k - 1], self.s[k]
        u = np.where(s1 > s0, np.clip((s - s0) / np.where(s1 > s0, s1 - s0, 1.0), 0.0, 1.0), 1.0)
        return np.where(s <= self.s[0], self.t[0], self.t[k - 1] + u * (self.t[k] - self.t[k - 1]))

    def sample(self, t: np.ndarray) -> np.ndarray:
        """Index of the sample in force at planned time(s) ``t`` [s]."""
        return np.clip(np.searchsorted(self.t, np.asarray(t, float), side="right") - 1, 0, len(self.t) - 1)


def _waits(timeline: Timeline, t: np.ndarray) -> list[tuple[int, int, int]]:
    """Zone waits of a timeline on refined times ``t``: (first waiting sample, release sample, holder)."""
    if timeline.holder is None:
        return []
    t0, waiting, holder = np.asarray(timeline.t, float), np.asarray(timeline.waiting, bool), timeline.holder
    out = []
    k, n = 0, len(t0)
    while k < n:
        if not waiting[k]:
            k += 1
            continue
        e = k
        while e + 1 < n and waiting[e + 1]:
            e += 1
        # the wait covers the steps ending at samples k..e: it starts at t0[k-1], ends at t0[e]
        a = int(np.searchsorted(t, t0[max(k - 1, 0)] - 1e-9, side="left"))
        b = int(np.searchsorted(t, t0[e] - 1e-9, side="left"))
        out.append((min(a, len(t) - 1), min(b, len(t) - 1), int(holder[e])))
        k = e + 1
    return out


def tie(tracks: list[Track], timelines: list[Timeline],
        timing: TimingModel | Sequence[TimingModel] | None = None) -> list[Track]:
    """Tie each robot's lag after a zone wait to the robot it waited for (module docstring).

    Waits are taken in the order they end; each release sets the waiting robot's lag from then
    on (until its next release) to the holder's lag at the release plus the restart, or keeps
    its own (less the planned wait) when that is the later.

    Parameters
    ----------
    tracks : list of Track
        The fleet's tracks (:meth:`Track.of`), in robot order.
    timelines : list of Timeline
        Their timelines (with :attr:`~planner.fleet.zones.Timeline.holder`).
    timing : TimingModel or sequence of TimingModel, optional
        One model for every robot, or each robot's own; default each track's own
        (:attr:`Track.timing`).

    Returns
    -------
    list of Track
    """
    root = [tr.root.copy() for tr in tracks]
    root_t = [tr.root_t.copy() for tr in tracks]
    parent = [np.full(len(tr.t), -1) for tr in tracks]
    parent_t, p_mean, p_var = ([np.zeros(len(tr.t)) for tr in tracks] for _ in range(3))
    xm = [tr.x_mean.copy() for tr in tracks]
    xv = [tr.x_var.copy() for tr in tracks]
    events = sorted((tracks[j].t[b], j, a, b, h) for j, tl in enumerate(timelines)
                    for a, b, h in _waits(tl, tracks[j].t) if 0 <= h < len(tracks) and h != j)

    def mean_at(j, k):
        r = root[j][k] if root[j][k] >= 0 else j
        own = model_of(timing, tracks, r).mean(np.interp(root_t[j][k], tracks[r].t, tracks[r].drive))
        return float(own) + xm[j][k]

    for t_rel, j, a, b, h in events:
        tj, mj = tracks[j], model_of(timing, tracks, j)
        before = max(a - 1, 0)
        waited = float(tj.t[b] - tj.t[a])
        kh = int(tracks[h].sample(t_rel))
        tied_mean = mean_at(h, kh) + mj.release_lag
        if mean_at(j, before) - waited >= tied_mean:
            # arrived after the holder had gone: it did not stop, and the plan's wait is lag made up
            xm[j][b:] -= waited
            continue
        r = root[h][kh]
        new_root, new_t = (h, t_rel) if r < 0 else (int(r), float(root_t[h][kh]))
        base_m, base_v = xm[h][kh] + mj.release_lag, xv[h][kh] + mj.release_var
        # tied from the release on; with a timing spread from the wait's start (TimingModel.tie_wait)
        c = a if mj.tie_wait else b
        since = tj.drive[c:] - tj.drive[b]
        root[j][c:], root_t[j][c:] = new_root, new_t
        # its own drift since the release: the speed factor's and the dwells' parts as they grow
        # from there (taken independent of the holder's lag)
        at_b = tj.drive[b]
        passed = mj.dwells(tj.drive[c:]) - mj.dwells(at_b)
        xm[j][c:] = base_m + mj.lag_rate * since + mj.dwell_mean * passed
        xv[j][c:] = base_v + mj.var_rate * since + mj.var_quad * since * since \
            + mj.dwell_var * passed
        if mj.tie_wait:
            parent[j][c:], parent_t[j][c:] = h, t_rel
            p_mean[j][c:] = xm[j][c:] - xm[h][kh]
            p_var[j][c:] = xv[j][c:] - xv[h][kh]
    out = [replace(tr, root=root[j], root_t=root_t[j], x_mean=xm[j], x_var=xv[j]) for j, tr in enumerate(tracks)]
    if any(model_of(timing, tracks, j).tie_wait for j in range(len(tracks))):
        out = [replace(tr, parent=parent[j], parent_t=parent_t[j], p_mean=p_mean[j], p_var=p_var[j])
               for j, tr in enumerate(out)]
    return out


def lag_difference(tracks: list[Track], i: int, j: int, t: np.ndarray,
                   timing: TimingModel | Sequence[TimingModel] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Mean [s] and variance [s^2] of ``delta_i - delta_j`` at planned time(s) ``t``.

    Each lag is its root's own lag plus an independent part (:class:`Track`); two lags with one
    root share that root's own lag up to the earlier of their times, whose variance cancels.
    (Parts of X shared through a robot between them are taken as independent: more spread.)
    With a declared timing spread (:attr:`Track.parent`), a robot that waited for the other is
    the other's lag at the release plus its restart and drift since, less the other's drift from
    the release to ``t``: the two lags are not taken as independent there.
    """
    t = np.asarray(t, float).reshape(-1)
    parts = []
    for r in (i, j):
        tr = tracks[r]
        k = tr.sample(t)
        root = np.where(tr.root[k] >= 0, tr.root[k], r)
        when = tr.root_t[k]
        drive, mean, var = np.empty(len(t)), np.empty(len(t)), np.empty(len(t))
        for q in np.unique(root):
            sel = root == q
            drive[sel] = np.interp(when[sel], tracks[q].t, tracks[q].drive)
            mean[sel] = model_of(timing, tracks, q).mean(drive[sel])
            var[sel] = model_of(timing, tracks, q).var(drive[sel])
        parts.append((root, drive, mean + tr.x_mean[k], var + tr.x_var[k]))
    (ri, di, mi, vi), (rj, dj, mj, vj) = parts
    shared = np.zeros(len(t))
    for q in np.unique(ri[ri == rj]):
        sel = (ri == q) & (rj == q)
        shared[sel] = model_of(timing, tracks, q).cov(di[sel], dj[sel])
    mean, var = mi - mj, np.maximum(vi + vj - 2.0 * shared, 0.0)
    # a robot that waited for the other: its lag is the other's at the release plus its restart and
    # drift since, and the other's lag at t is that at the release plus its own drift in between
    for a, b, sign in ((j, i, -1.0), (i, j, 1.0)):
        ta, tb = tracks[a], tracks[b]
        if ta.parent is None:
            continue
        k = ta.sample(t)
        sel = ta.parent[k] == b
        if not sel.any():
            continue
        ks = k[sel]
        g_m, g_v = model_of(timing, tracks, b).drift(np.interp(ta.parent_t[ks], tb.t, tb.drive),
                                                     np.interp(t[sel], tb.t, tb.drive))
        # delta_a - delta_b = p + delta_b(release) - delta_b(t) = p - drift of b from the release to t
        mean[sel] = sign * (ta.p_mean[ks] - g_m)
        var[sel] = ta.p_var[ks] + g_v
    return mean, var


def low_segment(origin: np.ndarray, h_origin: float | np.ndarray, target: np.ndarray, h_target: np.ndarray,
                top: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Project onto the floor the part of each ray at most ``top`` high.

    Parameters
    ----------
    origin : ndarray, shape (Q, 2)
        Laser positions [m] (at height ``h_origin``).
    h_origin : float or ndarray, shape (Q,)
        Laser heights [m].
    target : ndarray, shape (Q, 2)
        Reflector positions [m].
    h_target : ndarray, shape (Q,)
        Reflector centre heights [m]; NaN: above every robot (no low part).
    top : float
        Height of the blocking body [m].

    Returns
    -------
    a, b : ndarray, shape (Q, 2)
        Ends of the low part's projection [m].
    some : ndarray of bool, shape (Q,)
        The ray has a low part.
    """
    origin, target = np.asarray(origin, float).reshape(-1, 2), np.asarray(target, float).reshape(-1, 2)
    h0 = np.broadcast_to(np.asarray(h_origin, float), (len(origin),))
    h1 = np.asarray(h_target, float).reshape(-1)
    dh = h1 - h0
    level = np.abs(dh) <= _LEVEL * np.maximum(np.abs(h1), 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        u_top = np.where(level, np.nan, (top - h0) / np.where(level, 1.0, dh))
    rising = dh > 0
    lo = np.where(level, 0.0, np.where(rising, 0.0, np.clip(u_top, 0.0, 1.0)))
    hi = np.where(level, 1.0, np.where(rising, np.clip(u_top, 0.0, 1.0), 1.0))
    some = np.where(level, h0 <= top, np.where(rising, u_top >= 0.0, u_top <= 1.0)) & np.isfinite(h1)
    d = target - origin
    return origin + lo[:, None] * d, origin + hi[:, None] * d, some & (hi >= lo)


def _distance(xy: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(Q, T): distance from point ``xy[t]`` to segment ``a[q] b[q]`` [m]."""
    d = b - a                                                   # (Q, 2)
    L2 = np.einsum("qi,qi->q", d, d)
    w = xy[None, :, :] - a[:, None, :]                          # (Q, T, 2)
    u = np.clip(np.einsum("qti,qi->qt", w, d) / np.where(L2 > 0, L2, 1.0)[:, None], 0.0, 1.0)
    e = w - u[..., None] * d[:, None, :]
    return np.sqrt(np.einsum("qti,qti->qt", e, e))


def block_probability(other: Track, origin: np.ndarray, h_origin: float, target: np.ndarray,
                      h_target: np.ndarray, when: np.ndarray, shift_mean: np.ndarray, shift_var: np.ndarray,
                      group: np.ndarray | None = None, chunk: int = 256) -> np.ndarray:
    """Probability that robot ``other``'s body is on each ray at the time it is measured.

    Parameters
    ----------
    other : Track
        The robot that may block.
    origin : ndarray, shape (Q, 2)
        Where the measuring robot's laser is [m].
    h_origin : float
        Its height [m].
    target : ndarray, shape (Q, 2)
        The reflector of each ray [m].
    h_target : ndarray, shape (Q,)
        Reflector heights [m] (NaN: above every robot, never blocked).
    when : ndarray, shape (Q,)
        Planned time of each measurement [s].
    shift_mean, shift_var : ndarray, shape (Q,)
        Mean [s] and variance [s^2] of the measuring robot's lag less the other's at ``when``
        (:func:`lag_difference`): the other is where its plan has it at ``when + shift``.
    group : ndarray of int, shape (Q,), optional
        Rays measured together (one fix's): the probability is then per group (0 .. G-1) that
        the body hides at least one of its rays, each group's times and lags taken from its
        first ray.
    chunk : int
        Rays per vectorised pass (memory: chunk x T booleans).

    Returns
    -------
    ndarray, shape (Q,), or (G,) with ``group``
    """
    when = np.asarray(when, float).reshape(-1)
    q_n = len(when)
    gid = np.arange(q_n) if group is None else np.asarray(group, np.int64).reshape(q_n)
    n_out = int(gid.max(initial=-1)) + 1
    out = np.zeros(n_out)
    a, b, some = low_segment(origin, h_origin, target, h_target, other.height)
    mu = np.broadcast_to(np.asarray(shift_mean, float), (q_n,))      # mean of delta_i - delta_j
    sd = np.sqrt(np.maximum(np.broadcast_to(np.asarray(shift_var, float), (q_n,)), 1e-12))
    # cells of the other's samples: sample k stands for planned times [edge_k, edge_k+1), the first
    # and last reaching to -inf and +inf (standing on its docks before and after)
    t = other.t
    edges = np.concatenate([[-np.inf], 0.5 * (t[1:] + t[:-1]), [np.inf]])
    first = np.full(n_out, q_n, dtype=np.int64)
    np.minimum.at(first, gid, np.arange(q_n))
    # rays in time order, so that a chunk's rays need the other's samples of a short window only:
    # beyond WINDOW_SD standard deviations of a measurement its mass is below 1e-15
    rows = np.flatnonzero(some)
    rows = rows[np.argsort(when[rows], kind="stable")]
    reach_lo, reach_hi = when + mu - WINDOW_SD * sd, when + mu + WINDOW_SD * sd
    pairs, cover = [], []
    for lo in range(0, len(rows), chunk):
        q = rows[lo:lo + chunk]
        k0 = max(int(np.searchsorted(edges, reach_lo[q].min(), side="right")) - 1, 0)
        k1 = min(int(np.searchsorted(edges, reach_hi[q].max(), side="left")), len(t))
        if k1 <= k0:
            continue
        # rays whose low part (widened by the radius and the position spread) misses the box of
        # the window's samples: none
        reach = other.radius + POS_REACH * POS_SD   # (POS_SD is the largest spread of a sample)
        box_lo, box_hi = other.xy[k0:k1].min(axis=0) - reach, other.xy[k0:k1].max(axis=0) + reach
        near = np.all((np.minimum(a[q], b[q]) <= box_hi) & (np.maximum(a[q], b[q]) >= box_lo), axis=1)
        q = q[near]
        if len(q) == 0:
            continue
        dist = _distance(other.xy[k0:k1], a[q], b[q])
        qi, ki = np.nonzero(dist <= reach)
        pairs.append(gid[q[qi]] * len(t) + ki + k0)
        # the body covers the ray with the probability its centre, spread by POS_SD across the
        # edge of the blocking region, is inside: Phi((r - d) / POS_SD)
        spread = POS_SD if other.pos_sd is None else other.pos_sd[ki + k0]
        cover.append(ndtr((other.radius - dist[qi, ki]) / spread))
    key, cov = (np.concatenate(pairs), np.concatenate(cover)) if pairs else (np.zeros(0, np.int64), np.zeros(0))
    if not len(key):   # windows near some rays, but no sample within reach of one
        return out
    # a sample near several rays of one group counts once, with its largest cover (one position)
    order = np.lexsort((-cov, key))
    key, cov = key[order], cov[order]
    head = np.concatenate([[True], key[1:] != key[:-1]])
    key, cov = key[head], cov[head]
    g, k = np.divmod(key, len(t))
    r = first[g]
    z_hi = (edges[k + 1] - when[r] - mu[r]) / sd[r]
    z_lo = (edges[k] - when[r] - mu[r]) / sd[r]
    out += np.bincount(g, weights=cov * (ndtr(z_hi) - ndtr(z_lo)), minlength=n_out)
    return np.clip(out, 0.0, 1.0)


def traffic_probability(segment_density: np.ndarray, h_target: np.ndarray, tops: float,
                        traffic_block: float = TRAFFIC_BLOCK) -> np.ndarray:
    """Blocking probability of rays by traffic that is not simulated.

    Parameters
    ----------
    segment_density : ndarray, shape (Q,)
        ``routes.traffic`` density of the segment each ray's fix is taken on (0 off the network).
    h_target : ndarray, shape (Q,)
        Reflector heights [m] (NaN: above everything, never blocked).
    tops : float
        The tallest robot's height [m]: traffic is taken to be no taller.
    traffic_block : float
        Blocking probability per unit density.

    Returns
    -------
    ndarray, shape (Q,)
    """
    h = np.asarray(h_target, float)
    low = np.isfinite(h) & (h < tops)
    return np.where(low, np.clip(traffic_block * np.asarray(segment_density, float), 0.0, 1.0), 0.0)


def combine(p: np.ndarray, axis: int = 0) -> np.ndarray:
    """Probability that at least one of independent events of probabilities ``p`` happens, along ``axis``."""
    return 1.0 - np.prod(1.0 - np.clip(np.asarray(p, float), 0.0, 1.0), axis=axis)
