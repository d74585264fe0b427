"""Fallback subsets: what each fix measures instead when one of its markers is blocked.

For the marker in slot q of a fix's subset, the fallback is the candidate subset without that
marker whose static PEF over the fix's stretch is lowest (the best subset without it, as in
:attr:`planner.pef.map.PefResult.fallback`); its promise is the moving fix's fault area of that
subset at the same start and speed (:func:`planner.schedule.promise.predict`). A fix whose
marker has no fallback (no other visible subset, or none whose promise is under
``eps_max / (1 + PROMISE_TOLERANCE)``, the limit of a scheduled fix) names an empty one: with that
marker blocked the robot improvises with the best visible subset (beyond what the plan
promises) or, with fewer than k visible, dead-reckons on.
"""

from __future__ import annotations

import math

import numpy as np

from planner.schedule import promise
from scenarios.schema import Scenario


def fallbacks(scenario: Scenario, path: np.ndarray, speed: np.ndarray, starts: np.ndarray,
              orders: list[tuple[int, ...]], subsets: list[tuple[int, ...]], tau_s: np.ndarray,
              start_idx: np.ndarray) -> tuple[list[tuple[tuple[int, ...], ...]], list[tuple[float, ...]]]:
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

    Returns
    -------
    subs : list (F) of tuple (k) of tuple of int
        ``subs[i][q]``: what fix i measures when ``orders[i][q]`` is blocked; () if nothing.
    taus : list (F) of tuple (k) of float
        The promise of each fallback [m]; inf where there is none.
    """
    k = len(orders[0]) if orders else 0
    subs = [[() for _ in range(k)] for _ in orders]
    if orders:
        # per fix and slot: the first candidate of lowest finite tau_s among those without the
        # slot's marker (NaN never wins)
        sub_arr = np.asarray(subsets, dtype=np.int64).reshape(len(subsets), -1)       # (C, k)
        cols = np.asarray(tau_s, dtype=float)[:, np.asarray(start_idx, dtype=np.int64)].T  # (F, C)
        cols = np.where(np.isnan(cols), np.inf, cols)
        marks = np.asarray(orders, dtype=np.int64)                                     # (F, k)
        for q in range(k):
            holds = (sub_arr[None, :, :] == marks[:, q, None, None]).any(axis=2)        # (F, C)
            masked = np.where(holds, np.inf, cols)
            at = np.argmin(masked, axis=1)
            ok = masked[np.arange(len(orders)), at] < math.inf
            for i in np.flatnonzero(ok).tolist():
                subs[i][q] = tuple(int(x) for x in subsets[at[i]])
    taus = [[math.inf] * k for _ in orders]
    for q in range(k):
        rows = [i for i in range(len(orders)) if subs[i][q]]
        if rows:
            pred, _, _ = promise.predict(scenario, path, speed, np.asarray(starts, float)[rows],
                                         [subs[i][q] for i in rows])
            for i, p in zip(rows, pred, strict=True):
                taus[i][q] = float(p)
    limit = scenario.planning.eps_max / (1.0 + promise.PROMISE_TOLERANCE)
    for i in range(len(orders)):
        for q in range(k):
            if not taus[i][q] < limit:  # a fallback that cannot keep the promise is none
                subs[i][q], taus[i][q] = (), math.inf
    return [tuple(s) for s in subs], [tuple(t) for t in taus]
