"""Measurement models of the marker sensor: ranges and bearings, their Jacobians and noise.

A marker ``M_i`` seen from the robot at ``R`` gives the range ``r_i = |R - M_i|`` and, when
the sensor measures angles, the bearing of the marker in the robot frame. Errors are bounded
(`docs/design.md` §1): ``|e_i| <= rho_i`` with ``rho_i = Re * r_i + rho0`` for ranges and ``+-xi`` for
bearings, realised either uniform in the bound or gaussian with ``sigma = bound / 3``.

The inverse, the weighted least-squares position, is in :mod:`estimators.lsq`.
"""

from __future__ import annotations

import math

import numpy as np

from scenarios.schema import NoiseModel, SensorSpec

# Below this range [m] a marker is "at" the robot: the range Jacobian is undefined there.
_MIN_RANGE = 1e-12


def wrap_angle(a: np.ndarray | float) -> np.ndarray | float:
    """Wrap angles to (-pi, pi].

    Parameters
    ----------
    a : array_like or float
        Angles [rad], any shape.

    Returns
    -------
    ndarray or float
        Same shape, each angle moved by a multiple of 2*pi into (-pi, pi].
    """
    w = np.pi - np.mod(np.pi - np.asarray(a, dtype=float), 2.0 * np.pi)
    return float(w) if np.ndim(w) == 0 else w


def ranges(points: np.ndarray, markers: np.ndarray) -> np.ndarray:
    """Distances from points to markers.

    Parameters
    ----------
    points : ndarray, shape (..., 2)
        Robot positions [m].
    markers : ndarray, shape (M, 2)
        Marker positions [m].

    Returns
    -------
    ndarray, shape (..., M)
        ``|points - markers_j|`` [m].
    """
    p = np.asarray(points, dtype=float)
    m = np.asarray(markers, dtype=float).reshape(-1, 2)
    d = p[..., None, :] - m
    return np.hypot(d[..., 0], d[..., 1])


def range_jacobian(position: np.ndarray, markers: np.ndarray) -> np.ndarray:
    """Jacobian of the ranges with respect to the robot position.

    Parameters
    ----------
    position : ndarray, shape (2,)
        Robot position R [m].
    markers : ndarray, shape (k, 2)
        Marker positions [m].

    Returns
    -------
    ndarray, shape (k, 2)
        Rows ``u_i^T`` with ``u_i = (R - M_i) / r_i`` (unit vectors, dimensionless).
    """
    d = np.asarray(position, dtype=float) - np.asarray(markers, dtype=float).reshape(-1, 2)
    r = np.hypot(d[:, 0], d[:, 1])
    return d / np.maximum(r, _MIN_RANGE)[:, None]


def world_bearing(position: np.ndarray, markers: np.ndarray) -> np.ndarray:
    """Directions from the robot to the markers in the world frame.

    Parameters
    ----------
    position : ndarray, shape (2,)
        Robot position [m].
    markers : ndarray, shape (k, 2)
        Marker positions [m].

    Returns
    -------
    ndarray, shape (k,)
        ``atan2(M_i - R)`` [rad] in (-pi, pi].
    """
    d = np.asarray(markers, dtype=float).reshape(-1, 2) - np.asarray(position, dtype=float)
    return np.arctan2(d[:, 1], d[:, 0])


def world_bearing_jacobian(position: np.ndarray, markers: np.ndarray) -> np.ndarray:
    """Jacobian of :func:`world_bearing` with respect to the robot position.

    Parameters
    ----------
    position : ndarray, shape (2,)
        Robot position [m].
    markers : ndarray, shape (k, 2)
        Marker positions [m].

    Returns
    -------
    ndarray, shape (k, 2)
        Rows ``(dy_i, -dx_i) / r_i^2`` with ``(dx_i, dy_i) = M_i - R`` [rad/m].
    """
    d = np.asarray(markers, dtype=float).reshape(-1, 2) - np.asarray(position, dtype=float)
    r2 = np.maximum(np.einsum("ij,ij->i", d, d), _MIN_RANGE**2)
    return np.column_stack([d[:, 1] / r2, -d[:, 0] / r2])


def bearing(pose: np.ndarray, markers: np.ndarray) -> np.ndarray:
    """Bearings of the markers in the robot frame.

    Parameters
    ----------
    pose : ndarray, shape (3,)
        Robot pose (x [m], y [m], theta [rad]).
    markers : ndarray, shape (k, 2)
        Marker positions [m].

    Returns
    -------
    ndarray, shape (k,)
        ``wrap(atan2(M_i - R) - theta)`` [rad] in (-pi, pi].
    """
    pose = np.asarray(pose, dtype=float)
    return wrap_angle(world_bearing(pose[:2], markers) - pose[2])


def bearing_jacobian(pose: np.ndarray, markers: np.ndarray) -> np.ndarray:
    """Jacobian of :func:`bearing` with respect to the pose (x, y, theta).

    Parameters
    ----------
    pose : ndarray, shape (3,)
        Robot pose (x [m], y [m], theta [rad]).
    markers : ndarray, shape (k, 2)
        Marker positions [m].

    Returns
    -------
    ndarray, shape (k, 3)
        Rows ``(dy_i / r_i^2, -dx_i / r_i^2, -1)`` with ``(dx_i, dy_i) = M_i - R``.
    """
    pose = np.asarray(pose, dtype=float)
    jp = world_bearing_jacobian(pose[:2], markers)
    return np.column_stack([jp, -np.ones(jp.shape[0])])


