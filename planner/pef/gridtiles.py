"""The parallelogram PEF on a grid, streamed band by band.

(:mod:`planner.pef.pointblocks` applies the same idea to points, block by block, without the
visibility part.)

:func:`planner.pef.kernels.best_subset_grid` needs the whole visibility array (M, ny, nx) and
scores every marker at every cell: on a 120 x 80 m hall at 5 cm with 286 reflectors that is
1.1 GB of booleans and 286 normals per cell, although a cell sees about ten markers. This
module computes the same map without it. The grid is cut into bands of
:data:`~planner.pef.pairs.TILE_ROWS` rows; for each band (one thread per range of bands):

1. the markers within ``max_range`` of the band get their visibility on the band's rows, by
   the grid path's own rules (:mod:`planner.pef.visibility`: free, in range, in a flat
   marker's incidence wedge, each piece's shadow cleared row by row with the same half-planes
   and the same column search), into a band array (markers in range, TILE_ROWS, nx);
2. each tile of the band keeps the markers visible from one of its cells, in ascending index
   order, and its pairs in lexicographic order: the order of the global pair list restricted
   to them, so the pruned sweep (:func:`planner.pef.pairs._block`) picks the same pair as on
   the full list (a pair holding an unseen marker has NaN normals and never wins);
3. the previous tile's winners, as marker pairs, seed the next tile's pruning;
4. with redundancy 1, the tile is swept twice more, each time with every cell's best pair's
   first (second) marker hidden at that cell: tau_1 is the largest of the three (the
   recursion of :mod:`planner.pef.map`), at the cost of two more sweeps of a tile already in
   cache instead of two more passes over a full (M, ny, nx) array.

Values are identical to the full-array path (a test compares them); memory is one band per
thread, and the cost follows the markers a tile sees rather than all markers.
"""

from __future__ import annotations

import math

import numpy as np

from jit import compiled
from planner.pef.pairs import BLOCK, MARGIN, TILE_COLS, TILE_ROWS, _block, _scratch
from planner.pef.sight import SightRule
from planner.pef.threads import run_ranges
from planner.pef.visibility import (
    _first_above,
    _first_at_or_above,
    _free_grid_kernel,
    _range,
    prepare_sight,
    shadow_row,
    shadow_table,
    wedges_ok,
)


@compiled.njit(cache=True)
def _band_intervals(iy0, th, x, y, mx, my, r2max, hp, nhp, bm, nb, ivs, nint, lo_col, hi_col, sh):
    """Columns of band row r that band marker q (= ``bm[q]``) may see: ``ivs[q, r, :nint[q, r]]``.

    Each interval ``[i0, i1)`` of columns brackets the range disc minus the union of the pieces'
    shadows (the grid path's half-planes and column search); ascending, disjoint. The cells
    themselves are decided later with the exact range and free tests. ``lo_col[q]``,
    ``hi_col[q]`` is their hull over the band. ``sh`` (P, 2) scratch.
    """
    nx = x.size
    for q in range(nb):
        m = bm[q]
        lo_col[q], hi_col[q] = nx, 0
        for r in range(th):
            nint[q, r] = 0
            yy = y[iy0 + r]
            dy = yy - my[m]
            if dy * dy > r2max:
                continue
            half = math.sqrt(r2max - dy * dy)
            i0 = max(_first_at_or_above(x, mx[m] - half) - 1, 0)
            i1 = min(_first_above(x, mx[m] + half) + 1, nx)
            ns = 0
            for p in range(nhp.shape[1]):
                j0, j1 = shadow_row(hp[m, p], nhp[m, p], yy, x)
                j0, j1 = max(j0, i0), min(j1, i1)
                if j0 < j1:  # insertion by start column
                    k = ns
                    while k > 0 and sh[k - 1, 0] > j0:
                        sh[k, 0], sh[k, 1] = sh[k - 1, 0], sh[k - 1, 1]
                        k -= 1
                    sh[k, 0], sh[k, 1] = j0, j1
                    ns += 1
            c, n = i0, 0
            for k in range(ns):
                if sh[k, 0] > c:
                    ivs[q, r, n, 0], ivs[q, r, n, 1] = c, sh[k, 0]
                    n += 1
                c = max(c, sh[k, 1])
            if c < i1:
                ivs[q, r, n, 0], ivs[q, r, n, 1] = c, i1
                n += 1
            nint[q, r] = n
            if n:
                lo_col[q] = min(lo_col[q], ivs[q, r, 0, 0])
                hi_col[q] = max(hi_col[q], ivs[q, r, n - 1, 1])


