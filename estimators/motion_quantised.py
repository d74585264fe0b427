"""EKF predict with each wheel's encoder quantisation residual in the state, phase and all.

An encoder counts whole ticks of its wheel's rotation: the count converted to travel is
``r phi_k - q_k``, with ``q_k`` in ``[0, tick)`` the part of the rotation below the last tick
edge (``tick = 2 pi r / encoder_ticks`` [m]). The travel the odometry reports over step k is
therefore ``d_k = r (phi_k - phi_{k-1}) - q_k + q_{k-1}``: the quantisation error of a step is the
difference of two residuals, and over any window the errors telescope to ``q_start - q_end``.
Added to the process noise as white noise of variance ``tick^2 / 12`` per step (what
:func:`estimators.process_noise.wheel_variances` does) it grows without bound, at standstill too,
while the true error never exceeds one tick.

The residual is a sawtooth of the wheel's phase: centred, ``tick (phase - 1/2)
= -(tick / pi) sum_m sin(2 pi m phase) / m``. A step that turns the wheel ``T`` ticks advances
every harmonic's angle by ``2 pi m T``: a residual is not independent of the last one; over a
window the count error's variance is ``f (1 - f) tick^2`` for a fractional turn ``f``, not the
``tick^2 / 6`` of two independent residuals, and across the runs of a sweep a fix's windows all
have the same ``f`` (``docs/design.md`` §6). The state holds, per wheel, the first
``HARMONICS`` harmonics as phasors ``(p_c, p_s)_m = -(tick / (pi m)) (cos, sin)(2 pi m phase)``
[m] (``6 / (pi m)^2`` of the residual's variance each) and the rest ``w`` as white:
``q = sum_m p_s,m + w``. At each step phasor m turns by ``2 pi m T`` with the turn predicted from
the wheel command (:func:`estimators.encoder_phase.phase_advance`) and shrinks by
``rho_m = exp(-2 pi^2 m^2 sigma^2)`` for the prediction's uncertainty ``sigma`` [ticks], a fresh
part of variance ``(1 - rho_m^2)`` keeping it stationary; ``w`` is renewed. So every window's
count-error variance is right to within twice the white share, ``2 (1/12 - sum_m 1/(2 pi^2 m^2))
tick^2`` (0.012 for 8 harmonics, 0.065 for one; independent residuals are up to 0.167 off), and
with ``sigma`` infinite (no prediction) the model is that of independent residuals of variance
``tick^2 / 12``.

The wheel's rotation over the step is ``u_w = d_w - q_w,old + q_w,new``. With the relative
wheel-radius error ``e`` (optional state, :func:`estimators.motion.propagate_moments_biased`) the
wheels roll ``t_l = (1 - e) u_l`` and ``t_r = (1 + e) u_r`` plus the floor's random slip
(variance ``var_left``, ``var_right``), so ``pose' = f(pose, t_l, t_r)``, ``e' = e``,
``p' = rho R(2 pi T) p + n``, ``w' = w_new``, ``P' = A P A^T + B W B^T``.

State layout: ``(x [m], y [m], theta [rad], [e [-]], left block, right block)``, a block
``(p_c,1, p_s,1, ..., p_c,M, p_s,M, w)`` [m] of ``PER_WHEEL`` entries: shape
``(3 + 2 PER_WHEEL,)`` or ``(4 + 2 PER_WHEEL,)``.
"""

from __future__ import annotations

import math

import numpy as np

from estimators.motion import _arc_terms, _jacobians_into
from jit import compiled

#: harmonics of the sawtooth carried as phasors per wheel: they hold
#: ``sum_{m <= M} 6 / (pi^2 m^2)`` of a residual's variance (0.929 for 8), the rest is white
HARMONICS = 8
#: entries per wheel: each harmonic's phasor (cos, sin part) [m], then the white rest [m]
PER_WHEEL = 2 * HARMONICS + 1


def harmonic_share(m: int) -> float:
    """Share of a residual's variance ``tick^2 / 12`` in one component of harmonic ``m``'s phasor: 6 / (pi m)^2."""
    return 6.0 / (math.pi * m) ** 2


