"""EKF predict with each wheel's encoder quantisation residual in the state.

An encoder counts whole ticks of its wheel's rotation: the count converted to travel is
``r phi_k - q_k``, with ``q_k`` in ``[0, tick)`` the part of the rotation below the last tick
edge (``tick = 2 pi r / encoder_ticks`` [m]). The travel the odometry reports over step k is
therefore ``d_k = r (phi_k - phi_{k-1}) - q_k + q_{k-1}``: the quantisation error of a step is the
difference of two residuals, and over any window the errors telescope to ``q_start - q_end``.
Added to the process noise as white noise of variance ``tick^2 / 12`` per step (what
:func:`estimators.process_noise.wheel_variances` does) it grows without bound, at standstill too,
while the true error never exceeds one tick. With the residual a state, the error stays bounded.

A residual is the sawtooth of its wheel's phase: a read that turns the wheel ``n + f`` ticks
moves it by ``f`` (modulo the tick), so across the read it keeps the sawtooth's correlation
``c = 1 - 6 f (1 - f)`` (:func:`read_correlation`), and the read's count error has the variance
``f (1 - f) tick^2``: up to 1/4 tick^2 at f = 1/2, ~0 for a turn of whole ticks. The model is that
correlation and no more: ``q_new = c q_old + v`` with ``v`` fresh, of variance
``(1 - c^2) tick^2 / 12``, the turn predicted from the wheel command over the read's span
(:func:`estimators.encoder_phase.phase_advance`; c = 0, a new residual, when it is not). Over one
read (1-4 physics steps) the prediction holds to ~0.003 ticks; over the time between fixes it does
not: the simulated wheels fall behind their command by a steady ~1e-4 of their rate (0.055 ticks a
second on random-23-017), and a filter that turned the residual's harmonics by the command over
many reads learnt phases it did not have and was overconfident on five of 22 random worlds
(``docs/design.md`` §6). What the AR(1) loses is the correlation over several reads (a wheel that
turns 70.83 ticks a read is back near its phase every 6 reads).

The wheel's rotation over the step is ``u_w = d_w - q_w,old + q_w,new = d_w - (1 - c) q_w,old + v_w``. With the relative
wheel-radius error ``e`` (optional state, :func:`estimators.motion.propagate_moments_biased`) the
wheels roll ``t_l = (1 - e) u_l`` and ``t_r = (1 + e) u_r`` plus the floor's random slip
(variance ``var_left``, ``var_right``), so ``pose' = f(pose, t_l, t_r)``, ``e' = e``,
``q' = c q + v``, ``P' = A P A^T + B W B^T``.

State layout: ``(x [m], y [m], theta [rad], [e [-]], q_left [m], q_right [m])``: shape (5,) or (6,).
"""

from __future__ import annotations

import math

import numpy as np

from estimators.motion import _arc_terms, _jacobians_into
from jit import compiled


@compiled.njit(cache=True)
def read_correlation(turn, sigma):
    """Correlation of a wheel's residual across a read that turns it ``turn`` ticks [-].

    The sawtooth's autocorrelation at the read's fractional turn ``f``: ``1 - 6 f (1 - f)``
    for a phase uniform over a tick; 0 (a new residual) when the turn is not predicted (``sigma``
    infinite).
    """
    if not sigma < math.inf:
        return 0.0
    f = turn - math.floor(turn)
    return 1.0 - 6.0 * f * (1.0 - f)