@compiled.njit(cache=True, nogil=True, error_model="numpy")
def _without_pass(t, w, nl, npair, gm, local_of, visb, bestb, vist, pxb, pyb, mxl, myl, rel, ab, lsub, margin,
                  prev, nprev, sct, taut, bestt):
    """Tau of the tile's ``w`` cells with each cell's plain best marker ``bestb[2 c + t]`` hidden.

    The tile's visibility ``visb`` is copied into ``vist`` with that marker cleared per cell, and
    the block kernel runs on it (seeded by ``prev[:nprev]``, this pass's previous winners as
    global pairs, updated in place). Writes ``taut[:w]`` (inf where the cell has no plain best);
    returns the new ``nprev``.
    """
    for j in range(nl):
        for c in range(w):
            vist[j * BLOCK + c] = visb[j * BLOCK + c]
    for c in range(w):
        s = bestb[2 * c + t]
        if s >= 0:
            vist[s * BLOCK + c] = False
    cand = sct[12]
    ncand = np.int64(0)
    for c in range(nprev):
        a, b = local_of[prev[c, 0]], local_of[prev[c, 1]]
        if a >= 0 and b >= 0:
            cand[ncand] = a * (2 * nl - a - 1) // 2 + (b - a - 1)
            ncand += 1
    ncand = _block(pxb, pyb, vist, w, mxl[:nl], myl[:nl], rel, ab, lsub[:npair], margin, ncand, sct, taut, bestt)
    for c in range(ncand):
        prev[c, 0], prev[c, 1] = gm[lsub[cand[c], 0]], gm[lsub[cand[c], 1]]
    for c in range(w):
        if bestb[2 * c + t] < 0:
            taut[c] = np.inf
    return ncand


