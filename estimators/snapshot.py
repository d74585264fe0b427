"""Snapshot fix: the position from one set of marker measurements, without the filter.

Weighted least squares (Gauss-Newton from a prior) gives the point estimate and its
covariance ``P = (H^T W H)^-1`` with ``W = diag(1 / std^2)``, where ``std`` is the standard
deviation of the realised errors (:func:`estimators.measurements.range_std`). The realised
exact fault area of the same measurements comes with it.

With bearings (robot frame) the heading is a third unknown of the least squares
(:func:`estimators.lsq.solve_pose`): the fix is then a function of its own measurements
alone, and ``P`` is the position block of the pose's ``(H^T W H)^-1``. Any other heading
(the filter's) has an error common to every bearing and, having been updated with these same
bearings, correlated with their errors; neither a diagonal ``W`` nor an independent heading
variance describes that. The heading given is only the starting point of the solve.

The realised fault area does not use any heading: the robot-frame bearings constrain the
position through their pairwise differences (:func:`estimators.fault.exact.exact_fault_area`,
"Robot-frame bearings"), so under bounded errors the truth is in it whatever the heading
estimate's error (a filter heading's 3-sigma wedges missed the truth at 4 of 17,300 fixes).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from estimators.fault.annuli import marker_side
from estimators.fault.exact import FaultArea, exact_fault_area
from estimators.lsq import solve_pose, solve_position
from estimators.measurements import (
    bearing_std,
    collinear_markers,
    marker_line_side,
    range_std,
    reflect_across_marker_line,
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
    heading : float or None
        The heading estimated with the position [rad] (None without bearings).
    """

    position: np.ndarray
    covariance: np.ndarray
    fault_area: FaultArea
    residuals: np.ndarray
    iterations: int
    converged: bool
    heading: float | None = None