@compiled.njit(cache=True)
def propagate_moments_quantised(x, P, d_left, d_right, wheel_base, var_left, var_right, quant_var,
                                bias_walk_var, turn_slip=0.0, turn_left=0.0, turn_right=0.0,
                                sigma_left=math.inf, sigma_right=math.inf):
    """EKF predict step of the pose augmented with the encoders' residuals, in place.

    Parameters
    ----------
    x : numpy.ndarray, shape (5,) or (6,), float64, C-contiguous
        ``(x [m], y [m], theta [rad], [e [-]], q_left [m], q_right [m])``, the residuals centred
        (module docstring); overwritten. The heading is left unwrapped.
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
    turn_left, turn_right : float
        Each wheel's predicted turn over the step [ticks]
        (:func:`estimators.encoder_phase.phase_advance`).
    sigma_left, sigma_right : float
        Whether it is predicted: finite, or inf (the default: the residual is new).
    """
    n = x.shape[0]
    biased = n == 6
    b0 = n - 2                                   # the left wheel's residual
    e = x[3] if biased else 0.0
    scale = (1.0 - e, 1.0 + e)
    # q_new = c q_old + v, var(v) = (1 - c^2) tick^2 / 12: the wheels turned d - (1 - c) q_old + v
    c = (read_correlation(turn_left, sigma_left), read_correlation(turn_right, sigma_right))
    u_l, u_r = d_left - (1.0 - c[0]) * x[b0], d_right - (1.0 - c[1]) * x[b0 + 1]
    tl, tr = scale[0] * u_l, scale[1] * u_r
    F3 = np.empty((3, 3))
    G = np.empty((3, 2))
    _jacobians_into(x[2], tl, tr, wheel_base, F3, G, turn_slip)
    # A = d(new state)/d(old state): the pose rows mix pose, e and the old residuals; e's row is
    # the identity; a residual's row is c on its diagonal. Only the pose rows need products.
    A = np.zeros((3, n))
    for i in range(3):
        for j in range(3):
            A[i, j] = F3[i, j]
        if biased:
            A[i, 3] = -u_l * G[i, 0] + u_r * G[i, 1]
        A[i, b0] = -scale[0] * G[i, 0] * (1.0 - c[0])
        A[i, b0 + 1] = -scale[1] * G[i, 1] * (1.0 - c[1])
    AP = np.zeros((3, n))
    for i in range(3):
        for j in range(n):
            v = 0.0
            for m in range(n):
                v += A[i, m] * P[m, j]
            AP[i, j] = v
    out = np.zeros((n, n))
    for i in range(3):
        for j in range(i, 3):
            v = 0.0
            for m in range(n):
                v += AP[i, m] * A[j, m]
            out[i, j] = v
            out[j, i] = v
        if biased:
            out[i, 3] = AP[i, 3]                 # cov(pose', e) = A_pose P[:, e]
            out[3, i] = AP[i, 3]
        for w in range(2):
            out[i, b0 + w] = c[w] * AP[i, b0 + w]
            out[b0 + w, i] = out[i, b0 + w]
    if biased:
        out[3, 3] = P[3, 3] + bias_walk_var
        for w in range(2):
            out[3, b0 + w] = c[w] * P[3, b0 + w]
            out[b0 + w, 3] = out[3, b0 + w]
    for w in range(2):
        for w2 in range(2):
            out[b0 + w, b0 + w2] = c[w] * c[w2] * P[b0 + w, b0 + w2]
    # The noise: each wheel's fresh part of the residual and slip move the pose; the fresh part
    # is also the residual's.
    for w in range(2):
        sw = scale[w]
        slip_var = var_left if w == 0 else var_right
        fresh = (1.0 - c[w] * c[w]) * quant_var
        for i in range(3):
            gi = sw * G[i, w]
            for j in range(i, 3):
                v = gi * sw * G[j, w] * (fresh + slip_var)
                out[i, j] += v
                if j != i:
                    out[j, i] += v
            out[i, b0 + w] += gi * fresh
            out[b0 + w, i] = out[i, b0 + w]
        out[b0 + w, b0 + w] += fresh
    ds, dtheta, _, k, _, cs, sn = _arc_terms(x[2], tl, tr, wheel_base, turn_slip)
    x[0] += ds * k * cs
    x[1] += ds * k * sn
    x[2] += dtheta
    x[b0] = c[0] * x[b0]
    x[b0 + 1] = c[1] * x[b0 + 1]
    P[:, :] = out


# numba keys a cache on its own file only: flush the kernels above when a file they inline changed
compiled.keep_fresh(__name__)
