"""The schedule's search: windows of feasible next fixes and the forward choice.

:func:`search` chooses fix starts and subsets on a sampled track given every candidate fix's
error (one speed level per sample, :mod:`planner.schedule.promise`); the policy is described in
:mod:`planner.schedule.schedule`.
"""

from __future__ import annotations

import numpy as np

from planner.schedule.pathtime import Track
from scenarios.errors import PlanningError


class StretchError(PlanningError):
    """No schedule keeps the error under eps_max; ``stretch`` = (s_from, s_to) [m] is where.

    The schedule slows this stretch (and those in ``more``) down and tries again
    (:func:`planner.schedule.schedule.make_schedule`).
    """

    def __init__(self, message: str, stretch: tuple[float, float], more: tuple[tuple[float, float], ...] = ()):
        super().__init__(message)
        self.stretch = stretch
        self.more = more


class Windows:
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


def diagnose(pl: Windows, tau_best: np.ndarray, k: int) -> StretchError:
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
    return StretchError(
        f"no measurement schedule keeps the error under eps_max = {eps:.4g} m: from s = "
        f"{tr.s[a]:.2f} m ({x:.2f}, {y:.2f}) to s = {tr.s[b]:.2f} m the predicted error reaches "
        f"{err:.4g} m ({last}; best fix tau in the stretch {tau_txt})",
        (float(tr.s[best_j]) if reach[best_j] else 0.0, float(tr.s[b])))



def search(pl: Windows, taus: np.ndarray, limit: float, k: int, policy: str,
           switch_tolerance: float) -> tuple[list[tuple[int, int, float]], np.ndarray]:
    """Choose the fixes (module docstring of :mod:`planner.schedule.schedule`).

    Parameters
    ----------
    pl : Windows
        The sampled track's windows (drift against ``eps_max``).
    taus : ndarray, shape (L, C, n)
        Error of a fix of subset c started at sample j at speed level l [m] (inf: not possible).
    limit : float
        A fix is usable when its error is under this [m].
    k : int
        Markers per fix (for the diagnosis).
    policy : {"often", "sparse"}
    switch_tolerance : float
        Keep the previous subset while its error is within this fraction of the best's.

    Returns
    -------
    chosen : list of (sample, subset, tau)
        The fixes in path order.
    level : ndarray, shape (n,), int
        Speed level used at each sample: the fastest with a usable subset.

    Raises
    ------
    PlanningError
        If no schedule keeps the error under eps_max (names the worst stretch).
    """
    n = taus.shape[2]
    usable_at = taus.min(axis=1) < limit                       # (L, n)
    level = np.where(usable_at.any(axis=0), np.argmax(usable_at, axis=0), 0)
    tau_s = taus[level, :, np.arange(n)].T                     # (C, n)
    best_c = np.argmin(tau_s, axis=0)
    tau_best = tau_s[best_c, np.arange(n)]
    usable = np.isfinite(tau_best) & (tau_best < limit)
    tau_use = np.where(usable, tau_best, limit)
    done = usable & (pl.err_at_end(np.arange(n), tau_use) < pl.eps)
    lmax = pl.l_max(np.arange(n), tau_use)
    # backward pass: ok[j] = the rest of the path can be completed from a fix started at j
    ok = np.zeros(n, dtype=bool)
    suffix = np.zeros(n + 1, dtype=int)  # suffix[l] = count of ok in [l, n)
    for j in range(n - 1, -1, -1):
        lo, hi = pl.l_min[j], lmax[j]
        ok[j] = usable[j] and (done[j] or (lo <= hi and suffix[lo] - suffix[hi + 1] > 0))
        suffix[j] = suffix[j + 1] + ok[j]
    if not ok[0]:
        raise diagnose(pl, np.where(usable, tau_best, np.inf), k)

    def completable(j: int, t: float) -> bool:
        if pl.err_at_end(j, t) < pl.eps:
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
        if policy == "sparse" and pl.err_at_end(j, t_prev) < pl.eps:
            break
        # a fix at the planned speed wherever the window has one: slow-downs cost time
        cand = cand[level[cand] == level[cand].min()]
        nxt = int(cand[0] if policy == "often" else cand[-1])
        t_keep = float(tau_s[c_prev, nxt])
        if (np.isfinite(t_keep) and t_keep < limit and t_keep <= tau_best[nxt] * (1.0 + switch_tolerance)
                and completable(nxt, t_keep)):
            chosen.append((nxt, c_prev, t_keep))
        else:
            chosen.append((nxt, int(best_c[nxt]), float(tau_best[nxt])))
    return chosen, level
