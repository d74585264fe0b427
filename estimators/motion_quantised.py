"""EKF predict with each wheel's last encoder quantisation residuals in the state.

An encoder counts whole ticks of its wheel's rotation: the count converted to travel is
``r phi_k - q_k``, with ``q_k`` in ``[0, tick)`` the part of the rotation below the last tick
edge (``tick = 2 pi r / encoder_ticks`` [m]). The travel the odometry reports over step k is
therefore ``d_k = r (phi_k - phi_{k-1}) - q_k + q_{k-1}``: the quantisation error of a step is the
difference of two residuals, and over any window the errors telescope to ``q_start - q_end``.
Added to the process noise as white noise of variance ``tick^2 / 12`` per step (what
:func:`estimators.process_noise.wheel_variances` does) it grows without bound, at standstill too,
while the true error never exceeds one tick. With the residual a state, the error stays bounded.

A residual is the sawtooth of its wheel's phase, so residuals at two read boundaries between
which the wheel turned ``n + f`` ticks have the sawtooth's correlation ``1 - 6 f (1 - f)`` for a
phase uniform over a tick (:func:`read_correlation`), and a window's count error the variance
``f (1 - f) tick^2``: up to 1/4 tick^2 at f = 1/2, ~0 for a turn of whole ticks. The turns are
predicted from the wheel command (:mod:`estimators.encoder_phase`); the wheels fall behind their
command by a steady rate (~1e-4 of it in the simulation, 0.055 ticks a second on random-23-017),
so a turn over ``s`` physics steps is known to ``sigma s`` ticks, ``sigma`` the tracking error's
rate give or take (:func:`estimators.encoder_phase.sigma_per_step`): a rate error, whose error
grows with the lag, not with its square root. Averaged over it the correlation is that of the
count-error variance :func:`estimators.encoder_phase.count_error_var`, a proper covariance for
any set of boundaries (a mixture over the rate).

The state keeps each wheel's residuals at the last ``LAGS`` read boundaries, newest first. A
read's new residual is the best linear predictor from them, ``q_new = a . (q_0 .. q_{K-1}) + v``,
with the sawtooth covariances among those boundaries and the new one
(:func:`residual_predictor`); ``v`` is fresh, of the predictor's error variance. So every window
of up to ``LAGS`` reads has its count-error variance exact for its predicted turn, and windows
longer than that are the Gaussian chain's extrapolation of it. Why several: with one residual
(``LAGS`` 1, an AR(1) over a read, the model before this one) a wheel whose phase walks slowly
(random-23-000: -0.06 ticks a read) gets the mean 1/6 for windows whose turn sums to half a tick,
where the truth is 1/4 (up to 37 % low over 2-12 reads), and the filter's NEES was 3.11 at 200
runs; carrying the residual's harmonics by the command over every read (the model before that)
claimed the phase after the wheels had drifted from it (``docs/design.md`` §6).

The wheel's rotation over the step is ``u_w = d_w - q_w,0 + q_w,new``. With the relative
wheel-radius error ``e`` (optional state, :func:`estimators.motion.propagate_moments_biased`) the
wheels roll ``t_l = (1 - e) u_l`` and ``t_r = (1 + e) u_r`` plus the floor's random slip
(variance ``var_left``, ``var_right``), so ``pose' = f(pose, t_l, t_r)``, ``e' = e``, each
block shifts by one with ``q_new`` in front, ``P' = A P A^T + B W B^T``.

State layout: ``(x [m], y [m], theta [rad], [e [-]], left block, right block)``, a block the
``LAGS`` residuals ``(q_0, ..., q_{LAGS-1})`` [m], newest first: shape ``(3 + 2 LAGS,)`` or
``(4 + 2 LAGS,)``.
"""

from __future__ import annotations

import math

import numpy as np

from estimators.encoder_phase import LAGS, boundaries
from estimators.motion import _arc_terms, _jacobians_into
from jit import compiled

#: below this spread of a turn [ticks] :func:`read_correlation` averages near one whole tick
SIGMA_NEAR = 0.1
#: added to the predictor's correlation matrix: boundaries at the same phase (the start, a
#: stop) make it singular, and a share of 1e-9 of the residual's variance is far below anything
#: the filter resolves
JITTER = 1e-9


