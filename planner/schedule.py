"""The measurement schedule: where along a path to take fixes, and with which markers.

Between fixes the robot dead-reckons, so the predicted position error at arc length ``s`` is
the error of the last *completed* fix plus the drift since that fix started::

    err(s) = tau_i + drift_bound(s - s_i, turned(s_i -> s))   for s in (c_i, c_{i+1}]

where fix ``i`` starts at ``s_i`` and completes at ``c_i`` (it measures its ``k`` markers one
after another, ``k * measurement_time`` seconds, while the robot moves on), and ``tau_i`` is the
PEF error of its marker subset, the largest over the stretch ``[s_i, c_i]`` the fix is taken
over. Fix starts are at least ``max(1 / fix_rate_hz, k * measurement_time)`` seconds apart.
The first fix is taken at standstill at the start of the path (before departure).

Schedule choice (:func:`make_schedule`)
    The path is sampled at a fine spacing; every sample is a candidate fix start. A backward
    pass marks the samples from which the rest of the path can be completed (using the best
    subset's ``tau`` at every sample, which is what reaches farthest), so the forward pass
    never walks into a dead end: it is complete on the sampled path (finds a schedule whenever
    one exists with fixes starting at samples). Forward policy ``"often"`` (default) starts
    each fix as early as the rate allows among the completable samples (lowest error);
    ``"sparse"`` as late as the drift allows (fewest fixes).
    Subset policy: keep the previous fix's subset while its ``tau`` over the new stretch is
    within ``(1 + switch_tolerance)`` of the best subset's and the rest stays completable;
    otherwise take the best subset. ``switch`` marks the fixes whose subset differs from the
    previous fix's: the points where the robot must change the markers it measures.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import combinations

import numpy as np

from planner.drift import DEFAULT_INCREMENT, K_SIGMA, drift_bound
from planner.pathtime import Track, sample_track
from scenarios.errors import PlanningError
from scenarios.schema import Scenario

MAX_SUBSETS = 400
"""Above this many k-subsets of path-visible markers, only the PEF's pointwise-best subsets
along the path are considered (cost: one ``tau_subset`` call per subset)."""


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
        Predicted fix error: the PEF error of this subset, largest over the stretch the fix is
        taken over [m].
    switch : bool
        The subset differs from the previous fix's (always False for the first fix).
    """

    s: float
    position: tuple[float, float]
    markers: tuple[int, ...]
    tau: float
    switch: bool


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
    """

    fixes: tuple[ScheduledFix, ...]
    s: np.ndarray
    predicted_error: np.ndarray
    worst: float


def _candidate_subsets(pef, xy: np.ndarray, k: int) -> list[tuple[int, ...]]:
    vis = np.asarray(pef.visible(xy), dtype=bool)
    seen = np.flatnonzero(vis.any(axis=0))
    if math.comb(len(seen), k) <= MAX_SUBSETS:
        # only subsets seen together from some sample can ever be used
        return [tuple(int(m) for m in c) for c in combinations(seen, k) if vis[:, list(c)].all(axis=1).any()]
    best = np.asarray(pef.at(xy).best)
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


class _Planner:
    """Windows of feasible next fixes on a sampled track (see module doc)."""

    def __init__(self, tr: Track, drift, eps: float, gap: float):
        self.tr, self.drift, self.eps = tr, drift, eps
        n = len(tr.s)
        # earliest next start allowed by the sensor rate, strictly after the sample
        self.l_min = np.maximum(np.searchsorted(tr.t, tr.t_start + gap * (1 - 1e-9), side="left"),
                                np.arange(n) + 1)

    def err_at_completion(self, j, tau, nxt):
        """Error of fix (j, tau) just before a fix started at sample ``nxt`` completes [m]."""
        tr = self.tr
        return tau + self.drift(tr.c[nxt] - tr.s[j], tr.turn_in[tr.c_idx[nxt]] - tr.turn_ex[j])

    def err_at_end(self, j, tau):
        tr = self.tr
        return tau + self.drift(tr.s[-1] - tr.s[j], tr.turn_in[-1] - tr.turn_ex[j])

    def err_at_sample(self, j, tau, i):
        """Error of fix (j, tau) at sample i >= j [m]."""
        tr = self.tr
        return tau + self.drift(tr.s[i] - tr.s[j], tr.turn_in[i] - tr.turn_ex[j])

    def _last_ok(self, j, tau, err) -> np.ndarray:
        """Largest index i in (j, n) with err(j, tau, i) < eps (monotone in i), else j."""
        n = len(self.tr.s)
        j = np.asarray(j, dtype=int)
        lo, hi = j.copy(), np.full(j.shape, n, dtype=int)
        # invariant: the predicate holds at lo (vacuously at lo = j) and fails at hi
        while np.any(hi - lo > 1):
            mid = (lo + hi) // 2
            ok = (mid < n) & (err(j, tau, np.minimum(mid, n - 1)) < self.eps)
            lo = np.where(ok, mid, lo)
            hi = np.where(ok, hi, mid)
        return lo

    def l_max(self, j: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """Last sample l whose fix completes while fix (j, tau) is still under eps (j if none)."""
        return self._last_ok(j, tau, self.err_at_completion)

    def l_max_one(self, j: int, tau: float) -> int:
        """:meth:`l_max` for one fix, by windows (cheaper than a scalar binary search)."""
        n, width = len(self.tr.s), 64
        while True:
            ls = np.arange(j + 1, min(n, j + 1 + width))
            if len(ls) == 0:
                return j
            over = np.flatnonzero(self.err_at_completion(j, tau, ls) >= self.eps)
            if len(over):
                return int(ls[over[0]] - 1)
            if ls[-1] == n - 1:
                return n - 1
            width *= 4

    def fail_idx(self, j: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """First sample at or after j where fix (j, tau) alone reaches eps (n if never)."""
        j = np.asarray(j, dtype=int)
        first_ok = self.err_at_sample(j, tau, j) < self.eps
        return np.where(first_ok, self._last_ok(j, tau, self.err_at_sample) + 1, j)


def _diagnose(pl: _Planner, tau_best: np.ndarray, k: int) -> PlanningError:
    """Name the worst stretch of the best (farthest-reaching) schedule in a PlanningError."""
    tr, eps, n = pl.tr, pl.eps, len(pl.tr.s)
    good = np.isfinite(tau_best) & (tau_best < eps)
    lmax = pl.l_max(np.arange(n), np.where(good, tau_best, eps))
    reach = np.zeros(n, dtype=bool)
    reach[0] = good[0]
    frontier = np.zeros(n + 1, dtype=int)  # difference array of reachable windows
    active = 0
    for j in range(n):
        active += frontier[j]
        if j > 0:
            reach[j] = active > 0 and good[j]
        if reach[j] and pl.l_min[j] <= lmax[j]:
            frontier[pl.l_min[j]] += 1
            frontier[lmax[j] + 1] -= 1
    best_j, best_fail = 0, 0
    rj = np.flatnonzero(reach)
    if len(rj):
        fails = pl.fail_idx(rj, tau_best[rj])
        best_j, best_fail = int(rj[np.argmax(fails)]), int(fails.max())
    a = min(best_fail, n - 1)
    later_good = np.flatnonzero(good[a:])
    b = a + int(later_good[0]) if len(later_good) else n - 1
    b = max(b, int(tr.c_idx[min(pl.l_min[best_j], n - 1)]))
    stretch_tau = float(np.min(tau_best[a:b + 1]))
    if reach[best_j]:
        err = float(tau_best[best_j] + pl.drift(tr.s[b] - tr.s[best_j], tr.turn_in[b] - tr.turn_ex[best_j]))
        last = f"last usable fix at s = {tr.s[best_j]:.2f} m with tau {tau_best[best_j]:.4g} m"
    else:
        err = float(tau_best[0])
        last = "no usable fix at the start"
    tau_txt = (f"{stretch_tau:.4g} m" if np.isfinite(stretch_tau)
               else f"inf (fewer than {k} markers visible)")
    x, y = tr.xy[a]
    return PlanningError(
        f"no measurement schedule keeps the error under eps_max = {eps:.4g} m: from s = "
        f"{tr.s[a]:.2f} m ({x:.2f}, {y:.2f}) to s = {tr.s[b]:.2f} m the predicted error reaches "
        f"{err:.4g} m ({last}; best fix tau in the stretch {tau_txt})")


def make_schedule(scenario: Scenario, pef, path: np.ndarray, speed: np.ndarray | None = None, *,
                  spacing: float | None = None, policy: str = "often",
                  switch_tolerance: float = 0.2, k_sigma: float = K_SIGMA,
                  heading_error: float = 0.0, increment: float | None = DEFAULT_INCREMENT) -> Schedule:
    """Choose fixes along ``path`` so that the predicted error stays under ``eps_max``.

    Parameters
    ----------
    scenario : Scenario
        Uses ``sensor`` (fix rate, measurement time, k), ``robot`` (drift, max speed) and
        ``planning.eps_max``.
    pef : planner.pef.PEF
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
        Passed to :func:`planner.drift.drift_bound`.

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
    sensor, robot, eps = scenario.sensor, scenario.robot, scenario.planning.eps_max
    k = int(getattr(pef, "k", None) or sensor.markers_per_fix)
    v = (np.full(len(path), robot.max_speed) if speed is None
         else np.asarray(speed, dtype=float).reshape(-1))
    if v.shape != (len(path),) or np.any(v < 0) or not np.all(np.isfinite(v)):
        raise PlanningError(f"schedule: expected {len(path)} finite speeds >= 0, got shape {v.shape}")
    fix_time = k * sensor.measurement_time
    gap = max(1.0 / sensor.fix_rate_hz, fix_time)
    if spacing is None:
        spacing = min(scenario.planning.resolution, 0.25 * max(v.max(), 1e-9) * gap)
    if spacing <= 0:
        raise PlanningError(f"schedule: spacing must be > 0, got {spacing}")

    tr = sample_track(path, v, spacing, fix_time, gap)
    n = len(tr.s)
    subsets = _candidate_subsets(pef, tr.xy, k)
    if not subsets:
        tau = np.full((1, 2 * n), np.inf)
        subsets = [tuple(range(k))]
    else:
        # tau at the samples and at the exact completion points of fixes started there
        both = np.vstack([tr.xy, tr.xy_c])
        tau = np.stack([np.asarray(pef.tau_subset(both, np.asarray(c)), dtype=float) for c in subsets])
    tau_s = _stretch_tau(tau[:, :n], tau[:, n:], tr.c_idx)
    best_c = np.argmin(tau_s, axis=0)
    tau_best = tau_s[best_c, np.arange(n)]

    def drift(d, turned):
        return drift_bound(robot, d, turned, k_sigma, heading_error, increment)

    pl = _Planner(tr, drift, eps, gap)
    usable = np.isfinite(tau_best) & (tau_best < eps)
    tau_use = np.where(usable, tau_best, eps)
    done = usable & (pl.err_at_end(np.arange(n), tau_use) < eps)
    lmax = pl.l_max(np.arange(n), tau_use)
    # backward pass: ok[j] = the rest of the path can be completed from a fix started at j
    ok = np.zeros(n, dtype=bool)
    suffix = np.zeros(n + 1, dtype=int)  # suffix[l] = count of ok in [l, n)
    for j in range(n - 1, -1, -1):
        lo, hi = pl.l_min[j], lmax[j]
        ok[j] = usable[j] and (done[j] or (lo <= hi and suffix[lo] - suffix[hi + 1] > 0))
        suffix[j] = suffix[j + 1] + ok[j]
    if not ok[0]:
        raise _diagnose(pl, np.where(usable, tau_best, np.inf), k)

    def completable(j: int, t: float) -> bool:
        if pl.err_at_end(j, t) < eps:
            return True
        lo, hi = pl.l_min[j], pl.l_max_one(j, t)
        return lo <= hi and suffix[lo] - suffix[hi + 1] > 0

    chosen = [(0, int(best_c[0]), float(tau_best[0]))]
    while True:
        j, c_prev, t_prev = chosen[-1]
        lo, hi = pl.l_min[j], pl.l_max_one(j, t_prev)
        cand = np.flatnonzero(ok[lo:hi + 1]) + lo if lo <= hi else np.array([], dtype=int)
        if len(cand) == 0:
            break  # the current fix covers the rest (guaranteed by ok[j])
        if policy == "sparse" and pl.err_at_end(j, t_prev) < eps:
            break
        nxt = int(cand[0] if policy == "often" else cand[-1])
        t_keep = float(tau_s[c_prev, nxt])
        if (np.isfinite(t_keep) and t_keep < eps and t_keep <= tau_best[nxt] * (1.0 + switch_tolerance)
                and completable(nxt, t_keep)):
            chosen.append((nxt, c_prev, t_keep))
        else:
            chosen.append((nxt, int(best_c[nxt]), float(tau_best[nxt])))

    fixes = tuple(
        ScheduledFix(s=float(tr.s[j]), position=(float(tr.xy[j, 0]), float(tr.xy[j, 1])),
                     markers=subsets[c], tau=t, switch=i > 0 and c != chosen[i - 1][1])
        for i, (j, c, t) in enumerate(chosen))
    starts = np.array([j for j, _, _ in chosen])
    taus = np.array([t for _, _, t in chosen])
    completes = tr.c[starts]
    active = np.maximum(np.searchsorted(completes, tr.s, side="left") - 1, 0)
    fj = starts[active]
    err = taus[active] + drift(tr.s - tr.s[fj], tr.turn_in - tr.turn_ex[fj])
    # just before each later fix completes, the previous fix still holds
    handover = [pl.err_at_completion(starts[i], taus[i], starts[i + 1]) for i in range(len(starts) - 1)]
    worst = float(max([err.max(), *handover]))
    return Schedule(fixes=fixes, s=tr.s[tr.vertex_idx].copy(),
                    predicted_error=err[tr.vertex_idx].copy(), worst=worst)
