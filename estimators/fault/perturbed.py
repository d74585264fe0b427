"""A bound on the fault area of a moving fix whose poses are off the planned ones by at most Δ.

The realised fault area ``F`` of a moving fix (:mod:`estimators.fault.carried`) is the
intersection of annuli around the *shifted* markers ``M_i' = M_i + (dead-reckoned shift from the
i-th measurement to the fix's end)`` with measured radii ``r~_i`` and half-widths
``rho~_i = rho(r~_i) + shift_bound_i``. The planner knows the markers, the planned measurement
positions ``p_i`` and a bound ``Δ_i`` on ``|q_i - p_i|`` for the true positions ``q_i``; this
module bounds ``diam F`` for every such fix, whatever the noise (within its bound).

Construction (every step an inequality, no linearisation left unbounded):

1. **A point of F.** Under bounded noise and the odometry bound the truth ``c = q_end`` is in
   ``F`` (the containment check). The direction from ``M_i'`` to ``c`` is that of
   ``q_i - M_i - e_i`` with ``|e_i| <= shift_bound_i`` (the carry keeps the direction of a range),
   so it is the planned direction ``p_i - M_i`` turned by at most
   ``beta_i = asin((Δ_i + sb_i) / r_i)``.
2. **Curvature.** Within the ball ``B(c, D)`` annulus i lies in the strip
   ``r~ - rho~ - D^2 / (2 (r~ - rho~ - D)) <= u_i(c) . (p - M_i') <= r~ + rho~`` (the outer circle
   is outside its tangent line; the inner circle bulges in by at most its sagitta over a chord
   of half-length D): half-width ``h_i = rho~_i + D^2 / (4 (r~_i - rho~_i - D))``.
3. **Widths.** ``rho~_i <= rho(r_i + Δ_i + rho_i) / (1 - Re) + shift_bound(travel_i)``, with the
   travel over the shift bounded by the caller (at most the robot's top speed times the time).
4. **The strips' polygon.** Two strips of normals at angle ``a`` form a parallelogram of diagonal
   ``2 / sin a * sqrt(h1^2 + h2^2 + 2 h1 h2 |cos a|)`` (paper eq. 12), which grows as ``a`` moves
   away from 90 deg: with ``|a - a_plan| <= beta_1 + beta_2`` its largest value is at the end of
   that interval farthest from 90 deg. For k > 2 strips, turning normal i by ``beta_i`` moves
   the strip's edge by at most ``beta_i D`` over ``B(c, D)``: ``F`` lies in the strip polygon of
   the planned normals with half-widths ``h_i + beta_i D`` (:func:`strip_diameters`).
5. **Closing the ball.** If the polygon's diameter ``d`` is below ``D``, the polygon (it holds
   ``c``) lies inside ``B(c, d)``, so the component of ``F`` through ``c`` cannot reach the
   sphere ``|p - c| = D``: ``diam F <= d``. :func:`perturbed_diameters` finds such a ``D`` by
   iteration, or reports inf.

Assumptions: the noise within its declared bound, the odometry within
:func:`estimators.fault.carried.shift_bound` at a heading std no larger than the plan's, the
realised component the one holding the truth, and the ``Δ_i`` the caller states.
"""

from __future__ import annotations

import math

import numpy as np

from estimators.fault.carried import shift_bound
from estimators.fault.linearized import strip_diameters
from scenarios.schema import RobotSpec, SensorSpec

BALL_STEPS = 12
"""Iterations of step 5 before a fix's bound is given up as inf (each grows D by 5 %)."""


def _parallelogram_diagonal(h1, h2, sin_a, cos_a):
    with np.errstate(divide="ignore", invalid="ignore"):
        return 2.0 / sin_a * np.sqrt(h1 * h1 + h2 * h2 + 2.0 * h1 * h2 * np.abs(cos_a))


