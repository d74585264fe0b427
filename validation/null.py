"""The bounded-noise null model of a snapshot fix, for the ``bound`` and ``tightness`` checks.

Under the declared model a fix's range errors are independent and uniform in ``+-rho_i``
(bearing errors in ``+-xi``). Linearised at the true position R, with unit vectors
``u_i = (R - M_i) / r_i`` as the rows of ``H``, the weighted least-squares error is

    delta = L e,   L = (H^T W H)^-1 H^T W,   W = diag(1 / b_j^2),

where ``e_j`` is uniform in ``+-b_j`` (``b = rho`` for a range row). With bearings the fix
estimates the heading too (:func:`estimators.snapshot.snapshot_fix`): the unknowns are
``(x, y, theta)``, a range row is ``(u_i, 0)`` and a bearing row, scaled to metres, is
``(t_i, -r_i)`` (``t_i`` the unit normal turned by 90 degrees, ``b = r_i xi``), and ``delta``
is the position part of the solution. Writing ``A = L diag(b)``, ``delta = A s`` with ``s``
uniform in the cube ``[-1, 1]^n``.

What tau means per model, and why ``error <= tau`` follows:

- ``parallelogram`` / ``strips``: tau is the *diameter* of the linearised fault area
  ``F = {d : |g_j . d| <= b_j}`` centred at the truth (the long diagonal for two markers).
  With k = 2 ranges the LS point is the exact intersection, ``delta = H^-1 e`` lies in F, and
  F is centrally symmetric about 0, so ``|delta| <= tau / 2``. With k > 2 the LS point need
  not lie in F; :func:`worst_case_ratio` computes ``max |A s|`` over the cube's vertices (the
  maximum of a convex function on a box is at a vertex) to show the margin per fix.
- ``exact``: tau is the exact fault-area diameter of noise-free ranges, within the
  linearisation of the parallelogram diagonal for small ``rho / r``: the same argument.
- ``gdop``: tau is the major axis of a probability-p ellipse for gaussian errors, a diameter
  like the others but not a bound (not used here).

The real fix also carries each earlier range to the fix time by odometry; that shift error
is not in this null model, nor is the odometry's error in turning an earlier bearing into the
last one's frame. They only make observed errors larger, so they cannot make the tightness
check fail, and the ``bound`` check states it. (The realised fault area of a fix with
bearings uses no heading at all, :mod:`estimators.fault.exact`; this model is of the
least-squares point, which estimates the heading.)
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from scenarios.schema import SensorSpec

TARGET_SAMPLES = 400_000
"""Simulated fixes in total (draws per fix times fixes); ~20 ms of numpy for k = 2."""
MIN_DRAWS, MAX_DRAWS = 200, 4000
"""Draws per fix: enough that the tail sums of :func:`tightness_threshold` stay within a few
per cent (-ln(alpha) * draws exceedances are counted at the threshold)."""
MAX_WORST_ROWS = 12
"""Enumerate the 2^n cube vertices only up to this many rows."""


def error_maps(marker_xy: np.ndarray, truth: np.ndarray, sensor: SensorSpec) -> np.ndarray:
    """Return the linear map ``A`` from unit-cube noise to the LS position error of each fix.

    Parameters
    ----------
    marker_xy : ndarray, shape (F, k, 2)
        Positions of each fix's markers [m].
    truth : ndarray, shape (F, 2)
        True position of each fix [m].
    sensor : SensorSpec
        The declared sensor (range bounds; bearings when ``bearing_error > 0``).

    Returns
    -------
    ndarray, shape (F, 2, n)
        ``A = L diag(b)`` [m], with n = k rows (2k with bearings); NaN for a singular geometry.
    """
    diff = truth[:, None, :] - marker_xy
    r = np.hypot(diff[..., 0], diff[..., 1])
    u = diff / r[..., None]
    rows, bounds = [u], [np.asarray(sensor.range_bound(r), dtype=float)]
    if sensor.uses_bearing:
        # The fix estimates the heading with the position (estimators.snapshot): a third
        # column, the bearing residual r * d(beta) turning by -r per radian of heading.
        rows = [np.concatenate([u, np.zeros_like(r)[..., None]], axis=-1),
                np.stack([-u[..., 1], u[..., 0], -r], axis=-1)]
        bounds.append(r * sensor.bearing_error)
    g = np.concatenate(rows, axis=1)              # (F, n, m) scaled rows, m = 2 or 3 unknowns
    b = np.concatenate(bounds, axis=1)            # (F, n) error bounds [m]
    gw = g / b[..., None] ** 2                    # W H, W = diag(1 / b^2)
    info = np.einsum("fni,fnj->fij", g, gw)       # H^T W H
    # invertible in the position: the Schur complement of the heading (if any) is regular
    pos = info[:, :2, :2]
    if info.shape[1] == 3:
        pos = pos - np.einsum("fi,fj->fij", info[:, :2, 2], info[:, :2, 2]) / info[:, 2, 2, None, None]
    det = pos[:, 0, 0] * pos[:, 1, 1] - pos[:, 0, 1] ** 2
    scale = np.einsum("fii->f", pos) ** 2
    ok = det > 1e-12 * scale
    inv = np.full_like(info, np.nan)
    inv[ok] = np.linalg.inv(info[ok])
    lmap = np.einsum("fij,fnj->fin", inv, gw)[:, :2]  # position rows of (H^T W H)^-1 H^T W, (F, 2, n)
    return lmap * b[:, None, :]


def simulate_ratios(amap: np.ndarray, tau: np.ndarray, rng: np.random.Generator,
                    draws: int | None = None) -> np.ndarray:
    """Draw the ratio ``|LS error| / tau`` of each fix under the uniform bounded-noise model.

    Parameters
    ----------
    amap : ndarray, shape (F, 2, n)
        From :func:`error_maps`.
    tau : ndarray, shape (F,)
        The model's predicted error of each fix [m] (finite, > 0).
    rng : numpy.random.Generator
        The only source of randomness.
    draws : int, optional
        Draws per fix; default ``TARGET_SAMPLES / F`` clipped to ``[MIN_DRAWS, MAX_DRAWS]``.

    Returns
    -------
    ndarray, shape (F, draws)
        Simulated ratios [-].
    """
    f, _, n = amap.shape
    if draws is None:
        draws = int(np.clip(math.ceil(TARGET_SAMPLES / max(f, 1)), MIN_DRAWS, MAX_DRAWS))
    out = np.empty((f, draws))
    chunk = max(1, TARGET_SAMPLES // draws)
    for lo in range(0, f, chunk):
        hi = min(lo + chunk, f)
        s = rng.uniform(-1.0, 1.0, size=(hi - lo, draws, n))
        delta = np.einsum("fin,fdn->fdi", amap[lo:hi], s)
        out[lo:hi] = np.hypot(delta[..., 0], delta[..., 1]) / tau[lo:hi, None]
    return out


def worst_case_ratio(amap: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Largest ``|LS error| / tau`` the bounded model allows for each fix (cube vertices).

    Parameters
    ----------
    amap : ndarray, shape (F, 2, n)
        From :func:`error_maps`.
    tau : ndarray, shape (F,)
        Predicted error [m].

    Returns
    -------
    ndarray, shape (F,)
        ``max_s |A s| / tau`` over ``s`` in ``{-1, 1}^n`` (0.5 for two ranges, see the module
        docstring); NaN when n > ``MAX_WORST_ROWS``.
    """
    f, _, n = amap.shape
    if n > MAX_WORST_ROWS:
        return np.full(f, np.nan)
    # s and -s give the same norm: fix the first sign.
    signs = np.array([(1.0, *rest) for rest in itertools.product((1.0, -1.0), repeat=n - 1)])
    delta = np.einsum("fin,vn->fvi", amap, signs)
    return np.hypot(delta[..., 0], delta[..., 1]).max(axis=1) / tau