@compiled.njit(cache=True)
def read_correlation(turn, sigma):
    """Correlation of a wheel's residuals at two boundaries ``turn`` ticks apart, known to ``sigma`` [-].

    The sawtooth's autocorrelation at the fractional turn ``f``, ``1 - 6 f (1 - f)`` for a phase
    uniform over a tick, averaged over the turn's normal spread: ``1 - 6 v`` with ``v`` the count
    error's variance :func:`estimators.encoder_phase.count_error_var`. 0 when ``sigma`` is
    infinite (the turn is not predicted).
    """
    if not sigma < math.inf:
        return 0.0
    f = turn - math.floor(turn)
    if f > 0.5:
        f -= 1.0                                 # centred on the whole tick, |f| <= 1/2
    if sigma <= 0.0:
        return 1.0 - 6.0 * abs(f) + 6.0 * f * f
    if sigma < SIGMA_NEAR:
        # 1 - 6 |f| + 6 f^2 is smooth but at whole ticks, and the next one is > 5 sigma away:
        # average |f| (a folded normal) and f^2 over the spread
        z = f / sigma
        mean_abs = (sigma * math.sqrt(2.0 / math.pi) * math.exp(-0.5 * z * z)
                    + f * math.erf(z / math.sqrt(2.0)))
        return 1.0 - 6.0 * mean_abs + 6.0 * (f * f + sigma * sigma)
    # sum_m 6 / (pi m)^2 cos(2 pi m f) exp(-2 pi^2 m^2 sigma^2); past m = 20 the terms are < e^-79
    c = 0.0
    for m in range(1, 21):
        c += 6.0 / (math.pi * m) ** 2 * math.cos(2.0 * math.pi * m * f) * math.exp(
            -2.0 * (math.pi * m * sigma) ** 2)
    return c


@compiled.njit(cache=True)
def predictor_from(turns, steps, segments, per_step, coef):
    """Fill ``coef`` with the best linear predictor of the residual at boundary 0 from boundaries 1..K.

    Parameters
    ----------
    turns, steps, segments : ndarray, shape (K + 1,)
        Each boundary's commanded turn since any origin [ticks], physics step and segment,
        the new boundary first (:func:`estimators.encoder_phase.boundaries`).
    per_step : float
        The turn's uncertainty per physics step of lag [ticks] (inf: not predicted).
    coef : ndarray, shape (K,)
        Filled: ``a``, the new residual's weights on the past ones.

    Returns
    -------
    float
        The predictor's error variance as a share of the residual's, in ``[0, 1]``.
    """
    k = coef.shape[0]
    C = np.empty((k, k))
    c = np.empty(k)
    for i in range(k):
        c[i] = _pair(turns, steps, segments, per_step, 0, i + 1)
        for j in range(i + 1):
            C[i, j] = 1.0 + JITTER if i == j else _pair(turns, steps, segments, per_step, i + 1, j + 1)
    # Cholesky C = L L^T in place (lower), then L L^T a = c
    for j in range(k):
        s = C[j, j]
        for m in range(j):
            s -= C[j, m] * C[j, m]
        d = math.sqrt(max(s, JITTER))
        C[j, j] = d
        for i in range(j + 1, k):
            s = C[i, j]
            for m in range(j):
                s -= C[i, m] * C[j, m]
            C[i, j] = s / d
    for i in range(k):
        s = c[i]
        for m in range(i):
            s -= C[i, m] * coef[m]
        coef[i] = s / C[i, i]
    explained = 0.0
    for i in range(k):
        explained += coef[i] * coef[i]       # |L^-1 c|^2 = c . C^-1 c
    for i in range(k - 1, -1, -1):
        s = coef[i]
        for m in range(i + 1, k):
            s -= C[m, i] * coef[m]
        coef[i] = s / C[i, i]
    return min(max(1.0 - explained, 0.0), 1.0)


@compiled.njit(cache=True)
def _pair(turns, steps, segments, per_step, i, j):
    if segments[i] != segments[j]:
        return 0.0
    return read_correlation(turns[i] - turns[j], per_step * abs(steps[i] - steps[j]))


@compiled.njit(cache=True)
def residual_predictor(phase, wheel, coef):
    """Fill ``coef`` with the wheel's predictor over the read just recorded; return its fresh share.

    :func:`predictor_from` over the last ``LAGS + 1`` boundaries of ``phase``
    (:mod:`estimators.encoder_phase`).
    """
    turns = np.empty(LAGS + 1)
    steps = np.empty(LAGS + 1)
    segments = np.empty(LAGS + 1)
    per_step = boundaries(phase, wheel, turns, steps, segments)
    return predictor_from(turns, steps, segments, per_step, coef)


@compiled.njit(cache=True)
def _left_product(M, A3, coef_l, coef_r, biased, out):
    """``out = A M`` for the predict's transition ``A``: dense pose rows ``A3``, ``e`` kept, blocks shifted."""
    n = M.shape[0]
    k = coef_l.shape[0]
    for i in range(3):
        for col in range(n):
            v = 0.0
            for m in range(n):
                v += A3[i, m] * M[m, col]
            out[i, col] = v
    if biased:
        for col in range(n):
            out[3, col] = M[3, col]
    for w in range(2):
        base = n - 2 * k + w * k
        coef = coef_l if w == 0 else coef_r
        for col in range(n):
            v = 0.0
            for j in range(k):
                v += coef[j] * M[base + j, col]
            out[base, col] = v
        for j in range(k - 1, 0, -1):
            for col in range(n):
                out[base + j, col] = M[base + j - 1, col]


