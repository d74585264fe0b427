"""Dead-reckoning error growth between fixes: a bound from the declared robot.

Between two position fixes the robot integrates wheel odometry and its position error grows.
:func:`drift_bound` bounds that growth after the robot has travelled a path length ``d`` [m]
and turned a total absolute angle ``phi`` [rad] since the last fix, from the *declared* robot
(``scenario.robot``; ``b`` = wheel base). The bound is the sum of four parts (triangle
inequality: along-track and lateral parts are not orthogonal once the path turns).

Systematic wheel-radius error (UMBmark), ``e = |wheel_radius_error|``
    Right wheel ``1 + e``, left ``1 - e`` (and, to be safe, a common scale error of the same
    size). Along-track ``e d``; the heading error grows as ``2 e s / b`` and integrates to a
    lateral error ``e d^2 / b``. A turn makes each wheel travel ``b phi / 2``: heading error
    ``e phi``, lateral ``e phi d`` (as if the turn came first), along-track ``e b phi / 2``.

Random odometry noise, ``sigma = odometry_noise``, bounded at ``k_sigma`` standard deviations
    ``sigma`` is the relative std of each wheel's travel per odometry increment of length
    ``delta`` (``increment``), independent between increments and wheels. After ``d`` each
    wheel's error has std ``sigma sqrt(delta d)``; hence along-track std
    ``sigma sqrt(delta d / 2)``, heading std ``sigma sqrt(2 delta d) / b``, and the lateral
    error, the integral of that heading random walk, std ``sigma sqrt(2 delta / 3) d^1.5 / b``.
    For ``d < delta`` the error within one increment is fully correlated (``delta`` is replaced
    by ``d``). ``increment=None`` bounds the random part as fully correlated over the whole
    stretch (``delta = d``), which holds for any increment but is very pessimistic. The turn
    adds heading std ``sigma sqrt(delta b phi) / b``, acting laterally over ``d``.

Encoder quantisation, ``q = 2 pi r / ticks``
    Encoders count cumulatively, so each wheel is wrong by at most one tick at any time:
    along-track ``q``, heading ``2 q / b``, lateral ``2 q d / b``.

Heading error of the fix itself
    A range-only fix measures position, not heading; the filter's heading error at the fix is
    *neglected* by default. ``heading_error`` [rad] adds its lateral effect
    ``heading_error * d``.
"""

from __future__ import annotations

import math

import numpy as np

from jit import compiled
from scenarios.schema import RobotSpec

K_SIGMA = 3.0
"""Default multiple of a random error's std taken as its bound (99.73 % of a gaussian)."""

DEFAULT_INCREMENT = 0.02
"""Default odometry increment ``delta`` [m]: the travel between two odometry updates, e.g.
1 m/s at 50 Hz. A simulator that updates more often (shorter increments) drifts less than
this bound assumes, so the default is conservative for control rates >= 50 Hz at <= 1 m/s."""


def encoder_step(robot: RobotSpec) -> float:
    """Wheel travel per encoder tick ``q = 2 pi r / ticks`` [m]."""
    return 2.0 * math.pi * robot.wheel_radius / robot.encoder_ticks


def drift_bound(robot: RobotSpec, distance: np.ndarray | float, turned: np.ndarray | float = 0.0,
                k_sigma: float = K_SIGMA, heading_error: float = 0.0,
                increment: float | None = DEFAULT_INCREMENT) -> np.ndarray | float:
    """Bound of the dead-reckoning position error since the last fix (model: module doc).

    Parameters
    ----------
    robot : RobotSpec
        Declared robot spec (wheel base and radius, encoder ticks, wheel_radius_error,
        odometry_noise).
    distance : float or ndarray, shape (...)
        Path length travelled since the last fix [m], >= 0.
    turned : float or ndarray, broadcastable with ``distance``
        Total absolute heading change since the last fix [rad].
    k_sigma : float
        Multiple of the random parts' standard deviations used as their bound.
    heading_error : float
        Heading error bound at the fix [rad]; 0 neglects it.
    increment : float or None
        Odometry increment ``delta`` [m]; None treats the random error as fully correlated.

    Returns
    -------
    float or ndarray, broadcast shape of ``distance`` and ``turned``
        Position error bound [m]; exactly 0 when the robot has neither moved nor turned.
    """
    d, phi = np.asarray(distance, dtype=float), np.abs(np.asarray(turned, dtype=float))
    if d.shape != phi.shape:
        d, phi = np.broadcast_arrays(d, phi)
    shape = d.shape
    d, phi = np.ascontiguousarray(d).reshape(-1), np.ascontiguousarray(phi).reshape(-1)
    out = np.empty(d.size)
    # the power in numpy (its own SIMD loop on some CPUs), the rest compiled: the schedule's search
    # calls this thousands of times on short arrays, where forty numpy calls cost 60 us
    _drift_kernel(d, phi, d ** 1.5, float(robot.wheel_base), float(abs(robot.wheel_radius_error)),
                  float(robot.odometry_noise), float(encoder_step(robot)), float(k_sigma), float(heading_error),
                  increment is None, 0.0 if increment is None else float(increment), math.sqrt(2.0 / 3.0), out)
    return float(out[0]) if len(shape) == 0 else out.reshape(shape)


@compiled.njit(cache=True, nogil=True)
def _drift_kernel(d, phi, d15, b, e, sigma, q, k_sigma, heading_error, correlated, increment, c23, out):
    """:func:`drift_bound` element by element, in numpy's order of operations (correlated: increment None)."""
    half_b = 0.5 * b
    two_q = 2.0 * q
    for i in range(d.size):
        di, ph = d[i], phi[i]
        arc = half_b * ph  # each wheel's travel in the turn [m]
        systematic = e * (di + arc) + e * di * di / b + e * ph * di
        delta_d = di if correlated else min(increment, di)
        delta_t = arc if correlated else min(increment, arc)
        random_std = sigma * (np.sqrt(0.5 * delta_d * di) + c23 * np.sqrt(delta_d) * d15[i] / b
                              + np.sqrt(0.5 * delta_t * arc) + np.sqrt(delta_t * 2.0 * arc) * di / b)
        moved = di > 0.0 or ph > 0.0
        quantisation = (q if moved else 0.0) + two_q * di / b
        out[i] = systematic + k_sigma * random_std + quantisation + heading_error * di
