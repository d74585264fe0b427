"""The pair-cover problem of marker placement and its solvers (greedy, cutting planes + MILP).

Sites are the variables ``z_j``; a row (a class of points with identical good pairs) is
covered when both sites of one of its good pairs are chosen (and, for k > 2, at least k of the
chosen sites are visible from it). Instead of pair variables, the exact solver describes
"row r has a chosen good pair" by *independent-set cuts*: if T is a set of sites with no good
pair of row r inside (an independent set of the row's good-pair graph G_r, vertices S_r), any
cover must choose a site of ``S_r minus T``::

    min sum_j z_j   s.t.   sum_{j in S_r minus T} z_j >= 1   for all r and independent T in G_r
                           sum_{j in S_r} z_j >= 2,  sum_{j visible from r} z_j >= k,  z binary

Taking every maximal T this is exact; the cuts are generated as needed (one per row and
round, T grown greedily), so each LP/MILP has only the site variables and few hundred rows.

Redundancy 1 (any one chosen site may be blocked) is the same formulation with right-hand
sides one higher: a row is 1-robust exactly when no single chosen site meets every chosen good
pair of it, i.e. when every independent T leaves at least *two* chosen sites in ``S_r minus T``
(if only u were left, blocking u leaves the chosen sites of the row inside T, no pair among
them; conversely, if every chosen pair held u, T = the other chosen sites of the row would be
independent and leave only u). So ``sum_{S_r minus T} z >= 2``, ``sum_{S_r} z >= 3`` and
``sum_{visible} z >= k + 1``: its LP is a lower bound on the redundancy-1 count, and its
integer rounds find redundancy-1 covers directly (completed by
:func:`planner.placement.redundant.greedy_robust`).
"""

from __future__ import annotations

import math
import time

import numpy as np
from scipy import optimize, sparse

from jit import compiled
from planner.placement.pair_cover import PairCover
from planner.placement.redundant import greedy_robust, robust_rows
from planner.placement.search import WORK, local_search

MILP_TIME_LIMIT = 30.0
"""Default safety limit of the exact solver's LP and MILP rounds together [s] (the limits that
decide the result are counts: :data:`MAX_LP_ROUNDS`, :data:`LP_STALL`, :data:`MILP_NODE_LIMIT`)."""
MAX_LP_ROUNDS = 30
"""Most cutting-plane rounds of the LP phase."""
LP_STALL = 0.01
"""The LP phase stops when two rounds raised the LP value by less than this [markers]."""
MILP_NODE_LIMIT = 20_000
"""Branch-and-bound nodes of one integer round (HiGHS ``node_limit``)."""
SEARCH_GAP = 1.1
"""While the best cover is more than this times the bound, the local search goes on ..."""
SEARCH_EXTENSIONS = 2
"""... for at most this many more budgets, each from the best cover with the next seed."""

@compiled.njit(cache=True)
def _rows_covered(row_ptr, ea, eb, vis, k, chosen):
    """Rows with a chosen good pair and at least k visible chosen sites, shape (R,) bool."""
    return _recheck(row_ptr, ea, eb, vis, k, chosen, np.zeros(row_ptr.size - 1, dtype=np.bool_))


@compiled.njit(cache=True)
def _recheck(row_ptr, ea, eb, vis, k, chosen, covered):
    """``covered`` after adding sites to ``chosen``: only the uncovered rows can change."""
    for r in range(row_ptr.size - 1):
        if covered[r]:
            continue
        for e in range(row_ptr[r], row_ptr[r + 1]):
            if chosen[ea[e]] and chosen[eb[e]]:
                covered[r] = True
                break
        if covered[r] and k > 2:
            covered[r] = np.sum(vis[r] & chosen) >= k
    return covered


