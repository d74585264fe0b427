"""Local search on the pair cover: destroy a neighbourhood of the chosen sites, repair, prune.

Start from a cover (greedy, or a rounded LP). Each move takes a chosen site and its ``d - 1``
nearest chosen neighbours (``d`` in 1..:data:`MAX_DESTROY`), drops them, completes the cover
greedily (the site that closes the most uncovered points with a chosen partner, or the pair of
new sites that covers the most per site; candidates scored with a small random noise), and drops
chosen sites that are no longer needed, in random order. A move that ends with more sites is
undone; one with as many or fewer is kept (walking the plateau moves the search on).

Everything is incremental: ``cnt[r]`` counts the chosen good pairs of row r, updated through
each site's pairs and each pair's rows (only pairs whose other site is chosen are walked), so a
move costs the rows of the pairs it touches and of the rows it uncovers, not a pass over the
whole problem. The budget is counted in entries visited (:data:`WORK`) and in moves without
progress (:data:`STALL`), not in seconds: the same input gives the same cover on any machine
and under any load. Random numbers come from the caller's seed (a splitmix64 stream).
"""

from __future__ import annotations

import numpy as np

from jit import compiled
from planner.placement.pair_cover import PairCover

WORK = 1_000_000_000
"""Default budget of the search, in entries visited (rows of pairs counted or uncounted, pairs of rows scored):
about 5-10 s on the 120 x 80 m hall."""
MAX_DESTROY = 3
"""Most chosen sites one move drops."""


