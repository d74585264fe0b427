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

import functools
import math
from dataclasses import dataclass

import numpy as np

from estimators.fault.annuli import marker_side
from estimators.fault.exact import FaultArea, exact_fault_area
from estimators.lsq import solve_position
from estimators.measurements import (
    bearing_std,
    collinear_markers,
    marker_line_side,
    range_std,
    reflect_across_marker_line,
    wrap_angle,
)
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


def snapshot_fix(markers: np.ndarray, ranges: np.ndarray, rho: np.ndarray, prior: np.ndarray,
                 noise: NoiseModel, bearings: np.ndarray | None = None, bearing_error: float = 0.0,
                 heading: float | None = None, extra_var: np.ndarray | None = None,
                 fault_margin: np.ndarray | None = None) -> SnapshotFix:
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
        Starting point [m]. Ranges to collinear markers (always with two) fit a point and its
        mirror image across the marker line equally well: the fix is on the prior's side.
    noise : NoiseModel
        How the errors are realised (sets std from the bounds).
    bearings : ndarray, shape (k,), optional
        Measured bearings of the markers in the robot frame [rad].
    bearing_error : float
        Bound xi of the bearing errors [rad]; > 0 when ``bearings`` are given.
    heading : float, optional
        Robot heading [rad], required with ``bearings`` and taken as exact.
    extra_var : ndarray, shape (k,), optional
        Variance added to each range's error variance in the weights and the covariance
        [m^2] (e.g. the odometry error of carrying a range taken earlier to the fix time).
    fault_margin : ndarray, shape (k,), optional
        Added to ``rho`` for the fault area only [m] (a bound on the same extra error).

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
    # std is linear in the bound: one factor per noise model
    std = rho * _std_per_bound(noise)
    if extra_var is not None:
        std = np.sqrt(std**2 + np.asarray(extra_var, dtype=float))
    world = None
    if bearings is not None:
        if heading is None:
            raise ValueError("snapshot_fix: bearings given without the heading")
        world = wrap_angle(np.asarray(bearings, dtype=float) + float(heading))
        std = np.concatenate([std, np.full(k, bearing_std(float(bearing_error), noise))])

    sol = solve_position(markers, meas, std, prior, world_bearings=world)
    if world is None and _across_marker_line(sol.position, prior, markers):
        # Both mirror points fit equally well; the prior decides (`docs/design.md` §1).
        sol = solve_position(markers, meas, std, reflect_across_marker_line(sol.position, markers))

    fault_rho = rho if fault_margin is None else rho + np.asarray(fault_margin, dtype=float)
    area = exact_fault_area(markers, meas, fault_rho, sol.position, bearings=world,
                            bearing_error=bearing_error)
    return SnapshotFix(position=sol.position, covariance=_covariance(sol.jacobian, std), fault_area=area,
                       residuals=sol.residuals, iterations=sol.iterations, converged=sol.converged)


def _across_marker_line(position, prior, markers):
    """Tell whether ``position`` and ``prior`` lie strictly on opposite sides of collinear markers."""
    if markers.shape[0] == 2:           # always collinear: the side in plain floats
        return marker_side(position, markers) * marker_side(prior, markers) < 0.0
    return bool(collinear_markers(markers)
                and marker_line_side(position, markers) * marker_line_side(prior, markers) < 0)


@functools.lru_cache(maxsize=4)
def _std_per_bound(noise: NoiseModel) -> float:
    return float(range_std(1.0, noise))


def _covariance(jacobian, std):
    """``(H^T W H)^-1`` (2, 2) [m^2] in closed form; ``inf`` where (near) singular."""
    a = b = c = 0.0
    for (hx, hy), s in zip(jacobian.tolist(), std.tolist(), strict=True):  # k rows: floats beat numpy
        w = 1.0 / (s * s)
        a += hx * hx * w
        b += hx * hy * w
        c += hy * hy * w
    det = a * c - b * b
    if abs(det) <= 1e-14 * (a + c) ** 2:
        return np.full((2, 2), math.inf)
    return np.array([[c / det, -b / det], [-b / det, a / det]])
