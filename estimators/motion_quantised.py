"""EKF predict with each wheel's encoder quantisation residual in the state.

An encoder counts whole ticks of its wheel's rotation: the count converted to travel is
``r phi_k - q_k``, with ``q_k`` in ``[0, tick)`` the part of the rotation below the last tick
edge (``tick = 2 pi r / encoder_ticks`` [m]). The travel the odometry reports over step k is
therefore ``d_k = r (phi_k - phi_{k-1}) - q_k + q_{k-1}``: the quantisation error of a step is the
difference of two residuals, and over any window the errors telescope to ``q_start - q_end``.
Added to the process noise as white noise of variance ``tick^2 / 12`` per step (what
:func:`estimators.process_noise.wheel_variances` does) it grows without bound, at standstill too,
while the true error never exceeds one tick. With the residual a state, the error stays bounded.

Each read's new residual is taken independent of the last, zero-mean with ``tick^2 / 12``
(centred): the filter does not predict where in a tick a wheel stops. It could, from the wheel
command, to a fraction of a tick over a fix's few physics steps; but over the time between fixes
the simulated wheels fall behind their command by a steady ~1e-4 of their rate (0.055 ticks a
second on random-23-017), more than a prediction's sigma from the counts' history allows, and a
filter that turned the residual's harmonics by the command learnt phases it did not have and was
overconfident on five of 22 random worlds (``docs/design.md`` §6). The model's count error over
a read has the ``tick^2 / 6`` of two independent residuals, the mean over the read's fractional
turn of the ``f (1 - f) tick^2`` a known turn gives.

The wheel's rotation over the step is ``u_w = d_w - q_w,old + q_w,new``. With the relative
wheel-radius error ``e`` (optional state, :func:`estimators.motion.propagate_moments_biased`) the
wheels roll ``t_l = (1 - e) u_l`` and ``t_r = (1 + e) u_r`` plus the floor's random slip
(variance ``var_left``, ``var_right``), so ``pose' = f(pose, t_l, t_r)``, ``e' = e``,
``q' = q_new``, ``P' = A P A^T + B W B^T``.

State layout: ``(x [m], y [m], theta [rad], [e [-]], q_left [m], q_right [m])``: shape (5,) or (6,).
"""

from __future__ import annotations

import numpy as np

from estimators.motion import _arc_terms, _jacobians_into
from jit import compiled


@compiled.njit(cache=True)
def propagate_moments_quantised(x, P, d_left, d_right, wheel_base, var_left, var_right, quant_var,
                                bias_walk_var, turn_slip=0.0):
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
    """
    n = x.shape[0]
    biased = n == 6
    b0 = n - 2                                   # the left wheel's residual
    e = x[3] if biased else 0.0
    scale = (1.0 - e, 1.0 + e)
    # the new residuals are zero-mean: the wheels turned the reported travel less the old ones
    u_l, u_r = d_left - x[b0], d_right - x[b0 + 1]
    tl, tr = scale[0] * u_l, scale[1] * u_r
    F3 = np.empty((3, 3))
    G = np.empty((3, 2))
    _jacobians_into(x[2], tl, tr, wheel_base, F3, G, turn_slip)
    # A = d(new state)/d(old state): the pose rows mix pose, e and the old residuals; e's row is
    # the identity; the residuals' rows are zero (renewed). Only the pose rows need products.
    A = np.zeros((3, n))
    for i in range(3):
        for j in range(3):
            A[i, j] = F3[i, j]
        if biased:
            A[i, 3] = -u_l * G[i, 0] + u_r * G[i, 1]
        A[i, b0] = -scale[0] * G[i, 0]
        A[i, b0 + 1] = -scale[1] * G[i, 1]
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
    if biased:
        out[3, 3] = P[3, 3] + bias_walk_var
    # The noise: each wheel's new residual and slip move the pose; the new residual is the state.
    for w in range(2):
        sw = scale[w]
        slip_var = var_left if w == 0 else var_right
        for i in range(3):
            gi = sw * G[i, w]
            for j in range(i, 3):
                v = gi * sw * G[j, w] * (quant_var + slip_var)
                out[i, j] += v
                if j != i:
                    out[j, i] += v
            out[i, b0 + w] = gi * quant_var
            out[b0 + w, i] = out[i, b0 + w]
        out[b0 + w, b0 + w] = quant_var
    ds, dtheta, _, k, _, c, s = _arc_terms(x[2], tl, tr, wheel_base, turn_slip)
    x[0] += ds * k * c
    x[1] += ds * k * s
    x[2] += dtheta
    x[b0] = 0.0
    x[b0 + 1] = 0.0
    P[:, :] = out


# numba keys a cache on its own file only: flush the kernels above when a file they inline changed
compiled.keep_fresh(__name__)
