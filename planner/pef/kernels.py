"""numba kernels of the PEF: the best marker subset for each point under a linearised model.

One kernel, :func:`best_subset`, serves arbitrary points; :func:`best_subset_grid` gives the
same values on the cell centres of a grid. Points are processed in blocks of :data:`BLOCK`
(the parallelogram model: :mod:`planner.pef.pairs`, which walks a grid in square tiles and
prunes pairs that cannot win a tile); for each block the
scaled range normals ``g = u / rho`` (and with bearings the tangential ``h = t / (r tan xi)``)
of every marker are computed once, then every candidate subset is scored across the block's
points in a branch-free inner loop that vectorises (SIMD across points; threads across
blocks, :mod:`planner.pef.threads`).

Candidates are compared as fractions ``num / den`` by cross-multiplication
(``num * best_den < best_num * den``), with neither square root nor division:

- parallelogram: ``num = |g1|^2 + |g2|^2 + 2 |g1.g2|``, ``den = det(g1, g2)^2``; the squared
  long diagonal is ``4 num / den`` (see :mod:`estimators.fault.linearized`);
- gdop: ``num = T + sqrt(T^2 - 4 D)``, ``den = 2 D`` with trace T and determinant D of the
  information ``B = sum g g^T``, i.e. ``lambda_max(B^-1)``, monotone in the reported major axis
  ``2 sqrt(chi2.ppf(p, 2) lambda_max(B^-1) / 9)``;
- strips: the largest squared vertex norm of the strip polygon, a scalar O(s^3) loop per point
  and subset in float64.

Selection precision: for the parallelogram and gdop models the comparison runs in float32 (twice
the SIMD width); the normals of a point are first scaled by the smallest half-width seen from
it, so every number is O(1) and no product overflows. The winner's tau is then recomputed in
float64 from scratch (:mod:`planner.pef.scalar`), so tau is exact for the chosen subset and within
~1e-6 relative of the float64 minimum.

A marker not visible from a point gets NaN normals: every comparison with NaN is false, so a
subset holding it is never chosen; a parallel pair has ``den = 0`` and is never chosen either;
the initial best is ``1 / 0`` (infinite).
"""

from __future__ import annotations

import math

import numpy as np

from estimators.fault.linearized import strip_max_vertex_sq_k
from jit import compiled
from planner.pef import pairs as pef_pairs
from planner.pef.pointblocks import blocks_points_local
from planner.pef.scalar import (
    GDOP,
    PARALLELOGRAM,
    STRIPS,
    subset_tau,
    tau_gdop,
    tau_strips,
)
from planner.pef.threads import run_ranges

__all__ = ["BLOCK", "GDOP", "PARALLELOGRAM", "STRIPS", "best_subset", "best_subset_grid", "subset_tau"]

#: Points per block: a block's per-marker float32 normals stay in the L1/L2 cache.
BLOCK = 256


@compiled.njit(cache=True, error_model="numpy")
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


@compiled.njit(cache=True, error_model="numpy")
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


@compiled.njit(cache=True, error_model="numpy")
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


@compiled.njit(cache=True)
def _take(better, new, old):
    return new if better else old


@compiled.njit(cache=True, error_model="numpy")
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


@compiled.njit(cache=True, error_model="numpy")
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


@compiled.njit(cache=True)
def _store_best(best, p, subsets, s):
    """Write the marker indices of subset row ``s`` (or -1 when ``s < 0``) into ``best[p]``."""
    for t in range(best.shape[1]):
        best[p, t] = subsets[s, t] if s >= 0 else -1


@compiled.njit(cache=True, nogil=True, error_model="numpy")
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


@compiled.njit(cache=True, nogil=True, error_model="numpy")
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


def _check_outputs(tau, best):
    # The kernels write through flattened views: a reshape of a non-contiguous array would be a
    # copy, and the results would be lost without a word.
    if not (tau.flags.c_contiguous and best.flags.c_contiguous):
        raise ValueError("best_subset: tau and best must be C-contiguous output arrays")


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
    _check_outputs(tau, best)
    nblk = (px.size + BLOCK - 1) // BLOCK
    if model == PARALLELOGRAM:
        nblk = (px.size + pef_pairs.BLOCK - 1) // pef_pairs.BLOCK
        kernel = blocks_points_local  # pef_pairs.blocks_points on the markers each block sees
        args = (px, py, mx, my, vis.reshape(-1), rel, ab, subsets, pef_pairs.MARGIN, tau, best.reshape(-1))
    elif model == GDOP:
        kernel, args = _blocks_gdop, (px, py, mx, my, vis, rel, ab, tan_xi, subsets, chi2_ppf, tau, best)
    else:
        kernel, args = _blocks_strips, (px, py, mx, my, vis, rel, ab, tan_xi, subsets, tau, best)
    # Each model is its own kernel: a process compiles (or loads) only the models it uses.
    run_ranges(kernel, nblk, args, min_chunk=8)


def best_subset_grid(x, y, mx, my, vis, rel, ab, tan_xi, model, subsets, chi2_ppf, tau, best):
    """:func:`best_subset` on the cell centres of a grid, the same values as on the flattened points.

    Parameters
    ----------
    x : ndarray, shape (nx,)
        Cell-centre x coordinates [m].
    y : ndarray, shape (ny,)
        Cell-centre y coordinates [m].
    vis : ndarray of bool, shape (M, ny, nx)
        Marker visible from cell centre.
    tau : ndarray, shape (ny, nx)
        Output: error of the best subset [m]; inf where no subset is usable.
    best : ndarray of int64, shape (ny, nx, k)
        Output: marker indices of the chosen subset, -1 where none.
    mx, my, rel, ab, tan_xi, model, subsets, chi2_ppf
        As in :func:`best_subset`.

    Notes
    -----
    The parallelogram kernel walks the grid in square tiles, whose pair pruning is much sharper
    than on row segments (:mod:`planner.pef.pairs`); the choice per cell is the same. The other
    models run on the flattened points.
    """
    _check_outputs(tau, best)
    if model == PARALLELOGRAM:
        args = (x, y, mx, my, vis.reshape(-1), rel, ab, subsets, pef_pairs.MARGIN, tau.reshape(-1), best.reshape(-1))
        run_ranges(pef_pairs.blocks_grid, pef_pairs.tile_count(x.size, y.size), args, min_chunk=8)
        return
    px, py = np.tile(x, y.size), np.repeat(y, x.size)
    best_subset(px, py, mx, my, vis.reshape(vis.shape[0], -1), rel, ab, tan_xi, model, subsets, chi2_ppf,
                tau.reshape(-1), best.reshape(-1, best.shape[-1]))


# numba keys a cache on its own file only: flush the kernels above when a file they inline changed
compiled.keep_fresh(__name__)
