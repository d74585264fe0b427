"""numba block kernel of the parallelogram PEF: the best marker pair at each point.

Points are processed in blocks of :data:`BLOCK` (see :mod:`planner.pef.kernels` for the shared
scheme): float32 planes ``(x, y, |g|^2)`` of the scaled normals ``g = s u / rho`` of every
marker, a branch-free sweep over candidate pairs comparing ``num / den`` by cross-multiplication
(``num = |g1|^2 + |g2|^2 + 2 |g1.g2|``, ``den = det(g1, g2)^2``), then the winner's tau in
float64 (:func:`planner.pef.scalar.diagonal_of_offsets`).

Pruning. ``num / den >= 1 / |g1|^2 + 1 / |g2|^2`` (as ``det^2 <= |g1|^2 |g2|^2``), and since
``s`` is the smallest half-width seen from the point, the nearest marker has ``|g| = 1``, so
every partner adds at least 1. Before the sweep, the pairs that won the previous block (spatially
close: the grid path walks square tiles in a serpentine) are scored on this block, giving each
point an upper bound ``U`` of its best score. A marker is *useful* when ``1 / |g|^2 + 1 <= U``
at one of the block's points, and a pair is swept only when both markers are useful and
``1 / max|g1|^2 + 1 / max|g2|^2 <= max U`` over the block, each bound with a :data:`MARGIN` of
0.1 %. A dropped pair thus scores more than 0.1 % above the best at every point of the block,
far more than the float32 rounding of a comparison (~1e-7; only a pair within ~1e-4 rad of
parallel has a float32 score that far off), and the kept pairs are swept in their original
order: the choice is the unpruned sweep's (a float32 near-tie resolves the same way), so the
grid and the points path agree exactly. On an open floor square tiles keep about a fifth of the
pairs; on row segments of 256 points (the points path) they drop a fifth at most.
"""

from __future__ import annotations

import math

import numpy as np

from jit import compiled
from planner.pef.scalar import diagonal_of_offsets

#: Grid tiles: rows x columns of cells per block.
TILE_ROWS, TILE_COLS = 16, 16
#: Points per block.
BLOCK = TILE_ROWS * TILE_COLS
#: Relative slack of the pruning bounds.
MARGIN = 1.001
#: Pairs that won the previous block, scored first to bound this block's best.
N_CANDIDATES = 4

_PLANE = 3 * BLOCK  # one marker's x, y, |g|^2 rows in the flat planes array


@compiled.njit(cache=True, error_model="numpy")
def _planes(pxb, pyb, visb, w, mx, my, rel, ab, dxb, dyb, scale, seen, planes):
    """Fill the float32 planes of one block; count the markers ``seen`` from each point.

    ``pxb``, ``pyb`` (>= w,) are the block's points [m], ``visb`` (M * BLOCK,) their visibility.
    ``planes`` (M * 3 * BLOCK,) holds, for marker m, ``x`` at ``m * 3 * BLOCK + c``, ``y`` one
    BLOCK further, ``|g|^2`` two further: one base pointer per marker keeps the sweep's address
    registers few. NaN where hidden and in the padding beyond ``w``. One pass computes the
    unscaled normals and the scale (one square root and one division per marker and point), a
    second applies the scale.
    """
    nan, inf, one = np.float32(np.nan), np.float32(np.inf), np.float32(1.0)
    rel32, ab32 = np.float32(rel), np.float32(ab)
    for c in range(BLOCK):
        scale[c] = inf
        seen[c] = 0
    for m in range(mx.size):
        mxm, mym = mx[m], my[m]
        vb, pm = visb[m * BLOCK:(m + 1) * BLOCK], planes[m * _PLANE:(m + 1) * _PLANE]
        # The float64 differences get a loop of their own: mixed with the float32 arithmetic
        # they would halve the vector width of the whole loop.
        for c in range(w):
            dxb[c] = np.float32(pxb[c] - mxm)
            dyb[c] = np.float32(pyb[c] - mym)
        for c in range(w):
            dx, dy = dxb[c], dyb[c]
            rr = math.sqrt(dx * dx + dy * dy)
            rho = rel32 * rr + ab32
            f = one / (rho * rr)
            ok = vb[c] & (rr > 0)
            pm[c] = dx * f if ok else nan
            pm[BLOCK + c] = dy * f if ok else nan
            scale[c] = min(scale[c], rho) if ok else scale[c]
            seen[c] += np.int32(1) if ok else np.int32(0)
    for m in range(mx.size):
        pm = planes[m * _PLANE:(m + 1) * _PLANE]
        for c in range(w):
            xs, ys = pm[c] * scale[c], pm[BLOCK + c] * scale[c]
            pm[c], pm[BLOCK + c], pm[2 * BLOCK + c] = xs, ys, xs * xs + ys * ys
        for c in range(w, BLOCK):
            pm[c], pm[BLOCK + c], pm[2 * BLOCK + c] = nan, nan, nan


