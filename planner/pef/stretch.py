"""How much a marker subset's error can grow over the stretch a path sample stands for.

A path is judged at samples ``spacing`` apart, each standing for the points within
``h = spacing / 2`` of it (:mod:`planner.routes.admissible`), whose markers stay in sight there.
Between samples tau of the sample's subset changes with the geometry (measured on random floors:
up to 3 % over 5 cm), so a sample just under the target says nothing of the points beside it.
:func:`subset_stretch` bounds that change: for a point p' with ``|p' - p| <= h``,
``tau_S(p') <= g_S(p) tau_S(p)``.

Derivation (linearised regions). The subset's strips at p: unit normals ``n_j`` (range: the
direction from the marker; with bearings also the tangential one), half-widths ``b_j`` (range
``rel r_j + ab``; bearing ``r_j tan xi``), ranges ``r_j``. Moving to p':

- a half-width grows by at most ``A_j b_j``: ``A_j = rel h / b_j`` (range), ``h / r_j`` (bearing);
- a normal turns by a chord ``|n_j' - n_j| <= c_j = h / (r_j - h)`` (for vectors a, b:
  ``|a/|a| - b/|b|| <= |a - b| / min(|a|, |b|)``); no bound when ``r_j <= h``.

An offset ``d`` in the region at p' has ``|n_j . d| <= |n_j' . d| + c_j |d| <= b_j (1 + A_j) +
c_j |d|`` and ``|d| <= tau' / 2`` (the region is centrally symmetric about the point), so the
region at p' lies in the region at p scaled by ``1 + A + B tau'``, ``A = max A_j``,
``B = max_j c_j / (2 b_j)``. A diameter scales with its region:
``tau' <= (1 + A + B tau') tau``, i.e. ``g = (1 + A) / (1 - B tau)`` (inf when ``B tau >= 1``).

- ``gdop``: the p-level ellipse ``d^T (sum_j n_j n_j^T / b_j^2) d <= kappa^2``,
  ``kappa = sqrt(chi2.ppf(p, 2)) / 3`` (:mod:`estimators.fault.linearized`). Minkowski's
  inequality on the weighted norm gives the same form with ``B = sqrt(sum_j c_j^2 / b_j^2) /
  (2 kappa)``.
- ``exact`` (annuli): the same strips, linearised at p, with ``|d| <= tau'`` (the fault area is
  not symmetric about the point): ``B = max_j c_j / b_j``. This holds to first order in
  ``tau / r``, as the linearised models themselves; the property test checks it on random floors.

The factor is about ``1 + h / r`` for near markers: 1.01-1.03 at 5 cm and a few metres.

The promise of a moving fix bounds the realised fault area at poses within ``Δ`` of the planned
ones by the same turning of strips, for annuli with their curvature
(:mod:`estimators.fault.perturbed`, range fixes); this module bounds each PEF model's own value
(bearings and the gdop ellipse included) over a path's stretch.
"""

from __future__ import annotations

import math

import numpy as np

from jit import compiled
from planner.pef.scalar import GDOP, PARALLELOGRAM, subset_tau


@compiled.njit(cache=True, error_model="numpy")
def subset_stretch(model, px, py, mx, my, sub, rel, ab, tan_xi, chi2_ppf, h, tau, symmetric):
    """Return ``g`` >= 1: tau of subset ``sub`` within ``h`` [m] of (px, py) is at most ``g tau`` (module docstring).

    ``model``: a :mod:`planner.pef.scalar` code (the parallelogram has no bearing strips);
    ``symmetric``: the region is centrally symmetric about the point (False for the exact
    model). inf where a marker is within ``h`` or the bound does not close (``B tau >= 1``);
    1 when ``tau`` is inf (nothing to bound).
    """
    if not tau < np.inf or h <= 0.0:
        return 1.0
    bearing = tan_xi > 0.0 and model != PARALLELOGRAM
    a_max, b_max, c2 = 0.0, 0.0, 0.0
    for t in range(sub.size):
        dx, dy = px - mx[sub[t]], py - my[sub[t]]
        r = math.sqrt(dx * dx + dy * dy)
        if r <= h:
            return np.inf
        c = h / (r - h)
        w = rel * r + ab
        a_max = max(a_max, rel * h / w)
        b_max = max(b_max, c / w)
        c2 += (c / w) ** 2
        if bearing:
            wb = r * tan_xi
            a_max = max(a_max, h / r)
            b_max = max(b_max, c / wb)
            c2 += (c / wb) ** 2
    if model == GDOP:
        b_max = math.sqrt(c2) / math.sqrt(chi2_ppf) * 3.0
    grow = b_max * (0.5 if symmetric else 1.0) * tau
    return (1.0 + a_max) / (1.0 - grow) if grow < 1.0 else np.inf


@compiled.njit(cache=True, error_model="numpy")
def best_stretch(model, px, py, mx, my, best, rel, ab, tan_xi, chi2_ppf, h, tau, symmetric, out):
    """Fill ``out`` (N,) with :func:`subset_stretch` of each point's subset ``best`` (N, k) (-1: none, g = 1)."""
    for i in range(px.size):
        if best[i, 0] < 0:
            out[i] = 1.0
        else:
            out[i] = subset_stretch(model, px[i], py[i], mx, my, best[i], rel, ab, tan_xi, chi2_ppf, h, tau[i],
                                    symmetric)


@compiled.njit(cache=True, error_model="numpy")
def min_stretched(model, px, py, mx, my, vis, subsets, rel, ab, tan_xi, chi2_ppf, h, out_tau, out_best):
    """Fill ``out_tau`` (N,) with the least ``g_S tau_S`` over the subsets (C, k) visible at each point.

    ``vis`` (M, N): markers seen over each point's stretch. A k-subset's region lies in each of
    its pairs' (more strips, or more information, only shrink it), so with k > 2 a subset's
    bound is also the least of its pairs' ``g_T tau_T``. ``out_best`` (N, k): the subset
    reaching it (-1 and inf where none is visible). Linearised models only (symmetric regions).
    """
    k = subsets.shape[1]
    nx, ny, b = np.empty(2 * k), np.empty(2 * k), np.empty(2 * k)
    pair = np.empty(2, dtype=np.int64)
    for i in range(px.size):
        out_tau[i] = np.inf
        out_best[i, :] = -1
        for s in range(subsets.shape[0]):
            sub = subsets[s]
            seen = True
            for t in range(k):
                if not vis[sub[t], i]:
                    seen = False
                    break
            if not seen:
                continue
            tau = subset_tau(model, px[i], py[i], mx, my, sub, rel, ab, tan_xi, chi2_ppf, nx, ny, b)
            v = tau * subset_stretch(model, px[i], py[i], mx, my, sub, rel, ab, tan_xi, chi2_ppf, h, tau, True)
            if k > 2:
                for a in range(k):
                    for z in range(a + 1, k):
                        pair[0], pair[1] = sub[a], sub[z]
                        tp = subset_tau(model, px[i], py[i], mx, my, pair, rel, ab, tan_xi, chi2_ppf, nx, ny, b)
                        vp = tp * subset_stretch(model, px[i], py[i], mx, my, pair, rel, ab, tan_xi, chi2_ppf, h,
                                                 tp, True)
                        v = min(v, vp)
            if v < out_tau[i]:
                out_tau[i] = v
                out_best[i, :] = sub


# numba keys a cache on its own file only: flush the kernels above when a file they inline changed
compiled.keep_fresh(__name__)
