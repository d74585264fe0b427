"""The parallelogram PEF on points, block by block, on the markers each block sees.

The points path's counterpart of :mod:`planner.pef.gridtiles`: a block of :data:`BLOCK`
consecutive points keeps only the markers visible from one of its points, so the pruned pair
sweep (:func:`planner.pef.pairs._block`) runs over a few markers instead of all of them, with
the same result as :func:`planner.pef.pairs.blocks_points`.
"""

from __future__ import annotations

import numpy as np

from jit import compiled
from planner.pef.pairs import BLOCK, _block, _scratch


@compiled.njit(cache=True, nogil=True, error_model="numpy")
def blocks_points_local(b0, b1, px, py, mx, my, vis, rel, ab, subsets, margin, tau, best):
    """:func:`planner.pef.pairs.blocks_points` on each block's visible markers only.

    Same arguments and results: blocks of :data:`BLOCK` consecutive points; ``vis`` (M * N,),
    ``best`` (2 N,) flattened. Each block keeps the markers visible from one of its points
    and the rows of ``subsets`` among them, in their order (so the pruned sweep picks what it
    picks on all rows: a pair holding an unseen marker never wins), and the previous block's
    winners seed its pruning as rows of ``subsets``.
    """
    nm, npt, nsub = mx.size, px.size, subsets.shape[0]
    sc, _, _, visb, _, _ = _scratch(nm, nsub)
    cand = sc[12]
    gm = np.empty(nm, dtype=np.int64)
    local_of = np.full(nm, -1, dtype=np.int64)
    mxl, myl = np.empty(nm), np.empty(nm)
    lsub = np.empty((nsub, 2), dtype=np.int64)
    grow = np.empty(nsub, dtype=np.int64)            # subsets row of each local row
    lrow = np.full(nsub, -1, dtype=np.int64)         # local row of a subsets row, -1 if absent
    prev = np.empty(cand.size, dtype=np.int64)
    nprev = 0
    for blk in range(b0, b1):
        lo = blk * BLOCK
        w = min(BLOCK, npt - lo)
        nl = 0
        for m in range(nm):
            seen = False
            row = vis[m * npt + lo:m * npt + lo + w]
            for c in range(w):
                seen |= row[c]
            if seen:
                gm[nl], local_of[m] = m, nl
                mxl[nl], myl[nl] = mx[m], my[m]
                nl += 1
        npair = 0
        for s in range(nsub):
            a, b = local_of[subsets[s, 0]], local_of[subsets[s, 1]]
            if a >= 0 and b >= 0:
                lsub[npair, 0], lsub[npair, 1] = a, b
                grow[npair], lrow[s] = s, npair
                npair += 1
        if npair == 0:
            for c in range(w):
                tau[lo + c] = np.inf
                best[2 * (lo + c)] = -1
                best[2 * (lo + c) + 1] = -1
            nprev = 0
        else:
            for j in range(nl):
                src, dst = gm[j] * npt + lo, j * BLOCK
                for c in range(w):
                    visb[dst + c] = vis[src + c]
            ncand = np.int64(0)
            for c in range(nprev):
                if lrow[prev[c]] >= 0:
                    cand[ncand] = lrow[prev[c]]
                    ncand += 1
            bestb = best[2 * lo:2 * (lo + w)]
            ncand = _block(px[lo:lo + w], py[lo:lo + w], visb, w, mxl[:nl], myl[:nl], rel, ab, lsub[:npair],
                           margin, ncand, sc, tau[lo:lo + w], bestb)
            for c in range(ncand):
                prev[c] = grow[cand[c]]
            nprev = ncand
            for i in range(2 * w):
                bestb[i] = gm[bestb[i]] if bestb[i] >= 0 else -1
        for t in range(npair):
            lrow[grow[t]] = -1
        for j in range(nl):
            local_of[gm[j]] = -1


# numba keys a cache on its own file only: flush the kernels above when a file they inline changed
compiled.keep_fresh(__name__)