def snapshot_fix(markers: np.ndarray, ranges: np.ndarray, rho: np.ndarray, prior: np.ndarray,
                 noise: NoiseModel, bearings: np.ndarray | None = None, bearing_error: float = 0.0,
                 heading: float | None = None, extra_var: np.ndarray | None = None,
                 fault_margin: np.ndarray | None = None, bearing_margin: np.ndarray | None = None,
                 fault_markers: np.ndarray | None = None,
                 bearing_extra_var: np.ndarray | None = None) -> SnapshotFix:
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
        Robot heading [rad], required with ``bearings``: where the estimated heading starts
        (the fault area does not use it).
    extra_var : ndarray, shape (k,) or (k, k), optional
        Variance added to each range's error variance in the weights and the covariance
        [m^2] (e.g. the odometry error of carrying a range taken earlier to the fix time); a
        (k, k) matrix is the covariance of these extra errors (shared between ranges, e.g.
        shifts with a common end): the weights use its diagonal, so the position is the same,
        and ``covariance`` is the covariance of that weighted estimate under the whole matrix,
        ``P + P H^T W C_off W H P`` with ``C_off`` its off-diagonal part.
    fault_margin : ndarray, shape (k,), optional
        Added to ``rho`` for the fault area only [m] (a bound on the same extra error).
    bearing_margin : ndarray, shape (k,), optional
        Added to ``bearing_error`` for the fault area only [rad]: a bound on the extra error of
        each bearing (e.g. one taken earlier, turned into the last one's frame by odometry).
    fault_markers : ndarray, shape (k, 2), optional
        Marker positions for the fault area only [m], by default ``markers``: a bound may use
        a geometry the estimate must not (earlier ranges carried with a heading corrected by
        these same ranges: tighter, but its error correlated with theirs).
    bearing_extra_var : ndarray, shape (k,) or (k, k), optional
        As ``extra_var``, for the bearings [rad^2] (e.g. the odometry's turn error of carrying a
        bearing taken earlier into the last one's frame); with ``bearings`` only. Its
        off-diagonal part enters the covariance as ``extra_var``'s does.

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
    shared = None
    if extra_var is not None:
        extra = np.asarray(extra_var, dtype=float)
        if extra.ndim == 2:
            shared = extra - np.diag(np.diag(extra))
            extra = np.diag(extra)
        std = np.sqrt(std**2 + extra)
    robot_frame = None
    if bearings is not None:
        if heading is None:
            raise ValueError("snapshot_fix: bearings given without the heading")
        robot_frame = np.asarray(bearings, dtype=float)
        bstd = np.full(k, bearing_std(float(bearing_error), noise))
        if bearing_extra_var is not None:
            bextra = np.asarray(bearing_extra_var, dtype=float)
            if bextra.ndim == 2:
                off = bextra - np.diag(np.diag(bextra))
                shared = np.zeros((2 * k, 2 * k)) if shared is None else np.pad(shared, (0, k))
                shared[k:, k:] = off
                bextra = np.diag(bextra)
            bstd = np.sqrt(bstd**2 + bextra)
        std = np.concatenate([std, bstd])
        sol = solve_pose(markers, meas, robot_frame, std, np.r_[prior, float(heading)])
        covariance = _pose_position_covariance(sol.jacobian, std, shared)
    else:
        sol = solve_position(markers, meas, std, prior)
        if _across_marker_line(sol.position, prior, markers):
            # Both mirror points fit equally well; the prior decides (`docs/design.md` §1).
            sol = solve_position(markers, meas, std, reflect_across_marker_line(sol.position, markers))
        covariance = _covariance(sol.jacobian, std)
        if shared is not None and np.isfinite(covariance).all():
            g = covariance @ (sol.jacobian / (std * std)[:, None]).T     # (2, k): the estimate's gain
            covariance = covariance + g @ shared @ g.T

    fault_rho = rho if fault_margin is None else rho + np.asarray(fault_margin, dtype=float)
    area_markers = markers if fault_markers is None else np.asarray(fault_markers, dtype=float).reshape(k, 2)
    if robot_frame is None:
        area = exact_fault_area(area_markers, meas, fault_rho, sol.position)
    else:
        xi = np.full(k, float(bearing_error)) + (0.0 if bearing_margin is None
                                                 else np.asarray(bearing_margin, dtype=float))
        area = exact_fault_area(area_markers, meas, fault_rho, sol.position, robot_bearings=robot_frame,
                                robot_bearing_error=xi)
    return SnapshotFix(position=sol.position, covariance=covariance, fault_area=area,
                       residuals=sol.residuals, iterations=sol.iterations, converged=sol.converged,
                       heading=sol.heading)


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


def _pose_position_covariance(jacobian, std, shared=None):
    """Position block (2, 2) [m^2] of the pose's ``(H^T W H)^-1``; ``inf`` where (near) singular.

    The inverse of the Schur complement ``A - b b^T / c`` of the heading in the information
    matrix ``[[A, b], [b^T, c]]``: what the position keeps once the heading is estimated too.
    ``shared`` (m, m), the off-diagonal covariance of the first m measurements' errors (the
    ranges, or the ranges then the bearings: the first m rows of ``jacobian``), adds
    ``G shared G^T`` with ``G`` the position rows of the estimate's gain.
    """
    jw = jacobian / std[:, None]
    info = jw.T @ jw
    schur = info[:2, :2] - np.outer(info[:2, 2], info[:2, 2]) / info[2, 2]
    (a, b), (_, c) = schur.tolist()
    det = a * c - b * b
    if not det > 1e-14 * (a + c) ** 2:
        return np.full((2, 2), math.inf)
    cov = np.array([[c / det, -b / det], [-b / det, a / det]])
    if shared is None:
        return cov
    k = shared.shape[0]
    g = np.linalg.solve(info, (jw / std[:, None]).T)[:2, :k]   # position rows of (J^T W J)^-1 J^T W
    return cov + g @ shared @ g.T
