"""Differential-drive odometry motion model: pose propagation, Jacobians, process noise.

The state is the planar pose ``(x [m], y [m], theta [rad])``. The input over one control
step is the travel of each wheel, ``(d_left, d_right)`` [m], as the wheel encoders report it.
Over a step the wheels are assumed to turn at constant speeds, so the robot moves along an
arc of a circle; the exact end pose is

    ds = (d_left + d_right) / 2            travel of the axle midpoint [m]
    dtheta = (d_right - d_left) / b        heading change [rad], b = wheel base
    x' = x + ds * sinc(dtheta/2) * cos(theta + dtheta/2)
    y' = y + ds * sinc(dtheta/2) * sin(theta + dtheta/2)
    theta' = theta + dtheta

with ``sinc(h) = sin(h)/h`` (the chord of the arc is ``ds * sinc``; midpoint integration is
the same formula with ``sinc = 1``). A straight line and a turn on the spot are exact, and
two half steps compose to the full step.

Process noise: each wheel's travel error over a step is modelled as independent, zero-mean,
with variance (``wheel_variances``)

    var_w = (odometry_noise * |d_w|)**2            slip / floor, relative std per increment
          + (2 pi wheel_radius / encoder_ticks)**2 / 12   encoder quantisation (uniform in a tick)
          + VARIANCE_FLOOR                          keeps Q from vanishing at standstill
          [+ (wheel_radius_error * |d_w|)**2]       optional, see below

and the pose covariance grows by ``Q = G diag(var_left, var_right) G^T``. The quantisation term
is a white approximation: a real encoder's count error is bounded and does not accumulate (the
reported travel is ``true + q_{k-1} - q_k`` with ``q`` the residual below the last tick edge, so
the errors telescope: an MA(1) noise), and over many steps this term is pessimistic: over 24
steps at 60 Hz (0.4 s between fixes) it halves the pose NEES (1.53 against 3), and it grows at
standstill. The exact treatment carries the residuals as states:
:mod:`estimators.motion_quantised`, selected by ``Localizer(encoder_residual_state=True)``
(what an episode uses); there the per-wheel variance here keeps only the slip and the floor.

The optional systematic term treats the DECLARED wheel-radius error bound
(``RobotSpec.wheel_radius_error``) as a one-sigma white error per increment. A systematic error
actually adds up linearly (n steps give n times the error, not sqrt(n) times), so the term does
not model the accumulated drift of a biased wheel; it only widens the filter so a robot whose
actual wheels differ from the nominal ones is not over-trusted. It is off by default. To model
the coherent drift itself, estimate the error: :func:`propagate_moments_biased` propagates the
pose augmented with the relative wheel-radius error ``e`` (a random constant in the state, see
:class:`estimators.ekf.Localizer`'s ``estimate_wheel_bias``).

Checked against the simulated hardware (warehouse episodes) and left as it is:
- physics slip of PyBullet's wheel contacts along the wheels: true travel over kinematic travel
  with the actual radii is 1 + 1.9e-5 (left) and 1 + 0.9e-5 (right), ~1 mm over 40 m: below
  1e-3 of the declared random slip's variance (1 % per increment, ~0.15 mm per 60 Hz step) over
  any window between fixes, so not modelled;
- sideways slip in turns, MODELLED as a deterministic mean term (``RobotSpec.turn_slip``):
  the chassis slides outwards at a slip angle of 2.6e-3 rad per m/s^2 of centripetal
  acceleration at 1 m/s (warehouse: NEES 3.6 over its 1 m/s, 0.57 rad/s turn before). Measured
  with scripted turns on an open floor (lateral creep against the kinematic arc of the actual
  wheel travel): 1.59 mm/s at v = 1 m/s, omega = 0.57 rad/s (warehouse robot), 0.67 mm/s at
  0.5 m/s, 0.5 rad/s (paper-two-markers' robot): in both a slip angle of ``c omega T`` with
  ``c`` = 0.167 and 0.162 (T = 1/60 s, the odometry period), i.e. proportional to the yaw rate,
  not to the lateral acceleration (not a tyre's cornering compliance). It is mostly Bullet's
  integrator: each 1/240 s physics step moves the body along its velocity at the step's start
  heading, so the chord of a control step of N = 4 physics steps lags the arc's heading by
  ``dtheta / (2 N)`` (c = 0.125); at 1/960 s the creep drops 4x (0.40 mm/s), and 50 solver
  iterations leave 1.24 mm/s (c = 0.130): the rest (~0.04) is the 20-iteration solver's
  compliance. Friction parameters cannot remove it (the contact is far from sliding:
  0.06 g lateral against mu = 1; a friction anchor changes nothing in the turn), and a 4x
  smaller physics step costs 4x the run time, so the model declares it instead: a step's chord
  points along ``theta + (1/2 - turn_slip) dtheta`` (:func:`_arc_terms`), with ``turn_slip``
  = 0.13 in the built-ins (the simulation runs pybullet's 50 solver iterations, see
  :mod:`sim.physics.config`; measured 0.119-0.134 over four arcs on both built-in robots,
  against 0.11-0.19 with 20 iterations). The error it leaves is bounded (the lag is half a
  physics step of travel, <= 2 mm at 1 m/s) and, being deterministic given the encoder
  increments, is a mean term, not noise. The integrator's share is that of a read spanning the
  control period's 4 physics steps; a fix's measurements read between the ticks, spanning 1-3,
  and the episode gives the filter each read's own (``Localizer.predict(turn_slip=...)``,
  :func:`sim.physics.turn_lag.read_turn_slip`);
- crab and braking creep: with 20 solver iterations the small robot of ``paper-two-markers``
  (5 cm wheels, 0.1 mm laser) crabbed 0.41 mm sideways over a 3 m straight run at 0.5 m/s
  (a crab angle of ~1.4e-4 rad, more while braking) and failed NEES at 200 runs (3.218 against
  [2.853, 3.151]). That is the solver not converging on the wheel contacts, not a property of a
  robot; 50 iterations (pybullet's default) leave 0.075 mm (2.5e-5 rad) and NEES 3.007. It is
  therefore not modelled: the physics is made accurate enough instead, and
  ``tests/sim/physics/test_world.py`` bounds the crab of every built-in robot;
- wheel-radius error: the simulated wheels are ``r (1 -/+ e)`` with the actual ``e`` (0.002 in
  the built-ins) and the filter's prior std is ``|e|``: the squared error of the prior mean
  equals its variance, what consistency asks of a random constant;
- slip: the simulation draws ``slip * |d| * N(0, 1)`` on the quantised travel, the model's
  ``odometry_noise^2 d^2`` uses the reported travel: a factor ``1 + odometry_noise^2`` apart;
- standstill on the dock: with the residual states the pose covariance stays bounded; the
  white term added ``tick^2 / 12`` per wheel and step for as long as the robot held (a few
  steps per episode: the first fix takes 40 ms).

Hot paths are numba kernels (``cache=True``); the first call in a fresh environment compiles.
"""