@compiled.njit(cache=True)
def propagate_moments_quantised(x, P, d_left, d_right, wheel_base, var_left, var_right, quant_var,
                                bias_walk_var, turn_slip, coef_left, coef_right, fresh_left, fresh_right):
    """EKF predict step of the pose augmented with the encoders' residual blocks, in place.

    Parameters
    ----------
    x : numpy.ndarray, shape (3 + 2 K,) or (4 + 2 K,), float64, C-contiguous
        ``(x [m], y [m], theta [rad], [e [-]], left block, right block)`` (module docstring), the
        residuals centred; overwritten. The heading is left unwrapped.
    P : numpy.ndarray, shape (n, n), float64, C-contiguous
        Its covariance; overwritten.
    d_left, d_right : float
        Wheel travel reported by the encoders over the step (nominal radius) [m].
    wheel_base : float
        Distance between the wheels [m].
    var_left, var_right : float
        Variance of each wheel's random slip over the step [m^2] (already scaled), without
        quantisation.
    quant_var : float
        Variance of a residual [m^2]: ``tick^2 / 12`` (already scaled).
    bias_walk_var : float
        Variance added to ``e`` over the step [-] (ignored without ``e``).
    turn_slip : float
        Declared outward slip per radian of the step's heading change [-]
        (:func:`estimators.motion.propagate_moments`).
    coef_left, coef_right : numpy.ndarray, shape (K,)
        Each wheel's new residual's weights on its block (:func:`residual_predictor`; zeros: a
        new residual).
    fresh_left, fresh_right : float
        The share of ``quant_var`` that is new in each wheel's new residual, in ``[0, 1]``.
    """
    n = x.shape[0]
    k = coef_left.shape[0]
    if not (n - 2 * k in (3, 4) and coef_right.shape[0] == k and P.shape[0] == n and P.shape[1] == n):
        raise ValueError("propagate_moments_quantised: x, P and the predictors do not match")
    biased = n - 2 * k == 4
    bl, br = n - 2 * k, n - k                    # the blocks' first entries
    e = x[3] if biased else 0.0
    scale = (1.0 - e, 1.0 + e)
    q_l = 0.0
    q_r = 0.0
    for j in range(k):
        q_l += coef_left[j] * x[bl + j]
        q_r += coef_right[j] * x[br + j]
    u_l, u_r = d_left - x[bl] + q_l, d_right - x[br] + q_r
    tl, tr = scale[0] * u_l, scale[1] * u_r
    F3 = np.empty((3, 3))
    G = np.empty((3, 2))
    _jacobians_into(x[2], tl, tr, wheel_base, F3, G, turn_slip)
    # The pose rows of A: pose, e, and each residual through u_w = d_w - q_0 + a . q
    A3 = np.zeros((3, n))
    for i in range(3):
        for j in range(3):
            A3[i, j] = F3[i, j]
        if biased:
            A3[i, 3] = -u_l * G[i, 0] + u_r * G[i, 1]
        for j in range(k):
            A3[i, bl + j] = scale[0] * G[i, 0] * coef_left[j]
            A3[i, br + j] = scale[1] * G[i, 1] * coef_right[j]
        A3[i, bl] -= scale[0] * G[i, 0]
        A3[i, br] -= scale[1] * G[i, 1]
    AP = np.empty((n, n))
    _left_product(P, A3, coef_left, coef_right, biased, AP)
    out = np.empty((n, n))
    _left_product(AP.T, A3, coef_left, coef_right, biased, out)      # A (A P)^T = A P A^T
    if biased:
        out[3, 3] += bias_walk_var
    # The noise: each wheel's fresh residual part and slip move the pose; the fresh part is also
    # the new residual.
    for w in range(2):
        sw = scale[w]
        base = bl if w == 0 else br
        fresh = (fresh_left if w == 0 else fresh_right) * quant_var
        slip_var = var_left if w == 0 else var_right
        for i in range(3):
            gi = sw * G[i, w]
            for j in range(3):
                out[i, j] += gi * sw * G[j, w] * (fresh + slip_var)
            out[i, base] += gi * fresh
            out[base, i] += gi * fresh
        out[base, base] += fresh
    for i in range(n):                           # exactly symmetric, whatever the rounding
        for j in range(i):
            v = 0.5 * (out[i, j] + out[j, i])
            out[i, j] = v
            out[j, i] = v
    ds, dtheta, _, kk, _, cs, sn = _arc_terms(x[2], tl, tr, wheel_base, turn_slip)
    x[0] += ds * kk * cs
    x[1] += ds * kk * sn
    x[2] += dtheta
    for j in range(k - 1, 0, -1):
        x[bl + j] = x[bl + j - 1]
        x[br + j] = x[br + j - 1]
    x[bl] = q_l
    x[br] = q_r
    P[:, :] = out


# numba keys a cache on its own file only: flush the kernels above when a file they inline changed
compiled.keep_fresh(__name__)