@compiled.njit(cache=True, fastmath={"contract"})
def _score(p, q, c):
    """``num, den`` of the pair with planes ``p``, ``q`` at point ``c``."""
    det = p[c] * q[BLOCK + c] - p[BLOCK + c] * q[c]
    dot = p[c] * q[c] + p[BLOCK + c] * q[BLOCK + c]
    return p[2 * BLOCK + c] + q[2 * BLOCK + c] + np.float32(2.0) * abs(dot), det * det


@compiled.njit(cache=True)
def _take(better, new, old):
    return new if better else old


@compiled.njit(cache=True, error_model="numpy", fastmath={"contract"})
def _sweep(order, n, subsets, planes, bnd, bs):
    """Best of the pairs ``subsets[order[:n]]`` per point, two pairs per pass over the block.

    ``bnd`` (2 * BLOCK,) holds the best ``num`` then ``den``, ``bs`` (BLOCK,) the subset row.
    'contract' (fused multiply-add) only changes float32 rounding; NaN stays NaN.
    """
    for k in range(0, n, 2):
        s, t = order[k], order[min(k + 1, n - 1)]  # an odd count scores the last pair twice
        p0, q0 = planes[subsets[s, 0] * _PLANE:], planes[subsets[s, 1] * _PLANE:]
        p1, q1 = planes[subsets[t, 0] * _PLANE:], planes[subsets[t, 1] * _PLANE:]
        ss, st = np.int32(s), np.int32(t)
        for c in range(BLOCK):
            nb, db, sb = bnd[c], bnd[BLOCK + c], bs[c]
            num, den = _score(p0, q0, c)
            b = num * db < nb * den
            nb, db, sb = _take(b, num, nb), _take(b, den, db), _take(b, ss, sb)
            num, den = _score(p1, q1, c)
            b = num * db < nb * den
            bnd[c], bnd[BLOCK + c], bs[c] = _take(b, num, nb), _take(b, den, db), _take(b, st, sb)


@compiled.njit(cache=True, error_model="numpy")
def _reset(bnd, bs):
    for c in range(BLOCK):
        bnd[c], bnd[BLOCK + c], bs[c] = 1.0, 0.0, -1  # 1 / 0: worse than any pair


@compiled.njit(cache=True, error_model="numpy")
def _prune(nm, subsets, planes, seen, cand, ncand, margin, bnd, bs, bound, bits, order):
    """Write the rows of the pairs worth sweeping into ``order``; return their count.

    ``cand[:ncand]`` are the candidate rows, ``margin`` the bounds' factor (inf keeps every
    pair). Scratch: ``bnd``, ``bs``, ``bound`` (BLOCK,) and ``bits`` (2M,) int32. See the module
    docstring for the bounds.
    """
    nsub = subsets.shape[0]
    if ncand == 0:
        for s in range(nsub):
            order[s] = s
        return nsub
    _reset(bnd, bs)
    _sweep(cand, ncand, subsets, planes, bnd, bs)
    margin, one, zero = np.float32(margin), np.float32(1.0), np.float32(0.0)
    # u = U * margin - 1 per point (inf when no candidate is usable there); 0 where fewer than
    # two markers are seen, as such a point has no pair to keep.
    umax = zero
    for c in range(BLOCK):
        u = bnd[c] / bnd[BLOCK + c] * margin - one
        u = u if seen[c] >= 2 else zero
        bound[c] = u
        umax = max(umax, u)
    if umax == np.inf:
        for s in range(nsub):
            order[s] = s
        return nsub
    # Per marker: the points where it is useful (1/q + 1 <= U, i.e. q u >= 1; false for NaN),
    # and its largest q as the integer max of the bit patterns (q >= 0, NaN mapped to 0),
    # which vectorises where a float max reduction would need fast-math on NaN.
    pbits = planes.view(np.int32)
    for m in range(nm):
        o = m * _PLANE + 2 * BLOCK
        h, top = np.int32(0), np.int32(0)
        for c in range(BLOCK):
            q = planes[o + c]
            h += np.int32(1) if q * bound[c] >= one else np.int32(0)
            top = max(top, pbits[o + c] if q == q else np.int32(0))
        bits[m], bits[nm + m] = h, top
    qmax = bits.view(np.float32)[nm:]
    lim = umax + one  # max U * margin
    n = 0
    for s in range(nsub):
        i, j = subsets[s, 0], subsets[s, 1]
        if bits[i] > 0 and bits[j] > 0 and one / qmax[i] + one / qmax[j] <= lim:
            order[n] = s
            n += 1
    return n