from __future__ import annotations

import math

import numpy as np

from jit import compiled

VARIANCE_FLOOR = 1e-16
"""Smallest per-wheel travel variance per step [m^2] (10 nm std): a numerical guard only.

It must stay negligible against every error the model declares: at most 1 % of the slip
variance of a 1 mm read at the smallest non-zero slip the random worlds draw (``0.0001``,
``scenarios.worlds.SLIP_RANGE`` to four decimals: ``1e-14 m^2``). At 1e-12 (1 µm) it was 100
times that: on random-23-029 (slip 0.01 %, ~9 mm reads) the floor outweighed the declared slip
and the filter's heading random-walked where the truth's did not. Pose NEES over 8 episodes:
2.78 with the old floor, 2.97 with this one; with 2.7 million encoder ticks, 2.31
(heading 0.58 of its variance) and 3.06 (heading 0.92)."""

_SERIES_LIMIT = 1e-2
"""Below this |dtheta/2| [rad] sinc and its derivative use their Taylor series (the closed
forms lose digits to cancellation); truncation error < 3e-16."""


@compiled.njit(cache=True)
def _arc_terms(theta, d_left, d_right, wheel_base, turn_slip=0.0):
    """Intermediate terms of one arc step: ds, dtheta, h, sinc(h), sinc'(h), cos, sin(phi).

    ``phi = theta + (1 - 2 turn_slip) h``: the chord's heading, lagging the arc's by the
    declared outward slip ``turn_slip * dtheta`` (module docstring).
    """
    ds = 0.5 * (d_left + d_right)
    dtheta = (d_right - d_left) / wheel_base
    h = 0.5 * dtheta
    if abs(h) < _SERIES_LIMIT:
        h2 = h * h
        k = 1.0 - h2 / 6.0 + h2 * h2 / 120.0
        dk = h * (-1.0 / 3.0 + h2 / 30.0 - h2 * h2 / 840.0)
    else:
        s = math.sin(h)
        k = s / h
        dk = (h * math.cos(h) - s) / (h * h)
    phi = theta + (1.0 - 2.0 * turn_slip) * h
    return ds, dtheta, h, k, dk, math.cos(phi), math.sin(phi)