def tightness_threshold(ratios: np.ndarray, alpha: float) -> float:
    """Return the largest f with ``P(max_i ratio_i < f) <= alpha`` for independent fixes.

    ``P(max < f) = prod_i F_i(f)`` with ``F_i`` the CDF of fix i's ratio, estimated from its
    draws as ``(count(ratio < f) + 1) / (draws + 1)``: the +1 keeps the logarithm finite and
    biases ``F_i`` up, i.e. f down, so the false-alarm probability stays at most ``alpha`` up
    to the Monte-Carlo error of the tail counts.

    Parameters
    ----------
    ratios : ndarray, shape (F, draws)
        From :func:`simulate_ratios`.
    alpha : float
        False-alarm probability of the tightness check.

    Returns
    -------
    float
        The threshold f [-] (0 when even the smallest draw gives a larger probability:
        too few fixes to test tightness at this ``alpha``).
    """
    f, draws = ratios.shape
    pooled = np.sort(ratios, axis=None)
    log_alpha = math.log(alpha)

    def log_p_max_below(x: float) -> float:
        counts = (ratios < x).sum(axis=1)
        return float(np.sum(np.log((counts + 1.0) / (draws + 1.0))))

    if log_p_max_below(pooled[0]) > log_alpha:
        return 0.0
    # The probability grows with x: bisect for the last pooled value at which it is <= alpha.
    lo, hi = 0, pooled.size - 1
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if log_p_max_below(pooled[mid]) <= log_alpha:
            lo = mid
        else:
            hi = mid - 1
    return float(pooled[lo])