@compiled.njit(cache=True, error_model="numpy")
def _next_candidates(bs, w, counts, touched, cand):
    """Write the most frequent winners among ``bs[:w:4]`` into ``cand``; return their count.

    ``counts`` (C,) is zero on entry and on return; ``touched`` (C,) is scratch. Every fourth
    point is enough to find the block's main winners, which are all the candidates are for.
    """
    nd = 0
    for c in range(0, w, 4):
        s = bs[c]
        if s >= 0:
            if counts[s] == 0:
                touched[nd] = s
                nd += 1
            counts[s] += 1
    n = 0
    for _ in range(min(cand.size, nd)):
        top, at = 0, 0
        for t in range(nd):
            if counts[touched[t]] > top:
                top, at = counts[touched[t]], touched[t]
        cand[n] = at
        counts[at] = 0
        n += 1
    for t in range(nd):
        counts[touched[t]] = 0
    return n


@compiled.njit(cache=True, error_model="numpy")
def _tau_pairs(pxb, pyb, w, mx, my, subsets, rel, ab, bs, ax, ay, bx, by, taub, bestb):
    """Write the chosen pair ``subsets[bs[c]]`` (into ``bestb[2c:2c + 2]``) and its float64 tau.

    A scalar pass gathers the pair's marker coordinates into ``ax, ay, bx, by`` (BLOCK,); the
    arithmetic (square roots, divisions) then runs in a vectorised loop.
    """
    for c in range(w):
        s = bs[c]
        s0 = max(s, 0)
        i, j = subsets[s0, 0], subsets[s0, 1]
        ax[c], ay[c], bx[c], by[c] = mx[i], my[i], mx[j], my[j]
        bestb[2 * c] = i if s >= 0 else -1
        bestb[2 * c + 1] = j if s >= 0 else -1
    for c in range(w):
        t = diagonal_of_offsets(pxb[c] - ax[c], pyb[c] - ay[c], pxb[c] - bx[c], pyb[c] - by[c], rel, ab)
        taub[c] = t if bs[c] >= 0 else np.inf
        if not taub[c] < np.inf:  # the point on the line through both markers: no subset fixes it
            bestb[2 * c] = -1
            bestb[2 * c + 1] = -1


@compiled.njit(cache=True, error_model="numpy")
def _scratch(nm, nsub):
    """Allocate the per-thread buffers.

    Those of :func:`_block` (in the order it unpacks them), then the block's points, visibility,
    tau and pairs (flat, as the drivers fill and read them).
    """
    f32, i32, i64 = np.float32, np.int32, np.int64
    return ((np.empty(BLOCK, f32), np.empty(BLOCK, f32), np.empty(BLOCK, f32), np.empty(BLOCK, i32),
             np.empty(nm * _PLANE, f32), np.empty(2 * BLOCK, f32), np.empty(BLOCK, i32),
             np.empty(BLOCK, f32), np.empty(2 * nm, i32), np.empty(nsub, i64), np.zeros(nsub, i64),
             np.empty(nsub, i64), np.empty(N_CANDIDATES, i64),
             np.empty(BLOCK), np.empty(BLOCK), np.empty(BLOCK), np.empty(BLOCK)),
            np.empty(BLOCK), np.empty(BLOCK), np.empty(nm * BLOCK, np.bool_), np.empty(BLOCK),
            np.empty(2 * BLOCK, i64))


@compiled.njit(cache=True, error_model="numpy")
def _block(pxb, pyb, visb, w, mx, my, rel, ab, subsets, margin, ncand, sc, taub, bestb):
    """Best pair and tau for the ``w`` points of one block; return the next block's candidate count.

    ``visb`` (M * BLOCK,): marker m's visibility at ``m * BLOCK + c``; ``bestb`` (2 w,).
    """
    dxb, dyb, scale, seen, planes, bnd, bs, bound, bits, order, counts, touched, cand, ax, ay, bx, by = sc
    _planes(pxb, pyb, visb, w, mx, my, rel, ab, dxb, dyb, scale, seen, planes)
    n = _prune(mx.size, subsets, planes, seen, cand, ncand, margin, bnd, bs, bound, bits, order)
    _reset(bnd, bs)
    _sweep(order, n, subsets, planes, bnd, bs)
    _tau_pairs(pxb, pyb, w, mx, my, subsets, rel, ab, bs, ax, ay, bx, by, taub, bestb)
    return _next_candidates(bs, w, counts, touched, cand)


