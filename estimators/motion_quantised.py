"""EKF predict with each wheel's encoder quantisation residual in the state, as its harmonics.

An encoder counts whole ticks of its wheel's rotation: the count converted to travel is
``r phi_k - q_k``, with ``q_k`` the part of the rotation below the last tick edge, centred
(``[-tick/2, tick/2)``, ``tick = 2 pi r / encoder_ticks`` [m]). The travel the odometry reports
over read k is ``d_k = r (phi_k - phi_{k-1}) - q_k + q_{k-1}``: the quantisation error of a read
is the difference of two residuals, and over any window the errors telescope to
``q_start - q_end``. Added to the process noise as white noise of variance ``tick^2 / 12`` per
read (:func:`estimators.process_noise.wheel_variances`) it grows without bound, while the true
error never exceeds one tick.

The residual is the sawtooth of the wheel's phase, ``q = tick (phi0 + c - floor(phi0 + c) - 1/2)``
for a wheel turned ``c`` ticks from where its encoder's phase was ``phi0``:

    q(c) = sum_m a_m cos(2 pi m c) + b_m sin(2 pi m c),
    a_m = -tick sin(2 pi m phi0) / (pi m),  b_m = -tick cos(2 pi m phi0) / (pi m).

For a phase uniform over a tick (a run starts wherever the wheels stopped) every ``a_m`` and
``b_m`` has mean 0 and variance ``6 / (pi m)^2`` of the residual's ``tick^2 / 12``, all of them
uncorrelated. The drive holds each wheel to the integral of its command (``sim.physics.robot``,
a position loop; measured within 0.04 ticks on random worlds), so ``c`` is the
commanded turn (:mod:`estimators.encoder_phase`) and the phasors ``(a_m, b_m)`` are constants:
the state carries the first ``HARMONICS`` of each wheel and nothing forgets them while the
turn is predicted. A wheel turning at a steady rate makes residuals whose correlation does not
decay with the lag (a line spectrum); a chain of the last few residuals, the model before this
one, extrapolated it as decaying and was pessimistic (random-23-016: NIS 0.970, NEES 2.871 at 200
runs; ``docs/design.md`` section 6).

What the harmonics leave, ``r``, holds ``1 - sum_m<=M 6 / (pi m)^2`` of the variance (7.1 % for
``M = 8``), in frequencies where the drive's following error decorrelates it: it is carried as
one state, an AR(1) over a read with the correlation of those harmonics for the read's turn ``f``
known to ``sigma`` ticks (:func:`remainder_correlation`; ``sigma`` the tracking sigma of
:func:`estimators.encoder_phase.sigma_per_step` over the read's span). A read whose turn is not
predicted (no span: a filter used outside an episode) starts the wheel's residual afresh: its
phasors and remainder are redrawn from their prior; a read of span 0 keeps everything.

Not modelled: the drive's steady lag grows with the speed (``shortfall / DRIVE_GAIN``, 0.003 and
0.016 ticks at 0.5 m/s on the built-in robots), and a change of ``d`` ticks turns harmonic ``m``
by ``2 pi m d`` (0.8 rad for the 8th at 0.016 ticks), which the phasors' constant frame does not
allow for. ``tests/sim/physics/test_world.py`` bounds the cruise's lag by ``1 / (16 pi)`` ticks
(1 rad for the 8th); the 40 random worlds of ``pefsim worlds --count 40 --seed 23`` pass every check with it.

The wheel's rotation over the read is ``u_w = d_w - q_w(c_old) + q_w(c_new)``, linear in the
block. With the relative wheel-radius error ``e`` (optional state,
:func:`estimators.motion.propagate_moments_biased`) the wheels roll ``t_l = (1 - e) u_l`` and
``t_r = (1 + e) u_r`` plus the floor's random slip (variance ``var_left``, ``var_right``):
``pose' = f(pose, t_l, t_r)``, ``e' = e``, the phasors kept, ``r' = rho r + v``,
``P' = A P A^T + L W L^T``.

State layout: ``(x [m], y [m], theta [rad], [e [-]], left block, right block)``, a block
``(a_1, b_1, ..., a_M, b_M, r)`` [m]: shape ``(3 + 2 BLOCK,)`` or ``(4 + 2 BLOCK,)``.
"""

from __future__ import annotations

import math

import numpy as np

from estimators.encoder_phase import BOUNDARIES, boundaries
from estimators.motion import _arc_terms, _jacobians_into
from jit import compiled

#: harmonics of each wheel's residual carried as phasors: the 9th on hold 0.75 % of its variance
HARMONICS = 8
#: a wheel's block: ``(a_m, b_m)`` per harmonic, then the remainder
BLOCK = 2 * HARMONICS + 1
#: harmonics of the remainder's correlation series: past them lies 0.8 % of the remainder's variance
#: (0.06 % of the residual's), taken as part of it
REMAINDER_TERMS = 1024


@compiled.njit(cache=True)
def harmonic_share(m):
    """Share of a residual's variance ``tick^2 / 12`` in each of harmonic ``m``'s two phasor components [-]."""
    return 6.0 / (math.pi * m) ** 2