@compiled.njit(cache=True)
def arc_step(pose, d_left, d_right, wheel_base):
    """Pose after one arc step (module docstring): ``(x, y, theta)`` floats in, floats out.

    The one implementation of differential-drive dead reckoning: the filter's predict and the
    simulated wheel odometry both step with it (the odometry without the declared turn slip:
    it only carries a fix's ranges over a few centimetres). The heading is left unwrapped.
    """
    ds, dtheta, _, k, _, c, s = _arc_terms(pose[2], d_left, d_right, wheel_base)
    return pose[0] + ds * k * c, pose[1] + ds * k * s, pose[2] + dtheta


@compiled.njit(cache=True)
def _propagate_rows(states, d_left, d_right, wheel_base, out, turn_slip):
    for i in range(states.shape[0]):
        ds, dtheta, _, k, _, c, s = _arc_terms(states[i, 2], d_left[i], d_right[i], wheel_base, turn_slip)
        out[i, 0] = states[i, 0] + ds * k * c
        out[i, 1] = states[i, 1] + ds * k * s
        out[i, 2] = states[i, 2] + dtheta


@compiled.njit(cache=True)
def _jacobians_into(theta, d_left, d_right, wheel_base, F, G, turn_slip=0.0):
    ds, _, _, k, dk, c, s = _arc_terms(theta, d_left, d_right, wheel_base, turn_slip)
    lag = 1.0 - 2.0 * turn_slip   # d phi / d h
    F[0, 0] = 1.0
    F[0, 1] = 0.0
    F[0, 2] = -ds * k * s
    F[1, 0] = 0.0
    F[1, 1] = 1.0
    F[1, 2] = ds * k * c
    F[2, 0] = 0.0
    F[2, 1] = 0.0
    F[2, 2] = 1.0
    # d(ds)/d(d_w) = 1/2 for both wheels; dh/d(d_w) = -1/(2b) (left), +1/(2b) (right).
    for j in range(2):
        dh = (-0.5 if j == 0 else 0.5) / wheel_base
        G[0, j] = 0.5 * k * c + ds * dk * dh * c - ds * k * s * lag * dh
        G[1, j] = 0.5 * k * s + ds * dk * dh * s + ds * k * c * lag * dh
        G[2, j] = 2.0 * dh


@compiled.njit(cache=True)
def propagate_moments(x, P, d_left, d_right, wheel_base, var_left, var_right, turn_slip=0.0):
    """Propagate a pose estimate and its covariance through one arc step, in place.

    ``x <- f(x, d)`` and ``P <- F P F^T + G diag(var_left, var_right) G^T``, the EKF predict
    step of this motion model. The heading is left unwrapped.

    Parameters
    ----------
    x : numpy.ndarray, shape (3,), float64, C-contiguous
        Pose (x [m], y [m], theta [rad]); overwritten.
    P : numpy.ndarray, shape (3, 3), float64, C-contiguous
        Pose covariance [m^2, m rad, rad^2]; overwritten.
    d_left, d_right : float
        Measured wheel travel over the step [m].
    wheel_base : float
        Distance between the wheels [m].
    var_left, var_right : float
        Variance of each wheel's travel error over the step [m^2] (already scaled).
    turn_slip : float
        Declared outward slip per radian of the step's heading change [-]
        (``RobotSpec.turn_slip``, module docstring).
    """
    F = np.empty((3, 3))
    G = np.empty((3, 2))
    _jacobians_into(x[2], d_left, d_right, wheel_base, F, G, turn_slip)
    ds, dtheta, _, k, _, c, s = _arc_terms(x[2], d_left, d_right, wheel_base, turn_slip)
    x[0] += ds * k * c
    x[1] += ds * k * s
    x[2] += dtheta
    # Explicit loops: for 3x3 numba's BLAS-backed `@` costs more than the arithmetic.
    FP = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            FP[i, j] = F[i, 0] * P[0, j] + F[i, 1] * P[1, j] + F[i, 2] * P[2, j]
    for i in range(3):
        for j in range(i, 3):
            v = (FP[i, 0] * F[j, 0] + FP[i, 1] * F[j, 1] + FP[i, 2] * F[j, 2]
                 + G[i, 0] * var_left * G[j, 0] + G[i, 1] * var_right * G[j, 1])
            # Writing one triangle into both keeps P exactly symmetric over thousands of steps.
            P[i, j] = v
            P[j, i] = v