@compiled.njit(cache=True)
def _greedy_kernel(row_ptr, ea, eb, ep, pj, pl, weight, vis, k, chosen, fixed):
    """Greedy completion of ``chosen`` (in place), then removal of redundant sites (never ``fixed`` ones)."""
    n_rows, n_sites, n_pairs = row_ptr.size - 1, chosen.size, pj.size
    covered = _rows_covered(row_ptr, ea, eb, vis, k, chosen)
    stamp = np.full(n_sites, -1, dtype=np.int64)
    while not covered.all():
        gain1, gain2 = np.zeros(n_sites), np.zeros(n_pairs)
        stamp[:] = -1
        for r in range(n_rows):
            if covered[r]:
                continue
            for e in range(row_ptr[r], row_ptr[r + 1]):
                ca, cb = chosen[ea[e]], chosen[eb[e]]
                new = eb[e] if ca else ea[e]
                if ca != cb and stamp[new] != r:  # each (row, new site) counted once
                    stamp[new] = r
                    gain1[new] += weight[r]
                elif not ca and not cb:
                    gain2[ep[e]] += weight[r]
        j, p = np.argmax(gain1), np.argmax(gain2) if n_pairs else 0
        if gain1[j] > 0 and gain1[j] >= (gain2[p] if n_pairs else 0.0) / 2:
            chosen[j] = True
        elif n_pairs and gain2[p] > 0:  # a pair of new sites covers more per site added
            chosen[pj[p]] = chosen[pl[p]] = True
        else:  # only the k-visibility condition is missing: add the site most rows lack
            seen = np.zeros(n_sites)
            for r in range(n_rows):
                if not covered[r]:
                    seen += weight[r] * (vis[r] & ~chosen)
            if seen.max() <= 0:
                break
            chosen[np.argmax(seen)] = True
        covered = _recheck(row_ptr, ea, eb, vis, k, chosen, covered)
    for j in range(n_sites - 1, -1, -1):
        if chosen[j] and not fixed[j]:
            chosen[j] = False
            if not _rows_covered(row_ptr, ea, eb, vis, k, chosen).all():
                chosen[j] = True
    return chosen


def covered(cov: PairCover, chosen: np.ndarray, k: int) -> np.ndarray:
    """Rows covered by ``chosen`` sites ((S,) bool), shape (R,) bool."""
    return _rows_covered(cov.row_ptr, cov.ea, cov.eb, cov.vis, k, chosen)


def greedy(cov: PairCover, k: int, start: np.ndarray | None = None, fixed: np.ndarray | None = None) -> np.ndarray:
    """Greedy cover: chosen sites, shape (S,) bool.

    Adds the site that with the chosen ones covers the most uncovered points, or the pair of
    new sites that covers the most per site added when that is more, until every row is
    covered; then drops chosen sites that are no longer needed (latest index first).
    ``start`` (S,) bool: sites chosen beforehand (a partial solution to complete);
    ``fixed`` (S,) bool: sites that stay chosen (markers already installed).
    """
    fixed = _fixed(cov, fixed)
    chosen = np.zeros(cov.n_sites, dtype=np.bool_) if start is None else np.array(start, dtype=np.bool_)
    chosen |= fixed
    return _greedy_kernel(cov.row_ptr, cov.ea, cov.eb, cov.ep, cov.pj, cov.pl, cov.weight, cov.vis, k, chosen,
                          fixed)


def _fixed(cov: PairCover, fixed: np.ndarray | None) -> np.ndarray:
    return np.zeros(cov.n_sites, dtype=np.bool_) if fixed is None else np.asarray(fixed, dtype=np.bool_)