@compiled.njit(cache=True, nogil=True, error_model="numpy")
def bands_parallelogram(b0, b1, x, y, mx, my, wedge, max_range, hp, nhp, hidden, free, rel, ab, margin, tau, best,
                        redundant, tau_plain):
    """Bands ``b0 <= b < b1`` of the grid (``run_ranges`` kernel); see the module docstring.

    ``x`` (nx,), ``y`` (ny,) cell centres [m]; ``wedge`` (M, W, 4) the markers' wedges
    (:func:`wedges_ok`, per cell, as on the full array); ``free`` (ny, nx); writes ``tau`` (ny * nx,) [m]
    and ``best`` (2 * ny * nx,): the (ny, nx) and (ny, nx, 2) arrays flattened. With
    ``redundant`` (redundancy 1), ``tau`` is tau_1, the larger of the plain tau and the best
    pair's tau with either of its markers hidden, and ``tau_plain`` (ny * nx,) the plain tau
    (not written otherwise).
    """
    nm, nx, ny = mx.size, x.size, y.size
    npc = nhp.shape[1]
    ntx = -(-nx // TILE_COLS)
    r2max = max_range * max_range
    npair_max = max(nm * (nm - 1) // 2, 1)
    sc, pxb, pyb, visb, taub, bestb = _scratch(nm, npair_max)
    cand = sc[12]
    bm = np.empty(nm, dtype=np.int64)
    lo_col, hi_col = np.empty(nm, dtype=np.int64), np.empty(nm, dtype=np.int64)
    loc = np.empty(nm, dtype=np.int64)           # band index q of each tile marker
    gm = np.empty(nm, dtype=np.int64)            # global index of each tile marker
    local_of = np.full(nm, -1, dtype=np.int64)   # tile index of a global marker, -1 if absent
    mxl, myl = np.empty(nm), np.empty(nm)
    lsub = np.empty((npair_max, 2), dtype=np.int64)
    prev = np.empty((cand.size, 2), dtype=np.int64)
    ivs = np.empty((nm, TILE_ROWS, npc + 1, 2), dtype=np.int64)
    nint = np.zeros((nm, TILE_ROWS), dtype=np.int64)
    sh = np.empty((npc + 1, 2), dtype=np.int64)
    # the redundancy passes: their own scratch (and candidate chain), visibility and results
    sca, _, _, visa, taua, besta = _scratch(nm if redundant else 1, npair_max if redundant else 1)
    scb, _, _, visbb, taubb, bestbb = _scratch(nm if redundant else 1, npair_max if redundant else 1)
    preva, prevb = np.empty((cand.size, 2), dtype=np.int64), np.empty((cand.size, 2), dtype=np.int64)
    # int64 from the start: numba would compile _without_pass again for each literal it saw
    nprevb = npreva = np.int64(0)
    for band in range(b0, b1):
        iy0 = band * TILE_ROWS
        th = min(TILE_ROWS, ny - iy0)
        ylo, yhi = y[iy0], y[iy0 + th - 1]
        nb = np.int64(0)
        for m in range(nm):
            d = max(ylo - my[m], my[m] - yhi, 0.0)
            if not hidden[m] and d * d <= r2max:
                bm[nb] = m
                nb += 1
        _band_intervals(iy0, th, x, y, mx, my, r2max, hp, nhp, bm, nb, ivs, nint, lo_col, hi_col, sh)
        nprev = np.int64(0)
        for k in range(ntx):
            tx = k if band % 2 == 0 else ntx - 1 - k  # serpentine: neighbours share winners
            ix0 = tx * TILE_COLS
            tw = min(TILE_COLS, nx - ix0)
            ix1 = ix0 + tw
            w = th * tw
            # the tile's markers: an interval meets it (a marker whose cells there are all
            # out of range or not free only adds pairs that never win)
            nl = np.int64(0)
            for q in range(nb):
                if hi_col[q] <= ix0 or lo_col[q] >= ix1:
                    continue
                seen = False
                for r in range(th):
                    for v in range(nint[q, r]):
                        if ivs[q, r, v, 0] < ix1 and ivs[q, r, v, 1] > ix0:
                            seen = True
                            break
                    if seen:
                        break
                if seen:
                    loc[nl], gm[nl] = q, bm[q]
                    nl += 1
            for r in range(th):
                o = r * tw
                for i in range(tw):
                    pxb[o + i], pyb[o + i] = x[ix0 + i], y[iy0 + r]
            if nl < 2:
                for r in range(th):
                    cell = (iy0 + r) * nx + ix0
                    for i in range(tw):
                        tau[cell + i] = np.inf
                        best[2 * (cell + i)] = -1
                        best[2 * (cell + i) + 1] = -1
                        if redundant:
                            tau_plain[cell + i] = np.inf
                nprev = nprevb = npreva = np.int64(0)
                continue
            for j in range(nl):
                q, m = loc[j], gm[j]
                mxl[j], myl[j] = mx[m], my[m]
                local_of[m] = j
                for r in range(th):
                    o = j * BLOCK + r * tw - ix0
                    iy = iy0 + r
                    dy = y[iy] - my[m]
                    frow = free[iy]
                    for i in range(ix0, ix1):
                        visb[o + i] = False
                    for v in range(nint[q, r]):
                        for i in range(max(ivs[q, r, v, 0], ix0), min(ivs[q, r, v, 1], ix1)):
                            dx = x[i] - mx[m]
                            visb[o + i] = (frow[i] and dx * dx + dy * dy <= r2max
                                           and wedges_ok(dx, dy, wedge, m))
            npair = np.int64(0)
            for a in range(nl):
                for b in range(a + 1, nl):
                    lsub[npair, 0], lsub[npair, 1] = a, b
                    npair += 1
            ncand = np.int64(0)  # the previous tile's winners, in this tile's pair rows
            for c in range(nprev):
                a, b = local_of[prev[c, 0]], local_of[prev[c, 1]]
                if a >= 0 and b >= 0:
                    cand[ncand] = a * (2 * nl - a - 1) // 2 + (b - a - 1)
                    ncand += 1
            ncand = _block(pxb, pyb, visb, w, mxl[:nl], myl[:nl], rel, ab, lsub[:npair], margin, ncand, sc,
                           taub, bestb)
            for c in range(ncand):
                prev[c, 0], prev[c, 1] = gm[lsub[cand[c], 0]], gm[lsub[cand[c], 1]]
            nprev = ncand
            if redundant:
                nl_pairs = npair
                npreva = _without_pass(np.int64(0), w, nl, nl_pairs, gm, local_of, visb, bestb, visa, pxb, pyb,
                                       mxl, myl, rel, ab, lsub, margin, preva, npreva, sca, taua, besta)
                nprevb = _without_pass(np.int64(1), w, nl, nl_pairs, gm, local_of, visb, bestb, visbb, pxb, pyb,
                                       mxl, myl, rel, ab, lsub, margin, prevb, nprevb, scb, taubb, bestbb)
            for j in range(nl):
                local_of[gm[j]] = -1
            for r in range(th):
                o, cell = r * tw, (iy0 + r) * nx + ix0
                for i in range(tw):
                    if redundant:
                        tau_plain[cell + i] = taub[o + i]
                        tau[cell + i] = max(taub[o + i], taua[o + i], taubb[o + i])
                    else:
                        tau[cell + i] = taub[o + i]
                    for t in range(2):
                        s = bestb[2 * (o + i) + t]
                        best[2 * (cell + i) + t] = gm[s] if s >= 0 else -1


def parallelogram_grid(x: np.ndarray, y: np.ndarray, markers: np.ndarray, obstacles, max_range: float,
                       bounds: tuple[float, float, float, float], rel: float,
                       ab: float, redundancy: int = 0, normals: np.ndarray | None = None,
                       max_incidence: float = math.pi / 2,
                       rule: SightRule | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Compute the parallelogram PEF (k = 2) on the cell centres of a grid, band by band.

    Parameters
    ----------
    x : ndarray, shape (nx,)
        Cell-centre x coordinates, ascending and uniformly spaced [m].
    y : ndarray, shape (ny,)
        Cell-centre y coordinates, ascending and uniformly spaced [m].
    markers : ndarray, shape (M, 2)
        Marker positions [m].
    obstacles, max_range, bounds
        As in :func:`planner.pef.visibility.visible_grid`.
    rel, ab : float
        Range bound ``rho = rel * r + ab`` [m/m, m].
    redundancy : int
        0 or 1: with 1, ``tau`` is tau_1 (:mod:`planner.pef.map`: the larger of the plain tau
        and the best pair's tau with either of its markers hidden), computed in the same tile
        pass as the plain one.
    normals, max_incidence, rule
        Flat markers' normals and incidence limit, the line-of-sight rule, as in
        :func:`planner.pef.visibility.visible_grid`.

    Returns
    -------
    tau : ndarray, shape (ny, nx)
        Long diagonal of the best pair's parallelogram [m] (tau_1 with redundancy 1); inf where
        no pair is visible.
    best : ndarray of int64, shape (ny, nx, 2)
        Marker indices of the plain best pair (ascending), -1 where none.
    free : ndarray of bool, shape (ny, nx)
        Cell centre in free space.
    tau_plain : ndarray, shape (ny, nx)
        The plain tau (``tau`` itself with redundancy 0).
    """
    if redundancy not in (0, 1):
        raise ValueError(f"redundancy: the streamed grid handles 0 or 1, got {redundancy}")
    x = np.ascontiguousarray(x, dtype=float)
    y = np.ascontiguousarray(y, dtype=float)
    mk = np.asarray(markers, float).reshape(-1, 2)
    mx, my = np.ascontiguousarray(mk[:, 0]), np.ascontiguousarray(mk[:, 1])
    pa, sa = prepare_sight(obstacles, mk, bounds, normals, max_incidence, rule)
    x0, y0, x1, y1 = (float(v) for v in bounds)
    free = np.empty((y.size, x.size), dtype=np.bool_)
    _free_grid_kernel(x, y, x0, y0, x1, y1, pa.planes, pa.count, pa.bbox, free)
    tau = np.empty((y.size, x.size))
    best = np.empty((y.size, x.size, 2), dtype=np.int64)
    tau_plain = np.empty((y.size, x.size)) if redundancy else tau
    if mk.shape[0] < 2:
        tau.fill(np.inf)
        tau_plain.fill(np.inf)
        best.fill(-1)
        return tau, best, free, tau_plain
    max_range = _range(max_range, rule)
    hp, nhp, hidden = shadow_table(mx, my, *sa.kernel_args(), max_range)
    nbands = -(-y.size // TILE_ROWS)
    run_ranges(bands_parallelogram, nbands,
               (x, y, mx, my, sa.wedge, float(max_range), hp, nhp,
                hidden, free, float(rel), float(ab), MARGIN, tau.reshape(-1), best.reshape(-1), bool(redundancy),
                tau_plain.reshape(-1)), min_chunk=2)
    return tau, best, free, tau_plain


# numba keys a cache on its own file only: flush the kernels above when a file they inline changed
compiled.keep_fresh(__name__)