@compiled.njit(cache=True)
def remainder_share():
    """Share of a residual's variance past the carried harmonics [-] (0.071 for 8)."""
    rest = 1.0
    for m in range(1, HARMONICS + 1):
        # a_m cos + b_m sin: one component's variance at any turn
        rest -= harmonic_share(m)
    return rest


@compiled.njit(cache=True)
def remainder_correlation(turn, sigma):
    """Correlation of the remainder at two boundaries ``turn`` ticks apart, known to ``sigma`` ticks [-].

    ``sum_m cos(2 pi m turn) exp(-2 pi^2 m^2 sigma^2) / m^2`` over ``sum_m 1 / m^2``, ``m`` from
    ``HARMONICS + 1`` to ``REMAINDER_TERMS``: the sawtooth's autocorrelation without its carried
    harmonics, averaged over the turn's normal spread. 0 when ``sigma`` is not finite.
    """
    if not sigma < math.inf:
        return 0.0
    x = 2.0 * math.pi * (turn - math.floor(turn))
    m0 = HARMONICS + 1
    # cos(m x) and the damping by recurrences: cos((m+1) x) = 2 cos x cos(m x) - cos((m-1) x),
    # damp(m+1) = damp(m) t(m), t(m+1) = t(m) exp(-4 pi^2 sigma^2)
    c1 = math.cos(x)
    c_prev, c_now = math.cos((m0 - 1) * x), math.cos(m0 * x)
    a = 2.0 * (math.pi * sigma) ** 2
    damp = math.exp(-a * m0 * m0)
    t = math.exp(-a * (2 * m0 + 1))
    t_step = math.exp(-2.0 * a)
    num = 0.0
    den = 0.0
    for m in range(m0, REMAINDER_TERMS + 1):
        w = 1.0 / (m * m)
        den += w
        num += w * c_now * damp
        c_prev, c_now = c_now, 2.0 * c1 * c_now - c_prev
        damp *= t
        t *= t_step
    return num / den


def residual_block(q0: float, tick: float) -> np.ndarray:
    """Return a wheel's block for a known centred residual ``q0`` [m] at commanded turn 0, shape (BLOCK,).

    The phasors of the sawtooth at the phase ``q0 / tick + 1/2`` (module docstring) and the
    remainder that makes their sum ``q0``.
    """
    phase = q0 / tick + 0.5
    m = np.arange(1, HARMONICS + 1)
    a = -tick * np.sin(2.0 * np.pi * m * phase) / (np.pi * m)
    b = -tick * np.cos(2.0 * np.pi * m * phase) / (np.pi * m)
    return np.r_[np.column_stack([a, b]).ravel(), q0 - a.sum()]


def block_prior() -> np.ndarray:
    """Return a block's prior variances for a phase uniform over a tick, shape (BLOCK,) [shares of tick^2 / 12]."""
    m = np.arange(1, HARMONICS + 1)
    share = 6.0 / (np.pi * m) ** 2
    return np.r_[np.repeat(share, 2), remainder_share()]


@compiled.njit(cache=True)
def _wheel_read(phase, wheel, h_new, h_old):
    """Fill each harmonic's ``(cos, sin)`` at the read's two boundaries; return (kept, remainder rho).

    ``kept`` is 1.0 when the read's turn is predicted (both boundaries in one segment), else 0.0.
    """
    turns = np.empty(BOUNDARIES)
    steps = np.empty(BOUNDARIES)
    segments = np.empty(BOUNDARIES)
    per_step = boundaries(phase, wheel, turns, steps, segments)
    c_new = turns[0] - math.floor(turns[0])
    c_old = turns[1] - math.floor(turns[1])
    for m in range(1, HARMONICS + 1):
        a_new = 2.0 * math.pi * m * c_new
        a_old = 2.0 * math.pi * m * c_old
        h_new[2 * m - 2] = math.cos(a_new)
        h_new[2 * m - 1] = math.sin(a_new)
        h_old[2 * m - 2] = math.cos(a_old)
        h_old[2 * m - 1] = math.sin(a_old)
    if segments[0] != segments[1]:
        return 0.0, 0.0
    span = abs(steps[0] - steps[1])
    # a read of span 0 turned the wheel by 0, exactly (whatever the history says of sigma)
    return 1.0, remainder_correlation(turns[0] - turns[1], per_step * span if span > 0.0 else 0.0)


@compiled.njit(cache=True)
def _left_product(M, A3, kept, rho, biased, out):
    """``out = A M`` for the predict's transition ``A``: dense pose rows ``A3``, ``e`` kept, blocks scaled."""
    n = M.shape[0]
    k = BLOCK
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
        for j in range(k - 1):
            for col in range(n):
                out[base + j, col] = kept[w] * M[base + j, col]
        for col in range(n):
            out[base + k - 1, col] = rho[w] * M[base + k - 1, col]