def range_bound(sensor: SensorSpec, r: np.ndarray | float) -> np.ndarray | float:
    """Bound of the range error, ``rho = Re * r + rho0`` [m].

    Parameters
    ----------
    sensor : SensorSpec
        Gives ``Re`` (``relative_error``) and ``rho0`` (``absolute_error``).
    r : array_like or float
        True (or measured) ranges [m], any shape.

    Returns
    -------
    ndarray or float
        rho [m], same shape as ``r``.
    """
    return sensor.range_bound(np.asarray(r, dtype=float) if np.ndim(r) else float(r))


def bound_std(bound: np.ndarray | float, noise: NoiseModel) -> np.ndarray | float:
    """Return the standard deviation of an error realised from its bound.

    Parameters
    ----------
    bound : array_like or float
        Error bound (rho [m] or xi [rad]), any shape.
    noise : NoiseModel
        ``uniform`` in +-bound (std = bound / sqrt(3)) or ``gaussian`` (std = bound / 3).

    Returns
    -------
    ndarray or float
        The standard deviation, same shape and unit as ``bound``.
    """
    b = np.asarray(bound, dtype=float)
    noise = NoiseModel(noise)
    s = b / math.sqrt(3.0) if noise is NoiseModel.UNIFORM else b / 3.0
    return float(s) if s.ndim == 0 else s


def range_std(rho: np.ndarray | float, noise: NoiseModel) -> np.ndarray | float:
    """Return the standard deviation of the realised range error [m] (see :func:`bound_std`)."""
    return bound_std(rho, noise)


def bearing_std(xi: np.ndarray | float, noise: NoiseModel) -> np.ndarray | float:
    """Return the standard deviation of the realised bearing error [rad] (:func:`bound_std`)."""
    return bound_std(xi, noise)


def _draw(rng: np.random.Generator, bound: np.ndarray, noise: NoiseModel) -> np.ndarray:
    noise = NoiseModel(noise)
    if noise is NoiseModel.UNIFORM:
        return rng.uniform(-1.0, 1.0, size=bound.shape) * bound
    return rng.standard_normal(size=bound.shape) * (bound / 3.0)


def draw_range_errors(rng: np.random.Generator, rho: np.ndarray, noise: NoiseModel) -> np.ndarray:
    """Draw range errors for one fix.

    Parameters
    ----------
    rng : numpy.random.Generator
        The only source of randomness.
    rho : ndarray, shape (k,)
        Error bounds [m].
    noise : NoiseModel
        ``uniform`` in +-rho, or ``gaussian`` with sigma = rho / 3 (unbounded).

    Returns
    -------
    ndarray, shape (k,)
        Errors [m] to add to the true ranges.
    """
    return _draw(rng, np.asarray(rho, dtype=float), noise)


def draw_bearing_errors(rng: np.random.Generator, xi: float, n: int, noise: NoiseModel) -> np.ndarray:
    """Draw ``n`` bearing errors bounded by ``xi``.

    Parameters
    ----------
    rng : numpy.random.Generator
        The only source of randomness.
    xi : float
        Bearing error bound [rad].
    n : int
        Number of bearings.
    noise : NoiseModel
        ``uniform`` in +-xi, or ``gaussian`` with sigma = xi / 3.

    Returns
    -------
    ndarray, shape (n,)
        Errors [rad] to add to the true bearings.
    """
    return _draw(rng, np.full(int(n), float(xi)), noise)


def collinear_markers(markers: np.ndarray) -> bool:
    """Tell whether the markers lie on one line (always so for two; never for one).

    Ranges alone then cannot tell a position from its mirror image across that line.

    Parameters
    ----------
    markers : ndarray, shape (k, 2)
        Marker positions [m].
    """
    markers = np.asarray(markers, dtype=float).reshape(-1, 2)
    if markers.shape[0] < 3:
        return markers.shape[0] == 2
    d = markers[1:] - markers[0]
    i = int(np.argmax(np.einsum("ij,ij->i", d, d)))
    cross = d[:, 0] * d[i, 1] - d[:, 1] * d[i, 0]
    return bool(np.all(np.abs(cross) <= 1e-12 * float(d[i] @ d[i])))


def _marker_line(markers):
    a = markers[0]
    d = markers[int(np.argmax(np.hypot(*(markers - a).T)))] - a
    return a, d / math.hypot(d[0], d[1])


def marker_line_side(points: np.ndarray, markers: np.ndarray) -> np.ndarray:
    """Side of the line through collinear markers on which each point lies.

    Parameters
    ----------
    points : ndarray, shape (..., 2)
        Points [m].
    markers : ndarray, shape (k, 2)
        Collinear markers (k >= 2, see :func:`collinear_markers`) [m].

    Returns
    -------
    ndarray, shape (...)
        +1 left of the line (from the first marker toward the farthest one), -1 right, 0 on it.
    """
    a, d = _marker_line(np.asarray(markers, dtype=float).reshape(-1, 2))
    p = np.asarray(points, dtype=float)
    return np.sign(d[0] * (p[..., 1] - a[1]) - d[1] * (p[..., 0] - a[0]))


def reflect_across_marker_line(points: np.ndarray, markers: np.ndarray) -> np.ndarray:
    """Mirror images of points across the line through collinear markers.

    Parameters
    ----------
    points : ndarray, shape (..., 2)
        Points [m].
    markers : ndarray, shape (k, 2)
        Collinear markers (k >= 2) [m].

    Returns
    -------
    ndarray, shape (..., 2)
        Reflected points [m]; they have the same ranges to every marker.
    """
    a, d = _marker_line(np.asarray(markers, dtype=float).reshape(-1, 2))
    v = np.asarray(points, dtype=float) - a
    return a + 2.0 * (v @ d)[..., None] * d - v