@compiled.njit(cache=True)
def propagate_moments_biased(x, P, d_left, d_right, wheel_base, var_left, var_right, bias_walk_var,
                             turn_slip=0.0):
    """EKF predict step of the pose augmented with the relative wheel-radius error, in place.

    The state is ``(x [m], y [m], theta [rad], e [-])``; the true wheel travel is
    ``d_left * (1 - e)`` and ``d_right * (1 + e)`` (right radius ``r (1 + e)``, left
    ``r (1 - e)``, encoders converted with the nominal ``r``). The pose moves by the arc of the
    corrected travel, ``e`` stays (a random constant, plus an optional random walk), and

        P <- F4 P F4^T + Q4,   F4 = [[F, g_e], [0, 1]],   g_e = -d_left G[:, 0] + d_right G[:, 1],
        Q4 = [[G diag(var_left, var_right) G^T, 0], [0, bias_walk_var]]

    with ``F``, ``G`` of :func:`jacobians` at the corrected travel. The heading is left unwrapped.

    Parameters
    ----------
    x : numpy.ndarray, shape (4,), float64, C-contiguous
        Pose and wheel error (x [m], y [m], theta [rad], e [-]); overwritten.
    P : numpy.ndarray, shape (4, 4), float64, C-contiguous
        Its covariance; overwritten.
    d_left, d_right : float
        Wheel travel reported by the encoders over the step (nominal radius) [m].
    wheel_base : float
        Distance between the wheels [m].
    var_left, var_right : float
        Variance of each wheel's random travel error over the step [m^2] (already scaled).
    bias_walk_var : float
        Variance added to ``e`` over the step [-]; 0 for a random constant.
    turn_slip : float
        See :func:`propagate_moments`.
    """
    e = x[3]
    dl = d_left * (1.0 - e)
    dr = d_right * (1.0 + e)
    F = np.zeros((4, 4))
    F3 = np.empty((3, 3))
    G = np.empty((3, 2))
    _jacobians_into(x[2], dl, dr, wheel_base, F3, G, turn_slip)
    for i in range(3):
        for j in range(3):
            F[i, j] = F3[i, j]
        # d f / d e through d(dl)/de = -d_left and d(dr)/de = +d_right.
        F[i, 3] = -d_left * G[i, 0] + d_right * G[i, 1]
    F[3, 3] = 1.0
    ds, dtheta, _, k, _, c, s = _arc_terms(x[2], dl, dr, wheel_base, turn_slip)
    x[0] += ds * k * c
    x[1] += ds * k * s
    x[2] += dtheta
    FP = np.empty((4, 4))
    for i in range(4):
        for j in range(4):
            FP[i, j] = F[i, 0] * P[0, j] + F[i, 1] * P[1, j] + F[i, 2] * P[2, j] + F[i, 3] * P[3, j]
    for i in range(4):
        for j in range(i, 4):
            v = FP[i, 0] * F[j, 0] + FP[i, 1] * F[j, 1] + FP[i, 2] * F[j, 2] + FP[i, 3] * F[j, 3]
            if j < 3:
                v += G[i, 0] * var_left * G[j, 0] + G[i, 1] * var_right * G[j, 1]
            elif i == 3:
                v += bias_walk_var
            P[i, j] = v
            P[j, i] = v


def propagate(state, d_left, d_right, wheel_base: float, turn_slip: float = 0.0) -> np.ndarray:
    """Pose after one arc step of a differential-drive robot (exact for constant wheel speeds).

    Parameters
    ----------
    state : array_like, shape (3,) or (N, 3)
        Pose(s) (x [m], y [m], theta [rad]).
    d_left, d_right : float or array_like, shape (N,)
        Travel of the left and right wheel over the step [m]; broadcast against the poses.
    wheel_base : float
        Distance between the wheels [m].
    turn_slip : float
        Declared outward slip per radian of heading change [-] (module docstring).

    Returns
    -------
    numpy.ndarray, shape like ``state``
        New pose(s); the heading is ``theta + dtheta``, not wrapped.
    """
    states = np.asarray(state, dtype=float)
    rows = np.ascontiguousarray(states.reshape(-1, 3))
    n = rows.shape[0]
    dl = np.ascontiguousarray(np.broadcast_to(np.asarray(d_left, dtype=float), (n,)))
    dr = np.ascontiguousarray(np.broadcast_to(np.asarray(d_right, dtype=float), (n,)))
    out = np.empty_like(rows)
    _propagate_rows(rows, dl, dr, float(wheel_base), out, float(turn_slip))
    return out.reshape(states.shape)


def jacobians(state, d_left: float, d_right: float, wheel_base: float,
              turn_slip: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Jacobians of :func:`propagate` at one pose.

    Parameters
    ----------
    state : array_like, shape (3,)
        Pose (x [m], y [m], theta [rad]).
    d_left, d_right : float
        Wheel travel over the step [m].
    wheel_base : float
        Distance between the wheels [m].
    turn_slip : float
        Declared outward slip per radian of heading change [-].

    Returns
    -------
    F : numpy.ndarray, shape (3, 3)
        d f / d state.
    G : numpy.ndarray, shape (3, 2)
        d f / d (d_left, d_right) [m/m, rad/m].
    """
    F = np.empty((3, 3))
    G = np.empty((3, 2))
    _jacobians_into(float(state[2]), float(d_left), float(d_right), float(wheel_base), F, G, float(turn_slip))
    return F, G