@compiled.njit(cache=True)
def propagate_moments_quantised(x, P, d_left, d_right, wheel_base, var_left, var_right, quant_var,
                                bias_walk_var, turn_slip, phase):
    """EKF predict step of the pose augmented with the encoders' residual blocks, in place.

    Parameters
    ----------
    x : numpy.ndarray, shape (3 + 2 BLOCK,) or (4 + 2 BLOCK,), float64, C-contiguous
        ``(x [m], y [m], theta [rad], [e [-]], left block, right block)`` (module docstring);
        overwritten. The heading is left unwrapped.
    P : numpy.ndarray, shape (n, n), float64, C-contiguous
        Its covariance; overwritten.
    d_left, d_right : float
        Wheel travel reported by the encoders over the read (nominal radius) [m].
    wheel_base : float
        Distance between the wheels [m].
    var_left, var_right : float
        Variance of each wheel's random slip over the read [m^2] (already scaled), without
        quantisation.
    quant_var : float
        Variance of a residual [m^2]: ``tick^2 / 12`` (already scaled).
    bias_walk_var : float
        Variance added to ``e`` over the read [-] (ignored without ``e``).
    turn_slip : float
        Declared outward slip per radian of the read's heading change [-]
        (:func:`estimators.motion.propagate_moments`).
    phase : numpy.ndarray
        The encoder phase state after this read's :func:`estimators.encoder_phase.phase_advance`:
        each wheel's commanded turn at the read's two boundaries.
    """
    n = x.shape[0]
    k = BLOCK
    if not (n - 2 * k in (3, 4) and P.shape[0] == n and P.shape[1] == n):
        raise ValueError("propagate_moments_quantised: x and P do not hold the residual blocks")
    biased = n - 2 * k == 4
    bl, br = n - 2 * k, n - k                    # the blocks' first entries
    e = x[3] if biased else 0.0
    scale = (1.0 - e, 1.0 + e)
    h_new = np.empty((2, 2 * HARMONICS))
    h_old = np.empty((2, 2 * HARMONICS))
    kept = np.empty(2)
    rho = np.empty(2)
    g = np.empty((2, k))                         # d u_w / d block_w
    u = np.empty(2)
    for w in range(2):
        kept[w], rho[w] = _wheel_read(phase, w, h_new[w], h_old[w])
        base = bl if w == 0 else br
        uw = d_left if w == 0 else d_right
        for j in range(k - 1):
            g[w, j] = kept[w] * h_new[w, j] - h_old[w, j]
            uw += g[w, j] * x[base + j]
        g[w, k - 1] = rho[w] - 1.0
        uw += g[w, k - 1] * x[base + k - 1]
        u[w] = uw
    tl, tr = scale[0] * u[0], scale[1] * u[1]
    F3 = np.empty((3, 3))
    G = np.empty((3, 2))
    _jacobians_into(x[2], tl, tr, wheel_base, F3, G, turn_slip)
    A3 = np.zeros((3, n))
    for i in range(3):
        for j in range(3):
            A3[i, j] = F3[i, j]
        if biased:
            A3[i, 3] = -u[0] * G[i, 0] + u[1] * G[i, 1]
        for j in range(k):
            A3[i, bl + j] = scale[0] * G[i, 0] * g[0, j]
            A3[i, br + j] = scale[1] * G[i, 1] * g[1, j]
    AP = np.empty((n, n))
    _left_product(P, A3, kept, rho, biased, AP)
    out = np.empty((n, n))
    _left_product(AP.T, A3, kept, rho, biased, out)      # A (A P)^T = A P A^T
    if biased:
        out[3, 3] += bias_walk_var
    # The noise, source by source: the slip moves the pose; a redrawn phasor component and the
    # remainder's fresh part are new block states that move the pose through q(c_new).
    rest = remainder_share()
    for w in range(2):
        sw = scale[w]
        base = bl if w == 0 else br
        slip_var = var_left if w == 0 else var_right
        for i in range(3):
            for j in range(3):
                out[i, j] += sw * G[i, w] * sw * G[j, w] * slip_var
        for j in range(k):
            if j < k - 1:
                if kept[w] > 0.0:
                    continue
                v = harmonic_share(j // 2 + 1) * quant_var
                lead = h_new[w, j]
            else:
                v = (1.0 - rho[w] * rho[w]) * rest * quant_var
                lead = 1.0
            jb = base + j
            for i in range(3):
                li = sw * G[i, w] * lead
                for i2 in range(3):
                    out[i, i2] += li * sw * G[i2, w] * lead * v
                out[i, jb] += li * v
                out[jb, i] += li * v
            out[jb, jb] += v
    for i in range(n):                           # exactly symmetric, whatever the rounding
        for j in range(i):
            v = 0.5 * (out[i, j] + out[j, i])
            out[i, j] = v
            out[j, i] = v
    ds, dtheta, _, kk, _, cs, sn = _arc_terms(x[2], tl, tr, wheel_base, turn_slip)
    x[0] += ds * kk * cs
    x[1] += ds * kk * sn
    x[2] += dtheta
    for w in range(2):
        base = bl if w == 0 else br
        for j in range(k - 1):
            x[base + j] *= kept[w]
        x[base + k - 1] *= rho[w]
    P[:, :] = out


# numba keys a cache on its own file only: flush the kernels above when a file they inline changed
compiled.keep_fresh(__name__)