def perturbed_diameters(sensor: SensorSpec, robot: RobotSpec, markers, poses, delta, travel,
                        heading_std: float) -> np.ndarray:
    """Bound on the realised fault-area diameter of moving fixes with poses within ``delta`` (module docstring).

    Parameters
    ----------
    sensor, robot : SensorSpec, RobotSpec
        The declared sensor (range bound) and robot (odometry bound).
    markers : array_like, shape (F, k, 2)
        Each fix's markers in measurement order [m].
    poses : array_like, shape (F, k, 2)
        Planned position at each measurement [m]; the last is the fix's position.
    delta : array_like, shape (F, k)
        Bound on the distance of each true measurement position from the planned one [m].
    travel : array_like, shape (F, k)
        Bound on the dead-reckoned travel from each measurement to the fix's end [m] (0 for the
        last, which is not carried).
    heading_std : float
        Heading std the shift is turned with [rad] (the plan's assumption).

    Returns
    -------
    numpy.ndarray, shape (F,)
        Bound on the diameter [m]; inf where none closes (step 5) or a direction may turn by
        90 deg or more.
    """
    m = np.asarray(markers, dtype=float)
    p = np.asarray(poses, dtype=float)
    dl = np.asarray(delta, dtype=float)
    tr = np.asarray(travel, dtype=float)
    n_fix, k = m.shape[0], m.shape[1]
    out = np.full(n_fix, np.inf)
    if n_fix == 0 or k < 2:
        return out
    v = p - m
    r = np.hypot(v[..., 0], v[..., 1])
    u = v / np.where(r > 0, r, 1.0)[..., None]
    carried = (np.arange(k) < k - 1)[None, :]
    sb = np.where(carried, shift_bound(robot, np.maximum(tr, 0.0).ravel(), heading_std).reshape(tr.shape), 0.0)
    rel = sensor.relative_error
    r_hi = r + dl
    rho_true = sensor.range_bound(r_hi)
    rho = sensor.range_bound(r_hi + rho_true) / (1.0 - rel) + sb            # step 3
    r_lo = r - dl - rho_true - rho                                          # r~ - rho~ at least
    with np.errstate(divide="ignore", invalid="ignore"):
        beta = np.where((dl + sb) < r, np.arcsin(np.minimum((dl + sb) / np.where(r > 0, r, 1.0), 1.0)), np.inf)
    ok = np.all(r > 0, axis=1) & np.all(np.isfinite(beta), axis=1)

    if k == 2:
        a = np.arctan2(np.abs(u[:, 0, 0] * u[:, 1, 1] - u[:, 0, 1] * u[:, 1, 0]),
                       u[:, 0, 0] * u[:, 1, 0] + u[:, 0, 1] * u[:, 1, 1])     # in [0, pi]
        b = beta.sum(axis=1)
        worst = np.where(a >= 0.5 * math.pi, a + b, a - b)                  # step 4: farthest from 90 deg
        ok &= (worst > 0.0) & (worst < math.pi)
        worst = np.where(ok, worst, 0.5 * math.pi)  # no bound there (inf below); keeps sin finite
        sin_w, cos_w = np.sin(worst), np.cos(worst)

        def diameter(ball, rows):
            h = rho[rows] + ball[:, None] ** 2 / (4.0 * (r_lo[rows] - ball[:, None]))
            good = np.all(r_lo[rows] - ball[:, None] > 0.0, axis=1)
            return np.where(good, _parallelogram_diagonal(h[:, 0], h[:, 1], sin_w[rows], cos_w[rows]), np.inf)
    else:
        def diameter(ball, rows):
            h = rho[rows] + ball[:, None] ** 2 / (4.0 * (r_lo[rows] - ball[:, None])) + beta[rows] * ball[:, None]
            good = np.all(r_lo[rows] - ball[:, None] > 0.0, axis=1) & ok[rows]
            d = np.full(len(ball), np.inf)
            d[good] = strip_diameters(u[rows][good], h[good])
            return d

    ball = np.where(ok, diameter(np.zeros(n_fix), np.arange(n_fix)), np.inf)
    ball = np.where(np.isfinite(ball), 1.05 * ball, np.inf)
    # each fix's iteration is its own: only the fixes still open are evaluated again
    todo = np.flatnonzero(np.isfinite(ball))
    for _ in range(BALL_STEPS):                                             # step 5
        if not todo.size:
            break
        d = diameter(ball[todo], todo)
        closed = d < ball[todo]
        out[todo[closed]] = d[closed]
        grow = ~closed & np.isfinite(d)
        ball[todo[grow]] = 1.05 * np.maximum(d[grow], ball[todo[grow]])
        ball[todo[~closed & ~grow]] = np.inf
        todo = todo[grow]
    return out