#: share of the residual's variance in the white rest
WHITE_SHARE = 1.0 - sum(harmonic_share(m) for m in range(1, HARMONICS + 1))


@compiled.njit(cache=True)
def propagate_moments_quantised(x, P, d_left, d_right, wheel_base, var_left, var_right, quant_var,
                                bias_walk_var, turn_slip=0.0, turn_left=0.0, turn_right=0.0,
                                sigma_left=math.inf, sigma_right=math.inf):
    """EKF predict step of the pose augmented with the encoders' residual phasors, in place.

    Parameters
    ----------
    x : numpy.ndarray, shape (3 + 2 PER_WHEEL,) or (4 + 2 PER_WHEEL,), float64, C-contiguous
        ``(x [m], y [m], theta [rad], [e [-]], left block, right block)``, a wheel's block the
        phasors ``(p_c, p_s)`` of harmonics 1..HARMONICS and the white rest ``w`` [m] (module
        docstring); overwritten. The heading is left unwrapped.
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
        Variance of a residual [m^2]: ``tick^2 / 12`` (already scaled); harmonic m's phasor holds
        ``6 / (pi m)^2`` of it per component, the white rest what is left.
    bias_walk_var : float
        Variance added to ``e`` over the step [-] (ignored without ``e``).
    turn_slip : float
        Declared outward slip per radian of the step's heading change [-]
        (:func:`estimators.motion.propagate_moments`).
    turn_left, turn_right : float
        Each wheel's predicted turn over the step [ticks]
        (:func:`estimators.encoder_phase.phase_advance`).
    sigma_left, sigma_right : float
        Their standard deviations [ticks]; inf (the default): the phasors are renewed,
        independent of the last (the residuals of successive reads independent).
    """
    n = x.shape[0]
    biased = n == 4 + 2 * PER_WHEEL
    b0 = 4 if biased else 3                      # first entry of the left wheel's block
    e = x[3] if biased else 0.0
    scale = (1.0 - e, 1.0 + e)
    white = WHITE_SHARE * quant_var
    M = HARMONICS
    # per wheel and harmonic: shrink rho, cos, sin of the turn's angle, variance per component
    rho, co, si, var_h = np.empty((2, M)), np.empty((2, M)), np.empty((2, M)), np.empty(M)
    for m in range(M):
        var_h[m] = 6.0 / (math.pi * (m + 1)) ** 2 * quant_var
    u = np.empty(2)
    for w in range(2):
        turn = turn_left if w == 0 else turn_right
        sig = sigma_left if w == 0 else sigma_right
        b = b0 + PER_WHEEL * w
        q_old = x[b + 2 * M]
        q_new = 0.0
        for m in range(M):
            h = m + 1
            rho[w, m] = math.exp(-2.0 * (math.pi * h * sig) ** 2) if sig < math.inf else 0.0
            co[w, m], si[w, m] = math.cos(2.0 * math.pi * h * turn), math.sin(2.0 * math.pi * h * turn)
            pc, ps = x[b + 2 * m], x[b + 2 * m + 1]
            q_old += ps
            # p' = rho R(2 pi h turn) p (+ noise): the new residual's mean is the sum of the p'_s
            q_new += rho[w, m] * (si[w, m] * pc + co[w, m] * ps)
        d = d_left if w == 0 else d_right
        u[w] = d - q_old + q_new
    tl, tr = scale[0] * u[0], scale[1] * u[1]
    F3 = np.empty((3, 3))
    G = np.empty((3, 2))
    _jacobians_into(x[2], tl, tr, wheel_base, F3, G, turn_slip)
    A = np.zeros((n, n))
    for i in range(3):
        for j in range(3):
            A[i, j] = F3[i, j]
        if biased:
            A[i, 3] = -u[0] * G[i, 0] + u[1] * G[i, 1]
        for w in range(2):
            b = b0 + PER_WHEEL * w
            g = scale[w] * G[i, w]
            for m in range(M):
                A[i, b + 2 * m] = g * rho[w, m] * si[w, m]
                A[i, b + 2 * m + 1] = g * (rho[w, m] * co[w, m] - 1.0)
            A[i, b + 2 * M] = -g
    if biased:
        A[3, 3] = 1.0
    for w in range(2):
        b = b0 + PER_WHEEL * w
        for m in range(M):
            c, s_ = rho[w, m] * co[w, m], rho[w, m] * si[w, m]
            o = b + 2 * m
            A[o, o], A[o, o + 1] = c, -s_
            A[o + 1, o], A[o + 1, o + 1] = s_, c
        # the white rest's row stays zero: renewed
    ds, dtheta, _, k, _, c, s = _arc_terms(x[2], tl, tr, wheel_base, turn_slip)
    x[0] += ds * k * c
    x[1] += ds * k * s
    x[2] += dtheta
    for w in range(2):
        b = b0 + PER_WHEEL * w
        for m in range(M):
            o = b + 2 * m
            pc, ps = x[o], x[o + 1]
            x[o] = rho[w, m] * (co[w, m] * pc - si[w, m] * ps)
            x[o + 1] = rho[w, m] * (si[w, m] * pc + co[w, m] * ps)
        x[b + 2 * M] = 0.0
    # A is sparse (the pose rows mix everything, the phasor blocks rotate, the white rows are
    # zero): list each row's nonzero columns once, so A P A^T costs O(nnz n), not O(n^3).
    cols = np.empty((n, n), dtype=np.int64)
    ncol = np.zeros(n, dtype=np.int64)
    for i in range(n):
        for m in range(n):
            if A[i, m] != 0.0:
                cols[i, ncol[i]] = m
                ncol[i] += 1
    AP = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            v = 0.0
            for c in range(ncol[i]):
                m = cols[i, c]
                v += A[i, m] * P[m, j]
            AP[i, j] = v
    for i in range(n):
        for j in range(i, n):
            v = 0.0
            for c in range(ncol[j]):
                m = cols[j, c]
                v += AP[i, m] * A[j, m]
            # Writing one triangle into both keeps P exactly symmetric over thousands of steps.
            P[i, j] = v
            P[j, i] = v
    # The noise: per wheel each phasor's renewal (var (1 - rho^2) of its share per component),
    # the white rest's renewal and the slip; the pose sees the p_s renewals, the rest and the slip.
    for w in range(2):
        b = b0 + PER_WHEEL * w
        slip_var = var_left if w == 0 else var_right
        sw = scale[w]
        renew_sum = 0.0
        for m in range(M):
            renew = (1.0 - rho[w, m] * rho[w, m]) * var_h[m]
            renew_sum += renew
            o = b + 2 * m
            P[o, o] += renew
            P[o + 1, o + 1] += renew
            for i in range(3):
                P[i, o + 1] += sw * G[i, w] * renew
                P[o + 1, i] = P[i, o + 1]
        for i in range(3):
            gi = sw * G[i, w]
            for j in range(i, 3):
                v = gi * sw * G[j, w] * (renew_sum + white + slip_var)
                P[i, j] += v
                if j != i:
                    P[j, i] += v
            P[i, b + 2 * M] += gi * white
            P[b + 2 * M, i] = P[i, b + 2 * M]
        P[b + 2 * M, b + 2 * M] += white
    if biased:
        P[3, 3] += bias_walk_var


def phasor_state(residual: float, tick: float) -> np.ndarray:
    """Return a wheel's block (``PER_WHEEL`` entries [m]) for a known centred residual [m] on encoders of ``tick`` [m].

    The residual is ``tick (phase - 1/2)`` for the wheel's phase in ``[0, 1)`` ticks past its
    last edge, ``-(tick / pi) sum_m sin(2 pi m phase) / m``: harmonic m's phasor is
    ``-(tick / (pi m)) (cos, sin)(2 pi m phase)``, and the white rest what the first
    ``HARMONICS`` leave of the residual.
    """
    phase = residual / tick + 0.5
    out = np.empty(PER_WHEEL)
    for m in range(1, HARMONICS + 1):
        amp = -tick / (math.pi * m)
        out[2 * m - 2] = amp * math.cos(2.0 * math.pi * m * phase)
        out[2 * m - 1] = amp * math.sin(2.0 * math.pi * m * phase)
    out[-1] = residual - out[1:-1:2].sum()
    return out


# numba keys a cache on its own file only: flush the kernels above when a file they inline changed
compiled.keep_fresh(__name__)
