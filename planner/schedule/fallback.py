"""Fallback subsets: what each fix measures instead when one of its markers is blocked.

For the marker in slot q of a fix's subset, the fallback is the candidate subset without that
marker whose static PEF over the fix's stretch is lowest (the best subset without it, as in
:attr:`planner.pef.result.PefResult.fallback`); its promise is the bound on the moving fix's fault
area of that subset at the same start and speed (:func:`planner.schedule.promise.predict`). A fix whose
marker has no fallback (no other visible subset, or none whose promise passes the test of a
scheduled fix) names an empty one: with that marker blocked the robot improvises with the best
visible subset (beyond what the plan promises) or, with fewer than k visible, dead-reckons on.

A fallback passes the test of a scheduled fix: its promise is under ``eps_max / (1 +
POLYGON_TOLERANCE)``, and its promise plus the drift until the next fix completes (``margin``;
the fallback's area stays in force that long) is under ``eps_max``. Without the second part a
fallback could promise 29 mm and leave the robot at 33 mm before the next fix (``warehouse-
reflectors``, 19 of 405 fallbacks): the plan's redundancy would not hold for a moving robot.
Where the best subset by static PEF fails the test, the next :data:`CANDIDATES` - 1 are tried.
"""

from __future__ import annotations

import math

import numpy as np

from planner.schedule import promise
from scenarios.schema import Scenario

CANDIDATES = 4
"""Subsets tried per blocked marker, in order of static PEF, before it is left without a fallback."""


def fallbacks(scenario: Scenario, path: np.ndarray, speed: np.ndarray, starts: np.ndarray,
              orders: list[tuple[int, ...]], subsets: list[tuple[int, ...]], tau_s: np.ndarray,
              start_idx: np.ndarray, margin: np.ndarray | None = None, estimate=None,
              ) -> tuple[list[tuple[tuple[int, ...], ...]], list[tuple[float, ...]]]:
    """Fallback subset and its promise for every marker of every fix.

    Parameters
    ----------
    scenario : Scenario
    path : ndarray, shape (N, 2)
        Path vertices [m].
    speed : ndarray, shape (N,)
        Final vertex speeds [m/s].
    starts : ndarray, shape (F,)
        Arc length of each fix's start [m].
    orders : list of tuple of int, length F
        Each fix's markers in measurement order.
    subsets : list of tuple of int, length C
        The candidate subsets.
    tau_s : ndarray, shape (C, n)
        Static PEF of each candidate over the stretch of a fix started at each sample [m].
    start_idx : ndarray of int, shape (F,)
        Sample index of each fix's start.
    margin : ndarray, shape (F,), optional
        Drift bound from each fix's start until the next fix completes (the end of the path
        for the last) [m]; None: 0.
    estimate : float or ndarray, shape (F,), optional
        Bound on the estimate's error while each fix is taken [m], as for the fix itself
        (:func:`planner.schedule.promise.predict`); None: ``eps_max``.

    Returns
    -------
    subs : list (F) of tuple (k) of tuple of int
        ``subs[i][q]``: what fix i measures when ``orders[i][q]`` is blocked; () if nothing.
    taus : list (F) of tuple (k) of float
        The promise of each fallback [m]; inf where there is none.
    """
    k = len(orders[0]) if orders else 0
    n_fix = len(orders)
    margin = np.zeros(n_fix) if margin is None else np.asarray(margin, dtype=float).reshape(n_fix)
    eps = scenario.planning.eps_max
    limit = eps / (1.0 + promise.POLYGON_TOLERANCE)
    est = np.broadcast_to(np.asarray(eps if estimate is None else estimate, dtype=float), (n_fix,))
    subs = [[() for _ in range(k)] for _ in orders]
    taus = [[math.inf] * k for _ in orders]
    if not orders:
        return [], []
    # per fix and slot: candidates without the slot's marker in order of static PEF over the
    # fix's stretch (finite only; NaN never wins), best first
    sub_arr = np.asarray(subsets, dtype=np.int64).reshape(len(subsets), -1)       # (C, k)
    cols = np.asarray(tau_s, dtype=float)[:, np.asarray(start_idx, dtype=np.int64)].T  # (F, C)
    cols = np.where(np.isnan(cols), np.inf, cols)
    marks = np.asarray(orders, dtype=np.int64)                                     # (F, k)
    rank = []
    for q in range(k):
        holds = (sub_arr[None, :, :] == marks[:, q, None, None]).any(axis=2)        # (F, C)
        masked = np.where(holds, np.inf, cols)
        m = min(CANDIDATES, masked.shape[1])
        top = np.argsort(masked, axis=1, kind="stable")[:, :m]
        rank.append((top, np.take_along_axis(masked, top, axis=1) < math.inf))
    # the best candidate first; the next ones only for the slots it leaves without a fallback
    pending = [(i, q) for q in range(k) for i in range(n_fix)]
    for r in range(CANDIDATES):
        tries = [(i, q) for i, q in pending if r < rank[q][0].shape[1] and rank[q][1][i, r]]
        if not tries:
            break
        cand = [tuple(int(x) for x in subsets[rank[q][0][i, r]]) for i, q in tries]
        rows = [i for i, _ in tries]
        pred, _, _ = promise.predict(scenario, path, speed, np.asarray(starts, float)[rows], cand, est[rows])
        pending = []
        for (i, q), sub, p in zip(tries, cand, pred, strict=True):
            if p < limit and p + margin[i] < eps:
                subs[i][q], taus[i][q] = sub, float(p)
            else:
                pending.append((i, q))
    return [tuple(s) for s in subs], [tuple(t) for t in taus]