# The drivers take flat arrays and index them with unsigned integers: a signed index gets a
# negative-index wraparound select, which makes the short row copies ten times slower.

@compiled.njit(cache=True, nogil=True, error_model="numpy")
def blocks_points(b0, b1, px, py, mx, my, vis, rel, ab, subsets, margin, tau, best):
    """Blocks ``b0 <= b < b1`` of :data:`BLOCK` consecutive points (``run_ranges`` kernel).

    ``px``, ``py`` (N,) [m]; ``vis`` (M * N,): the (M, N) visibility, flattened; ``margin``:
    :data:`MARGIN` (inf: no pruning). Writes ``tau`` (N,) [m] and ``best`` (2 N,): the (N, 2)
    pairs, flattened.
    """
    nm, npt, u = mx.size, px.size, np.uint64
    sc, _, _, visb, _, _ = _scratch(nm, subsets.shape[0])
    ncand = np.int64(0)  # not the literal 0, which numba would compile _block for a second time
    for blk in range(b0, b1):
        lo = blk * BLOCK
        w = min(BLOCK, npt - lo)
        for m in range(nm):
            src, dst = u(m * npt + lo), u(m * BLOCK)
            for i in range(u(w)):
                visb[dst + i] = vis[src + i]
        ncand = _block(px[lo:lo + w], py[lo:lo + w], visb, w, mx, my, rel, ab, subsets, margin, ncand,
                       sc, tau[lo:lo + w], best[2 * lo:2 * (lo + w)])


def tile_count(nx: int, ny: int) -> int:
    """Count the :data:`TILE_ROWS` x :data:`TILE_COLS` tiles covering an (ny, nx) grid."""
    return -(-ny // TILE_ROWS) * -(-nx // TILE_COLS)


@compiled.njit(cache=True, nogil=True, error_model="numpy")
def blocks_grid(t0, t1, x, y, mx, my, vis, rel, ab, subsets, margin, tau, best):
    """Tiles ``t0 <= t < t1`` of the grid of cell centres ``x`` (nx,), ``y`` (ny,) [m].

    Tiles are numbered row by row in a serpentine (every other tile row right to left), so
    consecutive tiles are neighbours and the previous tile's winners are good candidates.
    ``vis`` (M * ny * nx,), ``tau`` (ny * nx,) [m] and ``best`` (2 * ny * nx,) are the (M, ny, nx),
    (ny, nx) and (ny, nx, 2) arrays flattened; ``margin`` as in :func:`blocks_points`.
    """
    nm, nx, ny, u = mx.size, x.size, y.size, np.uint64
    ntx = -(-nx // TILE_COLS)
    sc, pxb, pyb, visb, taub, bestb = _scratch(nm, subsets.shape[0])
    ncand = np.int64(0)  # see blocks_points
    for t in range(t0, t1):
        ty, k = t // ntx, t % ntx
        tx = k if ty % 2 == 0 else ntx - 1 - k
        iy0, ix0 = ty * TILE_ROWS, tx * TILE_COLS
        th, tw = min(TILE_ROWS, ny - iy0), min(TILE_COLS, nx - ix0)
        for r in range(th):
            o, cell, yr = u(r * tw), u((iy0 + r) * nx + ix0), y[iy0 + r]
            for i in range(u(tw)):
                pxb[o + i], pyb[o + i] = x[u(ix0) + i], yr
            for m in range(nm):
                src, dst = u(m * nx * ny) + cell, u(m * BLOCK) + o
                for i in range(u(tw)):
                    visb[dst + i] = vis[src + i]
        ncand = _block(pxb, pyb, visb, th * tw, mx, my, rel, ab, subsets, margin, ncand, sc, taub, bestb)
        for r in range(th):
            o, cell = u(r * tw), u((iy0 + r) * nx + ix0)
            for i in range(u(tw)):
                tau[cell + i] = taub[o + i]
            for i in range(u(2 * tw)):
                best[u(2) * cell + i] = bestb[u(2) * o + i]


# numba keys a cache on its own file only: flush the kernels above when a file they inline changed
compiled.keep_fresh(__name__)