@compiled.njit(cache=True)
def _rand(state):
    """splitmix64: next uniform in [0, 1) from ``state`` (1,) uint64, advanced in place."""
    state[0] += np.uint64(0x9E3779B97F4A7C15)
    z = state[0]
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    z = z ^ (z >> np.uint64(31))
    return (z >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@compiled.njit(cache=True)
def _lists(row_ptr, ep, pj, pl, n_sites):
    """Rows of each pair (CSR ``pptr`` (P + 1,), ``prow``) and pairs of each site (``sptr`` (S + 1,), ``spair``)."""
    n_pairs = pj.size
    pptr = np.zeros(n_pairs + 1, dtype=np.int64)
    for e in range(ep.size):
        pptr[ep[e] + 1] += 1
    pptr = np.cumsum(pptr)
    fill = pptr[:-1].copy()
    prow = np.empty(ep.size, dtype=np.int32)
    for r in range(row_ptr.size - 1):
        for e in range(row_ptr[r], row_ptr[r + 1]):
            prow[fill[ep[e]]] = r
            fill[ep[e]] += 1
    sptr = np.zeros(n_sites + 1, dtype=np.int64)
    for p in range(n_pairs):
        sptr[pj[p] + 1] += 1
        sptr[pl[p] + 1] += 1
    sptr = np.cumsum(sptr)
    sfill = sptr[:-1].copy()
    spair = np.empty(2 * n_pairs, dtype=np.int64)
    for p in range(n_pairs):
        spair[sfill[pj[p]]] = p
        sfill[pj[p]] += 1
        spair[sfill[pl[p]]] = p
        sfill[pl[p]] += 1
    return pptr, prow, sptr, spair


@compiled.njit(cache=True)
def _toggle(j, on, chosen, cnt, vcnt, vis, k, ls):
    """Choose (``on``) or drop site j, updating the pair counts ``cnt`` and visible counts ``vcnt``.

    ``ls``: :func:`_lists` and the pairs' sites. Returns the work done (entries visited).
    """
    pptr, prow, sptr, spair, pj, pl = ls
    step = 1 if on else -1
    work = sptr[j + 1] - sptr[j]
    for t in range(sptr[j], sptr[j + 1]):
        p = spair[t]
        if chosen[pl[p] if pj[p] == j else pj[p]]:
            work += pptr[p + 1] - pptr[p]
            for u in range(pptr[p], pptr[p + 1]):
                cnt[prow[u]] += step
    if k > 2:
        for r in range(cnt.size):
            if vis[r, j]:
                vcnt[r] += step
    chosen[j] = on
    return work


@compiled.njit(cache=True)
def _removable(j, chosen, cnt, vcnt, vis, k, ls, tmp):
    """Whether dropping chosen site j leaves every row covered, and the work done."""
    pptr, prow, sptr, spair, pj, pl = ls
    ok = True
    work = sptr[j + 1] - sptr[j]
    for t in range(sptr[j], sptr[j + 1]):
        p = spair[t]
        if chosen[pl[p] if pj[p] == j else pj[p]]:
            work += 3 * (pptr[p + 1] - pptr[p])
            for u in range(pptr[p], pptr[p + 1]):
                tmp[prow[u]] += 1
    for t in range(sptr[j], sptr[j + 1]):
        p = spair[t]
        if ok and chosen[pl[p] if pj[p] == j else pj[p]]:
            for u in range(pptr[p], pptr[p + 1]):
                if cnt[prow[u]] - tmp[prow[u]] <= 0:
                    ok = False
                tmp[prow[u]] = 0
        elif chosen[pl[p] if pj[p] == j else pj[p]]:
            for u in range(pptr[p], pptr[p + 1]):
                tmp[prow[u]] = 0
    if ok and k > 2:
        work += cnt.size
        for r in range(cnt.size):
            if vis[r, j] and vcnt[r] <= k:
                return False, work
    return ok, work


@compiled.njit(cache=True)
def _covered_row(r, cnt, vcnt, k):
    return cnt[r] > 0 and (k <= 2 or vcnt[r] >= k)


@compiled.njit(cache=True)
def _drop(j, chosen, cnt, vcnt, vis, k, ls, unc, n_unc, inunc):
    """Drop chosen site j; rows it leaves uncovered are appended to ``unc``. Returns the new length."""
    pptr, prow, sptr, spair, pj, pl = ls
    for t in range(sptr[j], sptr[j + 1]):
        p = spair[t]
        if chosen[pl[p] if pj[p] == j else pj[p]]:
            for u in range(pptr[p], pptr[p + 1]):
                r = prow[u]
                cnt[r] -= 1
                if cnt[r] == 0 and not inunc[r]:
                    inunc[r] = True
                    unc[n_unc] = r
                    n_unc += 1
    if k > 2:
        for r in range(cnt.size):
            if vis[r, j]:
                vcnt[r] -= 1
                if vcnt[r] == k - 1 and not inunc[r]:
                    inunc[r] = True
                    unc[n_unc] = r
                    n_unc += 1
    chosen[j] = False
    return n_unc


@compiled.njit(cache=True)
def _repair(row_ptr, ea, eb, ep, weight, vis, k, chosen, cnt, vcnt, ls, unc, n_unc, inunc,
            gain1, gain2, stamp, sites_hit, pairs_hit, added, n_added, state, noise):
    """Greedy completion of the uncovered rows ``unc[:n_unc]``; returns (work, n_added)."""
    work = 0
    n_sites = chosen.size
    while True:
        nu = 0
        for i in range(n_unc):
            r = unc[i]
            if _covered_row(r, cnt, vcnt, k):
                inunc[r] = False
            else:
                unc[nu] = r
                nu += 1
        n_unc = nu
        if n_unc == 0:
            return work, n_added
        n_sh, n_ph = 0, 0
        for i in range(n_unc):
            r = unc[i]
            if cnt[r] > 0:  # only the k-visibility condition is missing: any visible new site helps
                for s in range(n_sites):
                    if vis[r, s] and not chosen[s] and stamp[s] != r:
                        if gain1[s] == 0.0:
                            sites_hit[n_sh] = s
                            n_sh += 1
                        stamp[s] = r
                        gain1[s] += weight[r]
                work += n_sites
                continue
            work += row_ptr[r + 1] - row_ptr[r]
            for e in range(row_ptr[r], row_ptr[r + 1]):
                ca, cb = chosen[ea[e]], chosen[eb[e]]
                if ca != cb:
                    s = eb[e] if ca else ea[e]
                    if stamp[s] != r:  # each (row, new site) counted once
                        if gain1[s] == 0.0:
                            sites_hit[n_sh] = s
                            n_sh += 1
                        stamp[s] = r
                        gain1[s] += weight[r]
                elif not ca:
                    p = ep[e]
                    if gain2[p] == 0.0:
                        pairs_hit[n_ph] = p
                        n_ph += 1
                    gain2[p] += weight[r]
        best1, j = -1.0, -1
        for i in range(n_sh):
            s = sites_hit[i]
            v = gain1[s] * (1.0 + noise * _rand(state))
            if v > best1:
                best1, j = v, s
        best2, q = -1.0, -1
        for i in range(n_ph):
            p = pairs_hit[i]
            v = 0.5 * gain2[p] * (1.0 + noise * _rand(state))
            if v > best2:
                best2, q = v, p
        for i in range(n_sh):
            gain1[sites_hit[i]] = 0.0
            stamp[sites_hit[i]] = -1
        for i in range(n_ph):
            gain2[pairs_hit[i]] = 0.0
        if j >= 0 and best1 >= best2:
            new_a, new_b = j, -1
        else:
            e = -1
            for i in range(n_unc):  # the pair's sites: find one entry of pair q
                r = unc[i]
                for f in range(row_ptr[r], row_ptr[r + 1]):
                    if ep[f] == q:
                        e = f
                        break
                if e >= 0:
                    break
            new_a, new_b = ea[e], eb[e]
        for s in (new_a, new_b):
            if s >= 0 and not chosen[s]:
                work += _toggle(s, True, chosen, cnt, vcnt, vis, k, ls)
                added[n_added] = s
                n_added += 1


@compiled.njit(cache=True)
def _search(row_ptr, ea, eb, ep, pj, pl, weight, vis, k, xy, start, seed, work, max_destroy, noise, n_prune,
            stall, fixed):
    """Local search from the cover ``start`` (S,) bool; returns the best cover found, shape (S,) bool.

    ``fixed`` (S,) bool: chosen sites that no move drops.
    """
    n_rows, n_sites = row_ptr.size - 1, start.size
    n_pairs = pj.size
    pptr, prow, sptr, spair = _lists(row_ptr, ep, pj, pl, n_sites)
    ls = (pptr, prow, sptr, spair, pj, pl)
    state = np.array([np.uint64(seed)], dtype=np.uint64)
    chosen = np.zeros(n_sites, dtype=np.bool_)
    cnt = np.zeros(n_rows, dtype=np.int64)
    vcnt = np.zeros(n_rows, dtype=np.int64)
    for j in np.flatnonzero(start):
        _toggle(j, True, chosen, cnt, vcnt, vis, k, ls)
    for r in range(n_rows):
        if not _covered_row(r, cnt, vcnt, k):
            return start.copy()  # not a cover: nothing to improve from
    tmp = np.zeros(n_rows, dtype=np.int64)
    unc = np.empty(n_rows, dtype=np.int64)
    inunc = np.zeros(n_rows, dtype=np.bool_)
    gain1, gain2 = np.zeros(n_sites), np.zeros(n_pairs)
    stamp = np.full(n_sites, -1, dtype=np.int64)
    sites_hit = np.empty(n_sites, dtype=np.int64)
    pairs_hit = np.empty(n_pairs, dtype=np.int64)
    added = np.empty(n_sites, dtype=np.int64)
    best = chosen.copy()
    n_best = n_cur = int(chosen.sum())
    done, moves, last = 0, 0, 0
    while done < work and n_cur > 0 and moves - last < stall:
        moves += 1
        done += 4 * n_sites + 16 * int(chosen.sum())  # copies, scans and the sort of one move
        before = chosen.copy()
        ids = np.flatnonzero(chosen & ~fixed)
        if ids.size == 0:
            break
        c = ids[min(int(_rand(state) * ids.size), ids.size - 1)]
        dist = (xy[ids, 0] - xy[c, 0]) ** 2 + (xy[ids, 1] - xy[c, 1]) ** 2
        near = ids[np.argsort(dist, kind="mergesort")]
        d = min(1 + int(_rand(state) * max_destroy), ids.size)
        n_unc = 0
        for i in range(d):
            done += sptr[near[i] + 1] - sptr[near[i]]
            n_unc = _drop(near[i], chosen, cnt, vcnt, vis, k, ls, unc, n_unc, inunc)
        w, n_added = _repair(row_ptr, ea, eb, ep, weight, vis, k, chosen, cnt, vcnt, ls, unc,
                             n_unc, inunc, gain1, gain2, stamp, sites_hit, pairs_hit, added, 0, state, noise)
        done += w
        # prune: the added sites and the chosen ones nearest to the move, in random order
        cand = np.concatenate((added[:n_added], near[d:min(near.size, d + n_prune)]))
        for i in range(cand.size - 1, 0, -1):
            m = min(int(_rand(state) * (i + 1)), i)
            cand[i], cand[m] = cand[m], cand[i]
        for j in cand:
            if chosen[j] and not fixed[j]:
                ok, w = _removable(j, chosen, cnt, vcnt, vis, k, ls, tmp)
                done += w
                if ok:
                    done += _toggle(j, False, chosen, cnt, vcnt, vis, k, ls)
        n_new = int(chosen.sum())
        if n_new > n_cur:  # undo the move
            for j in range(n_sites):
                if chosen[j] and not before[j]:
                    done += _toggle(j, False, chosen, cnt, vcnt, vis, k, ls)
            for j in range(n_sites):
                if before[j] and not chosen[j]:
                    done += _toggle(j, True, chosen, cnt, vcnt, vis, k, ls)
        else:
            n_cur = n_new
            if n_cur < n_best:
                n_best = n_cur
                best[:] = chosen
                last = moves
    for j in range(n_sites):  # back to the best, then a full prune (latest index first)
        if chosen[j] and not best[j]:
            _toggle(j, False, chosen, cnt, vcnt, vis, k, ls)
    for j in range(n_sites):
        if best[j] and not chosen[j]:
            _toggle(j, True, chosen, cnt, vcnt, vis, k, ls)
    for j in range(n_sites - 1, -1, -1):
        if chosen[j] and not fixed[j] and _removable(j, chosen, cnt, vcnt, vis, k, ls, tmp)[0]:
            _toggle(j, False, chosen, cnt, vcnt, vis, k, ls)
    return chosen


NOISE = 0.3
"""Relative noise on the repair's scores: ties and near-ties broken at random [-]."""
STALL = 3000
"""The search stops after this many moves without a smaller cover."""
N_PRUNE = 8
"""Chosen sites nearest to a move, beyond the dropped ones, tried for removal after the repair."""


def local_search(cov: PairCover, k: int, start: np.ndarray, xy: np.ndarray, seed: int,
                 work: int = WORK, fixed: np.ndarray | None = None) -> np.ndarray:
    """Improve the cover ``start`` (S,) bool by destroy-repair-prune moves (see module doc).

    Parameters
    ----------
    cov : planner.placement.cover.PairCover
        The problem (named, not imported: the solver in ``cover`` calls this search).
    k : int
        Markers per fix.
    start : ndarray of bool, shape (S,)
        A cover of every row (returned unchanged otherwise).
    xy : ndarray, shape (S, 2)
        Site positions [m]: a move drops a chosen site and its nearest chosen neighbours.
    seed : int
        Seed of the moves' random choices.
    work : int
        Budget in (row, partner) entries visited.
    fixed : ndarray of bool, shape (S,), optional
        Sites of ``start`` that stay chosen (markers already installed).

    Returns
    -------
    ndarray of bool, shape (S,)
        A cover with at most ``start.sum()`` sites, none of which can be dropped.
    """
    return _search(cov.row_ptr, cov.ea, cov.eb, cov.ep, cov.pj, cov.pl, cov.weight, cov.vis, int(k),
                   np.ascontiguousarray(xy, dtype=float), np.asarray(start, dtype=np.bool_), int(seed) % (1 << 63),
                   int(work), MAX_DESTROY, NOISE, N_PRUNE, STALL,
                   np.zeros(cov.n_sites, dtype=np.bool_) if fixed is None else np.asarray(fixed, dtype=np.bool_))
