"""EKF predict with each wheel's encoder quantisation residual in the state (an MA(1) noise).

An encoder counts whole ticks of its wheel's rotation: the count converted to travel is
``r phi_k - q_k``, with ``q_k`` in ``[0, tick)`` the part of the rotation below the last tick
edge (``tick = 2 pi r / encoder_ticks`` [m]). The travel the odometry reports over step k is
therefore ``d_k = r (phi_k - phi_{k-1}) - q_k + q_{k-1}``: the quantisation error of a step is the
difference of two residuals, and over any window the errors telescope to ``q_start - q_end``.
Added to the process noise as white noise of variance ``tick^2 / 12`` per step (what
:func:`estimators.process_noise.wheel_variances` does) it grows without bound, at standstill too,
while the true error never exceeds one tick: the filter becomes pessimistic, the more the more
often it predicts (60 Hz here) and the slower the robot moves.

Exact treatment (a second-order-exact linear model of a moving-average noise): the state is
augmented with each wheel's current residual, centred, ``(q_left, q_right)`` [m], zero-mean with
variance ``tick^2 / 12`` (uniform over a tick). At each step the residual is replaced by a new
one, independent of everything before it (true when a step moves the wheel over many ticks, or
over an uncertain fraction of one; see ``estimators.ekf`` for when that is what the
simulated encoders do), and the wheel's rotation over the step is estimated as
``u_w = d_w - q_w,old + q_w,new``. With the relative wheel-radius error ``e`` (optional state,
:func:`estimators.motion.propagate_moments_biased`) the wheels roll ``t_l = (1 - e) u_l`` and
``t_r = (1 + e) u_r`` plus the floor's random slip (variance ``var_left``, ``var_right``), so

    pose' = f(pose, t_l, t_r),       e' = e,       q' = q_new,
    P' = A P A^T + B W B^T,

``A`` the Jacobian with respect to the old state (pose: ``F``; e: ``-u_l G_l + u_r G_r``;
old residuals: ``-(1 - e) G_l``, ``-(1 + e) G_r``; the residual rows are zero: they are
replaced) and ``B W B^T`` the new residuals and the slip, with the new residuals' rows
``(1 -/+ e) G_w tick^2/12`` coupling the pose to them. The pose picks up
``G (q_new - q_old)`` per step, whose sum over a window stays bounded: the pose covariance
at standstill no longer grows.

State layout: ``(x [m], y [m], theta [rad], [e [-]], q_left [m], q_right [m])``, shape (5,)
or (6,).
"""

from __future__ import annotations

import numpy as np

from estimators.motion import _arc_terms, _jacobians_into
from jit import compiled


@compiled.njit(cache=True)
def propagate_moments_quantised(x, P, d_left, d_right, wheel_base, var_left, var_right, quant_var,
                                bias_walk_var, turn_slip=0.0):
    """EKF predict step of the pose augmented with the encoder residuals, in place.

    Parameters
    ----------
    x : numpy.ndarray, shape (5,) or (6,), float64, C-contiguous
        ``(x [m], y [m], theta [rad], q_left [m], q_right [m])``, or with the relative
        wheel-radius error ``(x, y, theta, e [-], q_left, q_right)``; overwritten. The
        residuals are centred (zero mean); the heading is left unwrapped.
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
        Variance of a new residual [m^2]: ``tick^2 / 12`` (already scaled).
    bias_walk_var : float
        Variance added to ``e`` over the step [-] (ignored without ``e``).
    turn_slip : float
        Declared outward slip per radian of the step's heading change [-]
        (:func:`estimators.motion.propagate_moments`).
    """
    n = x.shape[0]
    biased = n == 6
    iq = n - 2
    e = x[3] if biased else 0.0
    sl, sr = 1.0 - e, 1.0 + e
    ul = d_left - x[iq]
    ur = d_right - x[iq + 1]
    tl, tr = sl * ul, sr * ur
    F3 = np.empty((3, 3))
    G = np.empty((3, 2))
    _jacobians_into(x[2], tl, tr, wheel_base, F3, G, turn_slip)
    A = np.zeros((n, n))
    for i in range(3):
        for j in range(3):
            A[i, j] = F3[i, j]
        if biased:
            A[i, 3] = -ul * G[i, 0] + ur * G[i, 1]
        A[i, iq] = -sl * G[i, 0]
        A[i, iq + 1] = -sr * G[i, 1]
    if biased:
        A[3, 3] = 1.0
    ds, dtheta, _, k, _, c, s = _arc_terms(x[2], tl, tr, wheel_base, turn_slip)
    x[0] += ds * k * c
    x[1] += ds * k * s
    x[2] += dtheta
    x[iq] = 0.0
    x[iq + 1] = 0.0
    # Explicit loops: for n <= 6 numba's BLAS-backed `@` costs more than the arithmetic.
    AP = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            v = 0.0
            for m in range(n):
                v += A[i, m] * P[m, j]
            AP[i, j] = v
    # Rows of the new residuals are zero in A: only the pose (and e) block propagates.
    m_top = iq
    wl = sl * sl * (quant_var + var_left)
    wr = sr * sr * (quant_var + var_right)
    for i in range(m_top):
        for j in range(i, m_top):
            v = 0.0
            for m in range(n):
                v += AP[i, m] * A[j, m]
            if j < 3:
                v += G[i, 0] * wl * G[j, 0] + G[i, 1] * wr * G[j, 1]
            elif i == 3:
                v += bias_walk_var
            # Writing one triangle into both keeps P exactly symmetric over thousands of steps.
            P[i, j] = v
            P[j, i] = v
    for i in range(m_top):
        cl = sl * G[i, 0] * quant_var if i < 3 else 0.0
        cr = sr * G[i, 1] * quant_var if i < 3 else 0.0
        P[i, iq] = cl
        P[iq, i] = cl
        P[i, iq + 1] = cr
        P[iq + 1, i] = cr
    P[iq, iq] = quant_var
    P[iq + 1, iq + 1] = quant_var
    P[iq, iq + 1] = 0.0
    P[iq + 1, iq] = 0.0


# numba keys a cache on its own file only: flush the kernels above when a file they inline changed
compiled.keep_fresh(__name__)
