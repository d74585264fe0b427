"""Snapshot fix: the position from one set of marker measurements, without the filter.

Weighted least squares (Gauss-Newton from a prior) gives the point estimate and its
covariance ``P = (H^T W H)^-1`` with ``W = diag(1 / std^2)``, where ``std`` is the standard
deviation of the realised errors (:func:`estimators.measurements.range_std`). The realised
exact fault area of the same measurements comes with it.

Bearings are supported with a *known* heading (e.g. the filter's): a robot-frame bearing
``b_i`` becomes the world direction ``b_i + heading``; the heading's own error is not
propagated into the covariance or the fault area.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from estimators.fault_area import FaultArea, exact_fault_area
from estimators.measurements import bearing_std, range_std, solve_position, wrap_angle
from scenarios.schema import NoiseModel


@dataclass(frozen=True)
class SnapshotFix:
    """A least-squares fix from one set of measurements.

    Attributes
    ----------
    position : ndarray, shape (2,)
        Estimated position [m].
    covariance : ndarray, shape (2, 2)
        ``(H^T W H)^-1`` at ``position`` [m^2]; ``inf`` everywhere when the geometry is
        singular (e.g. the robot on the line through two markers).
    fault_area : FaultArea
        Exact fault area of the measurements (component at ``position``).
    residuals : ndarray, shape (k,) or (2k,)
        Measured minus predicted at ``position``: ranges [m], then bearings [rad].
    iterations : int
        Gauss-Newton iterations.
    converged : bool
        Whether Gauss-Newton converged.
    """

    position: np.ndarray
    covariance: np.ndarray
    fault_area: FaultArea
    residuals: np.ndarray
    iterations: int
    converged: bool


def _side(p, a, b):
    """Sign of the cross product (b - a) x (p - a): which side of line a-b ``p`` is on."""
    return math.copysign(1.0, (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]))


def snapshot_fix(markers: np.ndarray, ranges: np.ndarray, rho: np.ndarray, prior: np.ndarray,
                 noise: NoiseModel, bearings: np.ndarray | None = None, bearing_error: float = 0.0,
                 heading: float | None = None) -> SnapshotFix:
    """Weighted least-squares position fix and its fault area.

    Parameters
    ----------
    markers : ndarray, shape (k, 2)
        Marker positions [m].
    ranges : ndarray, shape (k,)
        Measured ranges [m].
    rho : ndarray, shape (k,)
        Range error bounds [m] (> 0); the weights use ``range_std(rho, noise)``.
    prior : ndarray, shape (2,)
        Starting point [m]; with two ranges the fix is on the prior's side of the marker line.
    noise : NoiseModel
        How the errors are realised (sets std from the bounds).
    bearings : ndarray, shape (k,), optional
        Measured bearings of the markers in the robot frame [rad].
    bearing_error : float
        Bound xi of the bearing errors [rad]; > 0 when ``bearings`` are given.
    heading : float, optional
        Robot heading [rad], required with ``bearings`` and taken as exact.

    Returns
    -------
    SnapshotFix
    """
    markers = np.asarray(markers, dtype=float).reshape(-1, 2)
    meas = np.asarray(ranges, dtype=float)
    rho = np.asarray(rho, dtype=float)
    prior = np.asarray(prior, dtype=float)
    k = markers.shape[0]
    if meas.shape != (k,) or rho.shape != (k,):
        raise ValueError(f"snapshot_fix: ranges {meas.shape} and rho {rho.shape} must be ({k},)")
    std = np.asarray(range_std(rho, noise), dtype=float)
    world = None
    if bearings is not None:
        if heading is None:
            raise ValueError("snapshot_fix: bearings given without the heading")
        world = wrap_angle(np.asarray(bearings, dtype=float) + float(heading))
        std = np.concatenate([std, np.full(k, bearing_std(float(bearing_error), noise))])

    sol = solve_position(markers, meas, std, prior, world_bearings=world)
    position = sol.position
    if world is None and k == 2 and _side(position, *markers) != _side(prior, *markers):
        # Both mirror points fit equally well; the prior decides (DESIGN §1).
        d = (markers[1] - markers[0]) / np.linalg.norm(markers[1] - markers[0])
        v = position - markers[0]
        position = markers[0] + 2.0 * (v @ d) * d - v
        sol = solve_position(markers, meas, std, position)

    jw = sol.jacobian / std[:, None]
    info = jw.T @ jw
    if abs(np.linalg.det(info)) <= 1e-14 * float(np.trace(info)) ** 2:
        covariance = np.full((2, 2), math.inf)
    else:
        covariance = np.linalg.inv(info)
    area = exact_fault_area(markers, meas, rho, sol.position, bearings=world,
                            bearing_error=bearing_error)
    return SnapshotFix(position=sol.position, covariance=covariance, fault_area=area,
                       residuals=sol.residuals, iterations=sol.iterations, converged=sol.converged)