@compiled.njit(cache=True)
def _separate(row_ptr, ea, eb, n_sites, z, tol, cuts, need):
    """Independent-set cuts, one per row: ``cuts[r]`` = S_r minus a maximal independent set T.

    T is grown greedily in the row's good-pair graph G_r (sites S_r, edges = good pairs), by
    descending ``z`` then ascending degree. No good pair lies inside T, so every cover takes a
    site of S_r minus T: ``sum_{S_r minus T} z >= 1`` is valid (``>= 2`` for redundancy 1,
    see module doc). Returns which rows' cuts ``z`` violates, their sum short of ``need`` by
    more than ``tol``.
    """
    n_rows = row_ptr.size - 1
    violated = np.zeros(n_rows, dtype=np.bool_)
    adj = np.zeros((n_sites, n_sites), dtype=np.bool_)
    deg = np.zeros(n_sites, dtype=np.int64)
    in_row = np.zeros(n_sites, dtype=np.bool_)
    blocked = np.zeros(n_sites, dtype=np.bool_)
    for r in range(n_rows):
        for e in range(row_ptr[r], row_ptr[r + 1]):
            a, b = ea[e], eb[e]
            adj[a, b] = adj[b, a] = True
            deg[a] += 1
            deg[b] += 1
            in_row[a] = in_row[b] = True
        sites = np.flatnonzero(in_row)
        key = np.empty(sites.size)
        for t in range(sites.size):
            key[t] = -z[sites[t]] * 1e6 + deg[sites[t]]
        slack = 0.0
        for t in np.argsort(key, kind="mergesort"):
            j = sites[t]
            if blocked[j]:
                cuts[r, j] = True
                slack += z[j]
                continue
            for m in sites:  # j joins T: its neighbours can no longer
                if adj[j, m]:
                    blocked[m] = True
        violated[r] = slack < need - tol
        for e in range(row_ptr[r], row_ptr[r + 1]):
            a, b = ea[e], eb[e]
            adj[a, b] = adj[b, a] = False
            deg[a] = deg[b] = 0
            in_row[a] = in_row[b] = False
        for j in sites:
            blocked[j] = False
    return violated


def _any_subset(a: sparse.csr_matrix, a_size: np.ndarray, b: sparse.csr_matrix, strict: bool = False,
                chunk: int = 512) -> np.ndarray:
    """For each row of ``b``: is some row of ``a`` a subset of it? Shape (len(b),) bool.

    ``a_size`` (len(a),): the rows' support sizes. ``strict``: ``a`` and ``b`` are the same
    duplicate-free rows, and a row is not its own subset.
    """
    out = np.zeros(b.shape[0], dtype=bool)
    if a.shape[0] == 0 or b.shape[0] == 0:
        return out
    for lo in range(0, b.shape[0], chunk):
        overlap = (a @ b[lo:lo + chunk].T).toarray()  # (len(a), chunk) shared sites
        sub = overlap == a_size[:, None]
        if strict:
            idx = np.arange(lo, min(lo + chunk, b.shape[0]))
            sub[idx, idx - lo] = False
        out[lo:lo + chunk] = sub.any(axis=0)
    return out


class _Cuts:
    """Covering rows ``sum_{j in support} z_j >= rhs``, kept free of dominated duplicates."""

    def __init__(self, n_sites: int):
        self.support = np.zeros((0, n_sites), dtype=bool)
        self.rhs = np.zeros(0)

    def add(self, support: np.ndarray, rhs: float) -> int:
        """Add the rows of ``support`` (C, S) not implied by existing ones; returns how many.

        A row is implied by one with a subset of its support and at least its ``rhs``; existing
        rows that a new one implies are dropped. The result is what adding the rows one by one
        would leave (survivors in their order, then the new rows in theirs); the subset tests
        are sparse products, in chunks, so that thousands of rows cost seconds, not minutes.
        """
        support = np.asarray(support, dtype=bool).reshape(-1, self.support.shape[1])
        if not len(support):
            return 0
        _, first = np.unique(np.packbits(support, axis=1), axis=0, return_index=True)
        support = support[np.sort(first)]  # duplicates: the first one stands for them
        new = sparse.csr_matrix(support, dtype=np.int32)
        size = np.asarray(new.sum(axis=1)).ravel()
        old = sparse.csr_matrix(self.support, dtype=np.int32)
        old_size = np.asarray(old.sum(axis=1)).ravel()
        strong = self.rhs >= rhs
        keep = ~_any_subset(old[strong], old_size[strong], new)                 # implied by an old row
        keep &= ~_any_subset(new, size, new, strict=True)                          # by another new row
        support, new, size = support[keep], new[keep], size[keep]
        weak = self.rhs <= rhs
        drop = np.zeros(len(self.rhs), dtype=bool)
        drop[weak] = _any_subset(new, size, old[weak])                            # old rows a new one implies
        self.support = np.vstack([self.support[~drop], support])
        self.rhs = np.append(self.rhs[~drop], np.full(len(support), float(rhs)))
        return len(support)

    def solve(self, time_limit: float, at_most: int | None = None, fixed: np.ndarray | None = None):
        """LP relaxation (``at_most`` None) or an integer point with at most ``at_most`` sites.

        ``fixed`` (S,) bool: sites held at 1 and not counted (in the objective nor in ``at_most``).
        """
        n = self.support.shape[1]
        free = np.ones(n) if fixed is None else (~fixed).astype(float)
        a, lo, hi = self.support.astype(float), self.rhs, np.full(len(self.rhs), np.inf)
        if at_most is not None:
            a, lo, hi = np.vstack([a, free]), np.append(lo, 0.0), np.append(hi, at_most)
        con = optimize.LinearConstraint(sparse.csr_matrix(a), lo, hi)
        # integer rounds only look for a feasible point: a zero objective stops at the first
        cost = free if at_most is None else np.zeros(n)
        low = np.zeros(n) if fixed is None else fixed.astype(float)
        return optimize.milp(cost, constraints=[con], integrality=np.full(n, float(at_most is not None)),
                             bounds=optimize.Bounds(low, 1.0),
                             options={"time_limit": max(time_limit, 0.1), "node_limit": MILP_NODE_LIMIT})


