"""The PEF models for one marker subset at one point, in float64 (numba scalar functions).

The block kernels of :mod:`planner.pef.kernels` rank candidate subsets in float32 and then
recompute the winner's tau here; :func:`subset_tau` is also the entry point for callers that
score single subsets (e.g. marker placement). Model codes: PARALLELOGRAM, STRIPS, GDOP.
"""

from __future__ import annotations

import math

import numpy as np

from estimators.fault.linearized import info_lambda_max_inv_k, strip_max_vertex_sq_k
from jit import compiled

PARALLELOGRAM, STRIPS, GDOP = 0, 1, 2


@compiled.njit(cache=True, error_model="numpy")
def _fill_strips(px, py, mx, my, sub, rel, ab, tan_xi, nx, ny, b):
    """Fill unit normals and half-widths of the strips of ``sub`` at (px, py).

    Returns their count (k, or 2k with the tangential bearing strips); 0 when the point is on a
    marker.
    """
    k = sub.size
    ns = 2 * k if tan_xi > 0.0 else k
    for t in range(k):
        dx, dy = px - mx[sub[t]], py - my[sub[t]]
        r = math.sqrt(dx * dx + dy * dy)
        if r == 0.0:
            return 0
        nx[t], ny[t], b[t] = dx / r, dy / r, rel * r + ab
        if ns > k:
            nx[k + t], ny[k + t], b[k + t] = -dy / r, dx / r, r * tan_xi
    return ns


@compiled.njit(cache=True, error_model="numpy")
def diagonal_of_offsets(d1x, d1y, d2x, d2y, rel, ab):
    """Long diagonal [m] of the parallelogram of two markers seen at offsets ``d = point - marker``.

    ``(2/sin a) sqrt(rho1^2 + rho2^2 + 2 rho1 rho2 |cos a|)`` (:mod:`estimators.fault.linearized`) with
    ``sin a = |d1 x d2| / (r1 r2)`` and ``cos a = d1.d2 / (r1 r2)``: two divisions instead of six.
    inf when the point is on a marker or the markers are collinear with it. Branch-free, so a
    loop over points calling it vectorises.
    """
    r1, r2 = math.sqrt(d1x * d1x + d1y * d1y), math.sqrt(d2x * d2x + d2y * d2y)
    rho1, rho2 = rel * r1 + ab, rel * r2 + ab
    rr = r1 * r2
    sn = abs(d1x * d2y - d1y * d2x)
    cs = abs(d1x * d2x + d1y * d2y) / rr
    tau = 2.0 * rr / sn * math.sqrt(rho1 * rho1 + rho2 * rho2 + 2.0 * rho1 * rho2 * cs)
    return np.inf if (r1 == 0.0) | (r2 == 0.0) | (sn == 0.0) else tau


@compiled.njit(cache=True, error_model="numpy")
def tau_parallelogram(px, py, mx, my, sub, rel, ab):
    """Long diagonal [m] of the parallelogram of the pair ``sub`` (2,) at (px, py), float64."""
    return diagonal_of_offsets(px - mx[sub[0]], py - my[sub[0]], px - mx[sub[1]], py - my[sub[1]], rel, ab)


@compiled.njit(cache=True, error_model="numpy")
def tau_gdop(px, py, mx, my, sub, rel, ab, tan_xi, chi2_ppf, nx, ny, b):
    """Major axis [m] of the p-level ellipse of subset ``sub`` at (px, py), float64.

    ``2 sqrt(chi2_ppf lambda_max(P))``, a diameter like the other models' tau (``nx, ny, b``:
    scratch >= 2k).
    """
    ns = _fill_strips(px, py, mx, my, sub, rel, ab, tan_xi, nx, ny, b)
    if ns == 0:
        return np.inf
    sxx, sxy, syy = 0.0, 0.0, 0.0
    for t in range(ns):
        w = 1.0 / (b[t] * b[t])
        sxx += w * nx[t] * nx[t]
        sxy += w * nx[t] * ny[t]
        syy += w * ny[t] * ny[t]
    # sigma = rho / 3: P = B^-1 / 9; the factor 2 turns the semi-major axis into the diameter.
    return 2.0 * math.sqrt(chi2_ppf * info_lambda_max_inv_k(sxx, sxy, syy) / 9.0)


@compiled.njit(cache=True, error_model="numpy")
def tau_strips(px, py, mx, my, sub, rel, ab, tan_xi, nx, ny, b):
    """Strip-polygon diameter [m] of subset ``sub`` at (px, py), float64 (``nx, ny, b``: scratch >= 2k)."""
    ns = _fill_strips(px, py, mx, my, sub, rel, ab, tan_xi, nx, ny, b)
    if ns == 0:
        return np.inf
    for t in range(ns):
        nx[t] /= b[t]
        ny[t] /= b[t]
    return 2.0 * math.sqrt(strip_max_vertex_sq_k(nx, ny, ns))


@compiled.njit(cache=True, error_model="numpy")
def subset_tau(model, px, py, mx, my, sub, rel, ab, tan_xi, chi2_ppf, nx, ny, b):
    """Return the model's error [m] of marker subset ``sub`` (k,) at point (px, py), in float64.

    Dispatches to :func:`tau_parallelogram` (which ignores bearings), :func:`tau_gdop` or
    :func:`tau_strips`; ``nx``, ``ny``, ``b`` are scratch arrays of length >= 2k. Visibility is
    not checked here; inf for a degenerate geometry.
    """
    if model == PARALLELOGRAM:
        return tau_parallelogram(px, py, mx, my, sub, rel, ab)
    if model == GDOP:
        return tau_gdop(px, py, mx, my, sub, rel, ab, tan_xi, chi2_ppf, nx, ny, b)
    return tau_strips(px, py, mx, my, sub, rel, ab, tan_xi, nx, ny, b)


# numba keys a cache on its own file only: flush the kernels above when a file they inline changed
compiled.keep_fresh(__name__)
