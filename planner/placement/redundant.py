"""Placement with redundancy: every point keeps a good pair when any r chosen markers are blocked.

A row (a class of points, :class:`~planner.placement.pair_cover.PairCover`) is *r-robust* under a
set of chosen sites when no r chosen sites hit every chosen good pair of the row (the vertex
cover number of the row's chosen good-pair graph exceeds r) and at least k + r chosen sites are
visible from it. Any vertex cover holds an end of the first chosen pair, so for r = 1 the test
is: a chosen good pair avoids its first end, and one avoids its second end. Only r <= 1 is
supported here.

The greedy here completes a set of sites into an r-robust one: it adds the site that makes the
most points robust (or, where one site is not enough, the one that completes the most chosen
pairs at non-robust rows), then drops chosen sites that are no longer needed. The exact solver
(:func:`~planner.placement.cover.solve_exact` with ``redundancy=1``) uses it to complete LP
roundings and integer points.
"""

from __future__ import annotations

import numpy as np

from jit import compiled
from planner.placement.pair_cover import PairCover
from scenarios.errors import PlanningError

#: Largest redundancy placement supports.
MAX_REDUNDANCY = 1


@compiled.njit(cache=True)
def _robust_row(row_ptr, ea, eb, vis, k, r, chosen, row):
    a, b = -1, -1
    for e in range(row_ptr[row], row_ptr[row + 1]):
        if chosen[ea[e]] and chosen[eb[e]]:
            a, b = ea[e], eb[e]
            break
    if a < 0:
        return False
    if r >= 1:
        avoid_a, avoid_b = False, False
        for e in range(row_ptr[row], row_ptr[row + 1]):
            i, j = ea[e], eb[e]
            if chosen[i] and chosen[j]:
                avoid_a |= i != a and j != a
                avoid_b |= i != b and j != b
        if not (avoid_a and avoid_b):
            return False
    if k + r > 2:
        return np.sum(vis[row] & chosen) >= k + r
    return True


@compiled.njit(cache=True)
def _robust_rows(row_ptr, ea, eb, vis, k, r, chosen):
    out = np.zeros(row_ptr.size - 1, dtype=np.bool_)
    for row in range(out.size):
        out[row] = _robust_row(row_ptr, ea, eb, vis, k, r, chosen, row)
    return out


@compiled.njit(cache=True)
def _greedy_robust(row_ptr, ea, eb, vis, weight, k, r, target, chosen, fixed):
    """Complete ``chosen`` (in place) until every ``target`` row is r-robust, then prune (never ``fixed`` sites)."""
    n_sites = chosen.size
    ok = _robust_rows(row_ptr, ea, eb, vis, k, r, chosen)
    while True:
        todo = np.flatnonzero(target & ~ok)
        if todo.size == 0:
            break
        gain, pairs = np.zeros(n_sites), np.zeros(n_sites)
        for s in range(n_sites):
            if chosen[s]:
                continue
            chosen[s] = True
            for row in todo:
                if _robust_row(row_ptr, ea, eb, vis, k, r, chosen, row):
                    gain[s] += weight[row]
            chosen[s] = False
        for row in todo:  # progress where no single site is enough: pairs a site completes
            for e in range(row_ptr[row], row_ptr[row + 1]):
                i, j = ea[e], eb[e]
                if chosen[i] != chosen[j]:
                    pairs[j if chosen[i] else i] += weight[row]
                elif not chosen[i]:
                    pairs[i] += 0.5 * weight[row]
                    pairs[j] += 0.5 * weight[row]
            for s in range(n_sites):
                if vis[row, s] and not chosen[s]:
                    pairs[s] += 1e-3 * weight[row]
        s = np.argmax(gain) if gain.max() > 0 else np.argmax(pairs)
        if chosen[s] or (gain[s] <= 0 and pairs[s] <= 0):
            break
        chosen[s] = True
        ok = _robust_rows(row_ptr, ea, eb, vis, k, r, chosen)
    for s in range(n_sites - 1, -1, -1):
        if chosen[s] and not fixed[s]:
            chosen[s] = False
            now = _robust_rows(row_ptr, ea, eb, vis, k, r, chosen)
            if np.any(target & ~now):
                chosen[s] = True
    return chosen


def _check(r: int) -> None:
    if not 0 <= r <= MAX_REDUNDANCY:
        raise PlanningError(f"planning.redundancy: placement supports at most {MAX_REDUNDANCY} "
                            f"blocked marker, got {r}")


def robust_rows(cov: PairCover, chosen: np.ndarray, k: int, r: int) -> np.ndarray:
    """Rows that stay covered with any r of the ``chosen`` (S,) sites blocked, shape (R,) bool."""
    _check(r)
    return _robust_rows(cov.row_ptr, cov.ea, cov.eb, cov.vis, k, r, np.asarray(chosen, dtype=np.bool_))


def greedy_robust(cov: PairCover, k: int, r: int, start: np.ndarray,
                  fixed: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Complete ``start`` (S,) bool into an r-robust cover of every row that can be made robust.

    ``fixed`` (S,) bool: sites of ``start`` that stay chosen (markers already installed).

    Returns
    -------
    chosen : ndarray of bool, shape (S,)
        The chosen sites.
    target : ndarray of bool, shape (R,)
        Rows that are r-robust with every site chosen (the others cannot be).
    """
    _check(r)
    target = robust_rows(cov, np.ones(cov.n_sites, dtype=bool), k, r)
    fixed = np.zeros(cov.n_sites, dtype=np.bool_) if fixed is None else np.asarray(fixed, dtype=np.bool_)
    chosen = _greedy_robust(cov.row_ptr, cov.ea, cov.eb, cov.vis, cov.weight, k, r, target,
                            np.array(start, dtype=np.bool_) | fixed, fixed)
    return chosen, target