def solve_exact(cov: PairCover, k: int, time_limit: float = MILP_TIME_LIMIT, integral: bool = True,
                xy: np.ndarray | None = None, seed: int = 0, work: int | None = None,
                fixed: np.ndarray | None = None, redundancy: int = 0):
    """Cutting planes on the site-only formulation, local search, then integer rounds (see module doc).

    LP phase: solve the LP over the current covering rows, add the independent-set cuts it
    violates, until none is found, or the LP value rose by less than :data:`LP_STALL` over
    two rounds, or after :data:`MAX_LP_ROUNDS` rounds; every LP value is a lower bound. Upper
    bound: the best of the greedy cover and the greedy completions of the LP solution's sites
    with ``z >= 0.3, 0.5, 0.7``, improved by :func:`planner.placement.search.local_search`.
    While the cover exceeds :data:`SEARCH_GAP` times the bound, the search runs again from it
    with the next seed, at most :data:`SEARCH_EXTENSIONS` times.
    Integer rounds (``integral``): look for an integer point with fewer sites than the best
    cover (HiGHS with a node limit, :data:`MILP_NODE_LIMIT`); if it covers, it is the new best;
    if not, add the cuts it violates (and complete it greedily); if there is none, the best
    cover is optimal.

    Every limit that decides the result is a count (rounds, nodes, entries visited), so the
    same problem gives the same cover and bound under any load; ``time_limit`` is only a
    safety net for instances far bigger than those these counts were set for.

    Parameters
    ----------
    cov : PairCover
    k : int
        Markers per fix.
    time_limit : float
        Safety limit of the LP and MILP rounds together [s].
    integral : bool
        Run the integer rounds.
    xy : ndarray, shape (S, 2), optional
        Site positions [m] for the local search's neighbourhoods (default: by site index).
    seed : int
        Seed of the local search.
    work : int, optional
        Local search budget in entries visited (default :data:`planner.placement.search.WORK`;
        0 turns it off).
    fixed : ndarray of bool, shape (S,), optional
        Sites that are chosen whatever happens (markers already installed): held at 1 in the
        LP and MILP, never dropped, and not counted; count and bound are then of the others.
    redundancy : {0, 1}
        Cover every row 1-robustly (see module doc): every row must be able to be made robust
        with every site chosen (:func:`planner.placement.redundant.robust_rows`). The local
        search is for redundancy 0 only.

    Returns
    -------
    chosen : ndarray of bool, shape (S,)
        Best cover found (the fixed sites included).
    bound : float
        Lower bound on the count (of the sites not fixed).
    optimal : bool
        ``chosen`` is proven minimal.
    """
    start = time.perf_counter()
    left = lambda: time_limit - (time.perf_counter() - start)
    fixed = _fixed(cov, fixed)
    size = lambda z: int(np.count_nonzero(z & ~fixed))
    r = int(redundancy)
    if r:
        def complete(z):
            return greedy_robust(cov, k, r, z, fixed)[0]

        def ok(z):
            return bool(robust_rows(cov, z, k, r).all())
        work = 0  # the local search keeps covers, not robust ones
    else:
        def complete(z):
            return greedy(cov, k, z, fixed)

        def ok(z):
            return bool(covered(cov, z, k).all())
    cuts = _Cuts(cov.n_sites)
    in_pair = np.zeros((len(cov.weight), cov.n_sites), dtype=bool)
    er = cov.er
    in_pair[er, cov.ea] = in_pair[er, cov.eb] = True
    cuts.add(in_pair, 2.0 + r)
    if k + r > 2:
        cuts.add(cov.vis, float(k + r))

    def separate(z):
        out = np.zeros((len(cov.weight), cov.n_sites), dtype=bool)
        return out[_separate(cov.row_ptr, cov.ea, cov.eb, cov.n_sites, z, 1e-6, out, 1.0 + r)]

    cuts.add(separate(np.zeros(cov.n_sites)), 1.0 + r)
    bound, x, history = 0.0, np.zeros(cov.n_sites), []
    for _ in range(MAX_LP_ROUNDS):
        if left() <= 0:
            break
        res = cuts.solve(left(), fixed=fixed)
        if res.x is None:
            break
        bound, x = max(bound, float(res.fun)), res.x
        history.append(bound)
        if len(history) > 2 and history[-1] < history[-3] + LP_STALL:
            break
        if not cuts.add(separate(res.x), 1.0 + r):
            break
    # LP rounding with repair at several thresholds (the hall's LP is fractional everywhere, and
    # which threshold completes best varies by a marker or two), without the search also against
    # plain greedy;
    # the local search does better from the roundings than from plain greedy (on the hall, 51-53
    # against 51-55 markers over three seeds), and each greedy costs seconds there
    work = WORK if work is None else int(work)
    starts = [complete((x >= t) | fixed) for t in (0.3, 0.5)]
    if work <= 0:
        starts += [complete((x >= 0.7) | fixed), complete(fixed.copy())]
    best = min(starts, key=size)
    if work > 0 and math.ceil(bound - 1e-6) < size(best):
        pos = np.column_stack([np.arange(cov.n_sites, dtype=float), np.zeros(cov.n_sites)]) if xy is None else xy
        best = local_search(cov, k, best, pos, seed, work, fixed)
        # far from the bound: search on from the best with fresh streams (the hall with posts:
        # 52 -> 51 against a bound of 47), a count of budgets, so the result stays load-free
        for extra in range(1, SEARCH_EXTENSIONS + 1):
            if size(best) <= SEARCH_GAP * math.ceil(bound - 1e-6):
                break
            best = local_search(cov, k, best, pos, seed + extra, work, fixed)
    while integral and math.ceil(bound - 1e-6) < size(best) and left() > 0:
        res = cuts.solve(left(), at_most=size(best) - 1, fixed=fixed)
        if res.status == 2:  # infeasible: nothing smaller than the best cover exists
            bound = float(size(best))
            break
        if res.x is None:
            break
        z = (res.x > 0.5) | fixed
        if ok(z):
            best = z
            continue
        completed = complete(z)
        best = completed if size(completed) < size(best) else best
        if not cuts.add(separate(z.astype(float)), 1.0 + r) and not cuts.add(~z[None, :], 1.0):
            # no independent-set cut cuts z off, yet z is no cover (a robust row short of a pair
            # left when one site is blocked): every cover holds a site outside z (coverage only
            # grows with sites), the no-good cut; when even that is implied, stop unproven
            break
    return best, bound, math.ceil(bound - 1e-6) >= size(best)
