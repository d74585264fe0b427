"""numba kernels of the PEF: the best marker subset for each point under a linearised model.

One kernel, :func:`best_subset`, serves arbitrary points and grids (a grid is its cell
centres, flattened). Points are processed in blocks of :data:`BLOCK`; for each block the
scaled range normals ``g = u / rho`` (and with bearings the tangential ``h = t / (r tan xi)``)
of every marker are computed once, then every candidate subset is scored across the block's
points in a branch-free inner loop that vectorises (SIMD across points; threads across
blocks, :mod:`planner.kernel_threads`).

Candidates are compared as fractions ``num / den`` by cross-multiplication
(``num * best_den < best_num * den``), with neither square root nor division:

- parallelogram: ``num = |g1|^2 + |g2|^2 + 2 |g1.g2|``, ``den = det(g1, g2)^2``; the squared
  long diagonal is ``4 num / den`` (see :mod:`estimators.linearized`);
- gdop: ``num = T + sqrt(T^2 - 4 D)``, ``den = 2 D`` with trace T and determinant D of the
  information ``B = sum g g^T``, i.e. ``lambda_max(B^-1)``;
- strips: the largest squared vertex norm of the strip polygon, a scalar O(s^3) loop per point
  and subset in float64.

Selection precision: for the parallelogram and gdop models the comparison runs in float32 (twice
the SIMD width); the normals of a point are first scaled by the smallest half-width seen from
it, so every number is O(1) and no product overflows. The winner's tau is then recomputed in
float64 from scratch (:mod:`planner.pef_scalar`), so tau is exact for the chosen subset and within
~1e-6 relative of the float64 minimum.

A marker not visible from a point gets NaN normals: every comparison with NaN is false, so a
subset holding it is never chosen; a parallel pair has ``den = 0`` and is never chosen either;
the initial best is ``1 / 0`` (infinite).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from estimators.linearized import strip_max_vertex_sq_k
from planner.kernel_threads import run_ranges
from planner.pef_scalar import (
    GDOP,
    PARALLELOGRAM,
    STRIPS,
    diagonal_of_offsets,
    subset_tau,
    tau_gdop,
    tau_strips,
)

__all__ = ["BLOCK", "GDOP", "PARALLELOGRAM", "STRIPS", "best_subset", "subset_tau"]

#: Points per block: a block's per-marker float32 normals stay in the L1/L2 cache.
BLOCK = 256


@numba.njit(cache=True, error_model="numpy")
def _block_normals(px, py, mx, my, vis, rel, ab, tan_xi, lo, w, gx, gy, hx, hy, scale):
    """Compute float64 normals g = u / rho, h = t / (r tan xi) of one block (NaN where hidden).

    ``scale`` = the smallest half-width seen from each point (inf where nothing is visible).

    Branch-free (selects, numpy error model) so that the loops vectorise.
    """
    nan = np.nan
    for c in range(w):
        scale[c] = np.inf
    for m in range(mx.size):
        mxm, mym = mx[m], my[m]
        for c in range(w):
            dx, dy = px[lo + c] - mxm, py[lo + c] - mym
            r2 = dx * dx + dy * dy
            r = math.sqrt(r2)
            rho = rel * r + ab
            f = 1.0 / (rho * r)
            ok = vis[m, lo + c] & (r2 > 0.0)
            gx[m, c] = dx * f if ok else nan
            gy[m, c] = dy * f if ok else nan
            scale[c] = min(scale[c], rho) if ok else scale[c]
        if tan_xi > 0.0:
            for c in range(w):
                dx, dy = px[lo + c] - mxm, py[lo + c] - mym
                r2 = dx * dx + dy * dy
                bw = math.sqrt(r2) * tan_xi
                f = 1.0 / (bw * math.sqrt(r2))
                ok = vis[m, lo + c] & (r2 > 0.0)
                hx[m, c] = -dy * f if ok else nan
                hy[m, c] = dx * f if ok else nan
                scale[c] = min(scale[c], bw) if ok else scale[c]
        else:
            for c in range(w):
                hx[m, c] = 0.0 if gx[m, c] == gx[m, c] else nan
                hy[m, c] = hx[m, c]


@numba.njit(cache=True, error_model="numpy")
def _block_scale(px, py, mx, my, vis, rel32, ab32, tan32, lo, w, r, scale):
    """Ranges ``r`` (M, BLOCK) and per-point scale: the smallest half-width seen (float32)."""
    bearing = tan32 > 0
    # Row views: numba cannot tell that ``lo + c`` is not negative, and the wraparound select
    # on such an index turns every load into a scalar one (the loops no longer vectorise).
    pxb, pyb = px[lo:lo + w], py[lo:lo + w]
    for c in range(BLOCK):
        scale[c] = np.inf
    for m in range(mx.size):
        mxm, mym = mx[m], my[m]
        vb, rm = vis[m, lo:lo + w], r[m]
        for c in range(w):
            dx, dy = np.float32(pxb[c] - mxm), np.float32(pyb[c] - mym)
            rr = math.sqrt(dx * dx + dy * dy)
            rm[c] = rr
            half = rel32 * rr + ab32
            half = min(half, rr * tan32) if bearing else half
            ok = vb[c] & (rr > 0)
            scale[c] = min(scale[c], half) if ok else scale[c]


@numba.njit(cache=True, error_model="numpy")
def _planes_parallelogram(px, py, mx, my, vis, rel, ab, lo, w, dxb, dyb, scale, a0, a1, a2):
    """Fill float32 planes (x, y, |g|^2) of ``g = s u / rho`` for one block.

    ``s`` = the smallest half-width seen from the point, so every entry is at most 1. NaN where
    hidden and in the padding beyond ``w``. The planes only rank candidates; ``dxb``, ``dyb``
    (BLOCK,) are scratch. One pass computes the unscaled normals and the scale (one square root
    and one division per marker and point), a second applies the scale.
    """
    nan, inf, one = np.float32(np.nan), np.float32(np.inf), np.float32(1.0)
    rel32, ab32 = np.float32(rel), np.float32(ab)
    pxb, pyb = px[lo:lo + w], py[lo:lo + w]  # views: see _block_scale
    for c in range(BLOCK):
        scale[c] = inf
    for m in range(mx.size):
        mxm, mym = mx[m], my[m]
        vb, x, y = vis[m, lo:lo + w], a0[m], a1[m]
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
            x[c] = dx * f if ok else nan
            y[c] = dy * f if ok else nan
            scale[c] = min(scale[c], rho) if ok else scale[c]
    for m in range(mx.size):
        x, y, q = a0[m], a1[m], a2[m]
        for c in range(w):
            xs, ys = x[c] * scale[c], y[c] * scale[c]
            x[c], y[c], q[c] = xs, ys, xs * xs + ys * ys
        for c in range(w, BLOCK):
            x[c], y[c], q[c] = nan, nan, nan


@numba.njit(cache=True, error_model="numpy")
def _planes_gdop(px, py, mx, my, vis, rel, ab, tan_xi, lo, w, r, scale, a0, a1, a2):
    """Fill float32 planes (xx, xy, yy) of the information ``s^2 (g g^T + h h^T)`` per marker.

    Scaled as in :func:`_planes_parallelogram`; ``h`` = 0 without bearings.
    """
    nan = np.float32(np.nan)
    rel32, ab32, tan32 = np.float32(rel), np.float32(ab), np.float32(tan_xi)
    bearing = tan_xi > 0.0
    _block_scale(px, py, mx, my, vis, rel32, ab32, tan32, lo, w, r, scale)
    pxb, pyb = px[lo:lo + w], py[lo:lo + w]  # views: see _block_scale
    for m in range(mx.size):
        mxm, mym = mx[m], my[m]
        vb, rm, sxx, sxy, syy = vis[m, lo:lo + w], r[m], a0[m], a1[m], a2[m]
        for c in range(w):
            dx, dy = np.float32(pxb[c] - mxm), np.float32(pyb[c] - mym)
            rr = rm[c]
            ok = vb[c] & (rr > 0)
            f = scale[c] / ((rel32 * rr + ab32) * rr)
            f2 = scale[c] / (rr * tan32 * rr) if bearing else np.float32(0.0)
            ux, uy, vx, vy = dx * f, dy * f, -dy * f2, dx * f2
            sxx[c] = ux * ux + vx * vx if ok else nan
            sxy[c] = ux * uy + vx * vy if ok else nan
            syy[c] = uy * uy + vy * vy if ok else nan
        for c in range(w, BLOCK):
            sxx[c], sxy[c], syy[c] = nan, nan, nan


@numba.njit(cache=True)
def _take(better, new, old):
    return new if better else old


@numba.njit(cache=True, error_model="numpy")
def _sweep_parallelogram(subsets, a0, a1, a2, bn, bd, bs):
    """Best pair per point of the block; pairs are scored two per sweep to halve the traffic."""
    two = np.float32(2.0)
    nsub = subsets.shape[0]
    for s in range(0, nsub, 2):
        t = min(s + 1, nsub - 1)  # an odd count scores the last pair twice (harmless)
        i, j, k, m = subsets[s, 0], subsets[s, 1], subsets[t, 0], subsets[t, 1]
        xi, yi, qi, xj, yj, qj = a0[i], a1[i], a2[i], a0[j], a1[j], a2[j]
        xk, yk, qk, xm, ym, qm = a0[k], a1[k], a2[k], a0[m], a1[m], a2[m]
        ss, st = np.int32(s), np.int32(t)
        for c in range(BLOCK):
            det1 = xi[c] * yj[c] - yi[c] * xj[c]
            num1 = qi[c] + qj[c] + two * abs(xi[c] * xj[c] + yi[c] * yj[c])
            den1 = det1 * det1
            det2 = xk[c] * ym[c] - yk[c] * xm[c]
            num2 = qk[c] + qm[c] + two * abs(xk[c] * xm[c] + yk[c] * ym[c])
            den2 = det2 * det2
            n0, d0, s0 = bn[c], bd[c], bs[c]
            b1 = num1 * d0 < n0 * den1
            n0, d0, s0 = _take(b1, num1, n0), _take(b1, den1, d0), _take(b1, ss, s0)
            b2 = num2 * d0 < n0 * den2
            bn[c], bd[c], bs[c] = _take(b2, num2, n0), _take(b2, den2, d0), _take(b2, st, s0)


@numba.njit(cache=True, error_model="numpy")
def _sweep_gdop(subsets, a0, a1, a2, bn, bd, bs, sxx, sxy, syy):
    """Best subset per point of the block by lambda_max of the inverse information."""
    zero, two, four = np.float32(0.0), np.float32(2.0), np.float32(4.0)
    nsub, k = subsets.shape
    for s in range(nsub):
        m0 = subsets[s, 0]
        for c in range(BLOCK):
            sxx[c], sxy[c], syy[c] = a0[m0, c], a1[m0, c], a2[m0, c]
        for t in range(1, k):
            m = subsets[s, t]
            for c in range(BLOCK):
                sxx[c] += a0[m, c]
                sxy[c] += a1[m, c]
                syy[c] += a2[m, c]
        ss = np.int32(s)
        for c in range(BLOCK):
            tr = sxx[c] + syy[c]
            dt = sxx[c] * syy[c] - sxy[c] * sxy[c]
            num = tr + math.sqrt(max(tr * tr - four * dt, zero))
            den = two * dt
            better = num * bd[c] < bn[c] * den
            bn[c], bd[c] = _take(better, num, bn[c]), _take(better, den, bd[c])
            bs[c] = _take(better, ss, bs[c])


@numba.njit(cache=True, error_model="numpy")
def _sweep_strips(subsets, gx, gy, hx, hy, w, bearing, bs):
    """Best subset per point of the block by the strip-polygon diameter (float64, scalar)."""
    nsub, k = subsets.shape
    ns = 2 * k if bearing else k
    sx = np.empty(ns)
    sy = np.empty(ns)
    bv = np.full(w, np.inf)
    for s in range(nsub):
        for c in range(w):
            usable = True
            for t in range(k):
                m = subsets[s, t]
                if math.isnan(gx[m, c]):
                    usable = False
                    break
                sx[t], sy[t] = gx[m, c], gy[m, c]
                if bearing:
                    sx[k + t], sy[k + t] = hx[m, c], hy[m, c]
            if usable:
                v = strip_max_vertex_sq_k(sx, sy, ns)
                if v < bv[c]:
                    bv[c] = v
                    bs[c] = s


@numba.njit(cache=True, error_model="numpy")
def _tau_pairs(px, py, mx, my, subsets, rel, ab, lo, w, bs, ax, ay, bx, by, tau, best):
    """Write the chosen pair ``subsets[bs[c]]`` and its float64 tau for the block's points.

    A scalar pass gathers the pair's marker coordinates into ``ax, ay, bx, by`` (BLOCK,); the
    arithmetic (square roots, divisions) then runs in a vectorised loop.
    """
    bb, taub = best[lo:lo + w], tau[lo:lo + w]  # views: see _block_scale
    for c in range(w):
        s = bs[c]
        s0 = max(s, 0)
        i, j = subsets[s0, 0], subsets[s0, 1]
        ax[c], ay[c], bx[c], by[c] = mx[i], my[i], mx[j], my[j]
        bb[c, 0] = i if s >= 0 else -1
        bb[c, 1] = j if s >= 0 else -1
    pxb, pyb = px[lo:lo + w], py[lo:lo + w]
    for c in range(w):
        t = diagonal_of_offsets(pxb[c] - ax[c], pyb[c] - ay[c], pxb[c] - bx[c], pyb[c] - by[c], rel, ab)
        taub[c] = t if bs[c] >= 0 else np.inf


@numba.njit(cache=True)
def _store_best(best, p, subsets, s):
    """Write the marker indices of subset row ``s`` (or -1 when ``s < 0``) into ``best[p]``."""
    for t in range(best.shape[1]):
        best[p, t] = subsets[s, t] if s >= 0 else -1


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _blocks_parallelogram(b0, b1, px, py, mx, my, vis, rel, ab, subsets, tau, best):
    nm = mx.size
    dxb = np.empty(BLOCK, dtype=np.float32)
    dyb = np.empty(BLOCK, dtype=np.float32)
    scale = np.empty(BLOCK, dtype=np.float32)
    a0 = np.empty((nm, BLOCK), dtype=np.float32)
    a1 = np.empty((nm, BLOCK), dtype=np.float32)
    a2 = np.empty((nm, BLOCK), dtype=np.float32)
    bn = np.empty(BLOCK, dtype=np.float32)
    bd = np.empty(BLOCK, dtype=np.float32)
    bs = np.empty(BLOCK, dtype=np.int32)
    ax, ay, bx, by = np.empty(BLOCK), np.empty(BLOCK), np.empty(BLOCK), np.empty(BLOCK)
    for blk in range(b0, b1):
        lo = blk * BLOCK
        w = min(BLOCK, px.size - lo)
        _planes_parallelogram(px, py, mx, my, vis, rel, ab, lo, w, dxb, dyb, scale, a0, a1, a2)
        bn[:], bd[:], bs[:] = 1.0, 0.0, -1
        _sweep_parallelogram(subsets, a0, a1, a2, bn, bd, bs)
        _tau_pairs(px, py, mx, my, subsets, rel, ab, lo, w, bs, ax, ay, bx, by, tau, best)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _blocks_gdop(b0, b1, px, py, mx, my, vis, rel, ab, tan_xi, subsets, chi2_ppf, tau, best):
    nm = mx.size
    k = subsets.shape[1]
    r = np.empty((nm, BLOCK), dtype=np.float32)
    scale = np.empty(BLOCK, dtype=np.float32)
    a0 = np.empty((nm, BLOCK), dtype=np.float32)
    a1 = np.empty((nm, BLOCK), dtype=np.float32)
    a2 = np.empty((nm, BLOCK), dtype=np.float32)
    bn = np.empty(BLOCK, dtype=np.float32)
    bd = np.empty(BLOCK, dtype=np.float32)
    bs = np.empty(BLOCK, dtype=np.int32)
    sxx = np.empty(BLOCK, dtype=np.float32)
    sxy = np.empty(BLOCK, dtype=np.float32)
    syy = np.empty(BLOCK, dtype=np.float32)
    tx, ty, tb = np.empty(2 * k), np.empty(2 * k), np.empty(2 * k)
    for blk in range(b0, b1):
        lo = blk * BLOCK
        w = min(BLOCK, px.size - lo)
        _planes_gdop(px, py, mx, my, vis, rel, ab, tan_xi, lo, w, r, scale, a0, a1, a2)
        bn[:], bd[:], bs[:] = 1.0, 0.0, -1
        _sweep_gdop(subsets, a0, a1, a2, bn, bd, bs, sxx, sxy, syy)
        for c in range(w):
            s = bs[c]
            _store_best(best, lo + c, subsets, s)
            tau[lo + c] = tau_gdop(px[lo + c], py[lo + c], mx, my, subsets[s], rel, ab, tan_xi, chi2_ppf,
                                   tx, ty, tb) if s >= 0 else np.inf


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _blocks_strips(b0, b1, px, py, mx, my, vis, rel, ab, tan_xi, subsets, tau, best):
    nm = mx.size
    k = subsets.shape[1]
    gx, gy = np.empty((nm, BLOCK)), np.empty((nm, BLOCK))
    hx, hy = np.empty((nm, BLOCK)), np.empty((nm, BLOCK))
    scale = np.empty(BLOCK)
    bs = np.empty(BLOCK, dtype=np.int32)
    tx, ty, tb = np.empty(2 * k), np.empty(2 * k), np.empty(2 * k)
    for blk in range(b0, b1):
        lo = blk * BLOCK
        w = min(BLOCK, px.size - lo)
        _block_normals(px, py, mx, my, vis, rel, ab, tan_xi, lo, w, gx, gy, hx, hy, scale)
        bs[:] = -1
        _sweep_strips(subsets, gx, gy, hx, hy, w, tan_xi > 0.0, bs)
        for c in range(w):
            s = bs[c]
            _store_best(best, lo + c, subsets, s)
            tau[lo + c] = tau_strips(px[lo + c], py[lo + c], mx, my, subsets[s], rel, ab, tan_xi,
                                     tx, ty, tb) if s >= 0 else np.inf


def best_subset(px, py, mx, my, vis, rel, ab, tan_xi, model, subsets, chi2_ppf, tau, best):
    """Best subset and its error for every point.

    Parameters
    ----------
    px, py : ndarray, shape (N,)
        Point coordinates [m].
    mx, my : ndarray, shape (M,)
        Marker coordinates [m].
    vis : ndarray of bool, shape (M, N)
        Marker visible from point.
    rel, ab : float
        Range bound ``rho = rel * r + ab`` [m/m, m].
    tan_xi : float
        tan of the bearing bound (0 = ranges only; used by STRIPS and GDOP).
    model : int
        PARALLELOGRAM (subsets must be pairs), STRIPS or GDOP.
    subsets : ndarray of int64, shape (C, k)
        Candidate marker subsets, C >= 1.
    chi2_ppf : float
        ``chi2.ppf(p, 2)`` for GDOP.
    tau : ndarray, shape (N,)
        Output: error of the best subset [m]; inf where no subset is usable.
    best : ndarray of int64, shape (N, k)
        Output: marker indices of the chosen subset (a row of ``subsets``), -1 where none.
    """
    nblk = (px.size + BLOCK - 1) // BLOCK
    if model == PARALLELOGRAM:
        kernel, args = _blocks_parallelogram, (px, py, mx, my, vis, rel, ab, subsets, tau, best)
    elif model == GDOP:
        kernel, args = _blocks_gdop, (px, py, mx, my, vis, rel, ab, tan_xi, subsets, chi2_ppf, tau, best)
    else:
        kernel, args = _blocks_strips, (px, py, mx, my, vis, rel, ab, tan_xi, subsets, tau, best)
    # Each model is its own kernel: a process compiles (or loads) only the models it uses.
    run_ranges(kernel, nblk, args, min_chunk=8)
