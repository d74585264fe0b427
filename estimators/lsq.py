"""Weighted Gauss-Newton position from ranges (and bearings).

The inverse of the measurement model: both the snapshot fix and the fault-area construction
start from it. :func:`solve_position` takes bearings in the world frame (a known heading);
:func:`solve_pose` takes them in the robot frame and estimates the heading with the position.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from estimators.measurements import (
    _MIN_RANGE,
    wrap_angle,
)
from jit import compiled


@dataclass(frozen=True)
class LsqSolution:
    """Result of :func:`solve_position`.

    Attributes
    ----------
    position : ndarray, shape (2,)
        Estimated position [m].
    jacobian : ndarray, shape (n, 2)
        Stacked measurement Jacobian at ``position`` (ranges first, then bearings).
    residuals : ndarray, shape (n,)
        Measured minus predicted at ``position`` (ranges [m], then wrapped bearings [rad]).
    iterations : int
        Gauss-Newton iterations taken.
    converged : bool
        True if the last step was shorter than the tolerance.
    heading : float or None
        Estimated heading [rad] in (-pi, pi] (:func:`solve_pose`; None from :func:`solve_position`,
        whose ``jacobian`` then has 2 columns, else 3: x, y, heading).
    """

    position: np.ndarray
    jacobian: np.ndarray
    residuals: np.ndarray
    iterations: int
    converged: bool
    heading: float | None = None


def _stack(p, markers, meas_ranges, world_bearings):
    d = p - markers
    r = np.maximum(np.hypot(d[:, 0], d[:, 1]), _MIN_RANGE)
    res = meas_ranges - r
    jac = d / r[:, None]
    if world_bearings is not None:
        pred = np.arctan2(-d[:, 1], -d[:, 0])
        res = np.concatenate([res, wrap_angle(world_bearings - pred)])
        jac = np.vstack([jac, np.column_stack([-d[:, 1], d[:, 0]]) / (r * r)[:, None]])
    return res, jac


def _normal_step(jw, rw):
    """Gauss-Newton step from the weighted Jacobian (n, 2) and residuals (n,); 2x2 closed form."""
    (a, b), (_, c) = (jw.T @ jw).tolist()
    g0, g1 = (jw.T @ rw).tolist()
    det = a * c - b * b
    if not det > 1e-14 * (a * c + b * b):      # (near) singular: e.g. robot on the marker line
        step, *_ = np.linalg.lstsq(jw, rw, rcond=None)
        return step
    return np.array([(c * g0 - b * g1) / det, (a * g1 - b * g0) / det])


@compiled.njit(cache=True)
def _stack_ranges(px, py, markers, meas, w, res, jac):
    """Fill ``res`` (k,) and ``jac`` (k, 2) at (px, py) as :func:`_stack` does; return the cost."""
    cost = 0.0
    for i in range(markers.shape[0]):
        dx = px - markers[i, 0]
        dy = py - markers[i, 1]
        r = max(math.hypot(dx, dy), _MIN_RANGE)
        res[i] = meas[i] - r
        jac[i, 0] = dx / r
        jac[i, 1] = dy / r
        cost += (res[i] * w[i]) ** 2
    return cost


@compiled.njit(cache=True)
def _gauss_newton_ranges(markers, meas, w, prior, max_iter, step_tol):
    """:func:`solve_position` for ranges only, the same iteration compiled (sums in another order).

    Returns (position (2,), jacobian (k, 2), residuals (k,), iterations, converged, ok);
    ``ok`` is False when a normal matrix was (near) singular: the caller then reruns the
    numpy version, whose least-squares step handles it.
    """
    k = markers.shape[0]
    res, jac = np.empty(k), np.empty((k, 2))
    res_q, jac_q = np.empty(k), np.empty((k, 2))
    px, py = prior[0], prior[1]
    cost = _stack_ranges(px, py, markers, meas, w, res, jac)
    converged, it = False, 0
    while it < max_iter:
        it += 1
        a = b = c = g0 = g1 = 0.0
        for i in range(k):
            j0, j1, rw = jac[i, 0] * w[i], jac[i, 1] * w[i], res[i] * w[i]
            a += j0 * j0
            b += j0 * j1
            c += j1 * j1
            g0 += j0 * rw
            g1 += j1 * rw
        det = a * c - b * b
        if not det > 1e-14 * (a * c + b * b):
            return np.array([px, py]), jac, res, it, converged, False
        sx, sy = (c * g0 - b * g1) / det, (a * g1 - b * g0) / det
        if math.hypot(sx, sy) < step_tol:
            px, py = px + sx, py + sy
            _stack_ranges(px, py, markers, meas, w, res, jac)
            converged = True
            break
        decreased = False
        for _ in range(30):
            qx, qy = px + sx, py + sy
            cost_q = _stack_ranges(qx, qy, markers, meas, w, res_q, jac_q)
            if cost_q <= cost * (1.0 + 1e-12):
                decreased = True
                break
            sx, sy = 0.5 * sx, 0.5 * sy
        if not decreased:
            converged = True
            break
        px, py, cost = qx, qy, cost_q
        res, res_q = res_q, res
        jac, jac_q = jac_q, jac
    return np.array([px, py]), jac, res, it, converged, True


def solve_position(markers: np.ndarray, meas_ranges: np.ndarray, std: np.ndarray, prior: np.ndarray,
                   world_bearings: np.ndarray | None = None, max_iter: int = 20,
                   step_tol: float = 1e-10) -> LsqSolution:
    """Weighted least-squares position from ranges (and world bearings), by Gauss-Newton.

    Minimises ``sum(residual_j^2 / std_j^2)`` starting at ``prior``, halving steps that do not
    decrease it. This usually stays on the prior's side of the line through two markers but
    does not guarantee it: :func:`estimators.snapshot.snapshot_fix` and
    :func:`estimators.fault.exact.exact_fault_area` resolve the mirror ambiguity explicitly.

    Parameters
    ----------
    markers : ndarray, shape (k, 2)
        Marker positions [m].
    meas_ranges : ndarray, shape (k,)
        Measured ranges [m].
    std : ndarray, shape (k,) or (2k,)
        Standard deviations of the range errors [m] (then of the bearing errors [rad]).
    prior : ndarray, shape (2,)
        Starting point [m].
    world_bearings : ndarray, shape (k,), optional
        Measured world-frame directions from the robot to the markers [rad].
    max_iter : int
        Iteration limit.
    step_tol : float
        Convergence when a step is shorter than this [m].

    Returns
    -------
    LsqSolution
    """
    markers = np.asarray(markers, dtype=float).reshape(-1, 2)
    meas_ranges = np.asarray(meas_ranges, dtype=float)
    w = 1.0 / np.asarray(std, dtype=float)
    p = np.array(prior, dtype=float)
    if world_bearings is None and w.shape == meas_ranges.shape == (markers.shape[0],) and p.shape == (2,):
        # The common case, compiled: the same iteration as _gauss_newton (tens of times faster).
        pos, jac, res, it, converged, ok = _gauss_newton_ranges(markers, meas_ranges, w, p, max_iter, step_tol)
        if ok:
            return LsqSolution(position=pos, jacobian=jac, residuals=res, iterations=it, converged=converged)
    return _gauss_newton(markers, meas_ranges, w, p, world_bearings, max_iter, step_tol)


def _gauss_newton(markers, meas_ranges, w, p, world_bearings, max_iter, step_tol):
    """Run the numpy Gauss-Newton of :func:`solve_position` (any measurements; ``w = 1/std``)."""
    res, jac = _stack(p, markers, meas_ranges, world_bearings)
    cost = float(np.sum((res * w) ** 2))
    converged = False
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 -- the count is reported
        step = _normal_step(jac * w[:, None], res * w)
        if math.hypot(step[0], step[1]) < step_tol:
            p = p + step
            res, jac = _stack(p, markers, meas_ranges, world_bearings)
            converged = True
            break
        # Backtrack when a full step overshoots (far priors, near-singular geometry): plain
        # Gauss-Newton can jump across the marker line to the mirror solution.
        for _ in range(30):
            q = p + step
            res_q, jac_q = _stack(q, markers, meas_ranges, world_bearings)
            cost_q = float(np.sum((res_q * w) ** 2))
            if cost_q <= cost * (1.0 + 1e-12):     # within rounding counts as no increase
                break
            step = 0.5 * step
        else:               # no decrease along the step: p is a minimum to rounding
            converged = True
            break
        p, res, jac, cost = q, res_q, jac_q, cost_q
    return LsqSolution(position=p, jacobian=jac, residuals=res, iterations=it, converged=converged)


def _stack_pose(q, markers, meas_ranges, robot_bearings):
    """Residuals (2k,) and Jacobian (2k, 3) of ranges and robot-frame bearings at pose ``q``."""
    d = q[:2] - markers
    r = np.maximum(np.hypot(d[:, 0], d[:, 1]), _MIN_RANGE)
    pred = np.arctan2(-d[:, 1], -d[:, 0]) - q[2]
    res = np.concatenate([meas_ranges - r, wrap_angle(robot_bearings - pred)])
    k = markers.shape[0]
    jac = np.zeros((2 * k, 3))
    jac[:k, :2] = d / r[:, None]
    jac[k:, :2] = np.column_stack([-d[:, 1], d[:, 0]]) / (r * r)[:, None]
    jac[k:, 2] = -1.0
    return res, jac


def solve_pose(markers: np.ndarray, meas_ranges: np.ndarray, robot_bearings: np.ndarray, std: np.ndarray,
               prior: np.ndarray, max_iter: int = 20, step_tol: float = 1e-10) -> LsqSolution:
    """Weighted least-squares pose (position and heading) from ranges and robot-frame bearings.

    Minimises ``sum(residual_j^2 / std_j^2)`` over ``(x, y, theta)`` by Gauss-Newton from
    ``prior``, halving steps that do not decrease it. The heading is an unknown, so the fix owes
    nothing to any other heading estimate: a common error of the frame the bearings were taken
    in cannot enter it. Needs at least three measurements (k >= 2 markers).

    Parameters
    ----------
    markers : ndarray, shape (k, 2)
        Marker positions [m].
    meas_ranges : ndarray, shape (k,)
        Measured ranges [m].
    robot_bearings : ndarray, shape (k,)
        Measured bearings of the markers in the robot frame at ``theta`` [rad].
    std : ndarray, shape (2k,)
        Standard deviations of the range errors [m], then of the bearing errors [rad].
    prior : ndarray, shape (3,)
        Starting pose (x [m], y [m], theta [rad]).
    max_iter : int
        Iteration limit.
    step_tol : float
        Convergence when a step's position part is shorter than this [m].

    Returns
    -------
    LsqSolution
        With ``heading`` set and a (2k, 3) ``jacobian`` (columns x, y, theta).
    """
    markers = np.asarray(markers, dtype=float).reshape(-1, 2)
    meas_ranges = np.asarray(meas_ranges, dtype=float)
    robot_bearings = np.asarray(robot_bearings, dtype=float)
    w = 1.0 / np.asarray(std, dtype=float)
    q = np.array(prior, dtype=float)
    res, jac = _stack_pose(q, markers, meas_ranges, robot_bearings)
    cost = float(np.sum((res * w) ** 2))
    converged = False
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 -- the count is reported
        step, *_ = np.linalg.lstsq(jac * w[:, None], res * w, rcond=None)
        if math.hypot(step[0], step[1]) < step_tol:
            q = q + step
            res, jac = _stack_pose(q, markers, meas_ranges, robot_bearings)
            converged = True
            break
        for _ in range(30):
            trial = q + step
            res_t, jac_t = _stack_pose(trial, markers, meas_ranges, robot_bearings)
            cost_t = float(np.sum((res_t * w) ** 2))
            if cost_t <= cost * (1.0 + 1e-12):
                break
            step = 0.5 * step
        else:
            converged = True
            break
        q, res, jac, cost = trial, res_t, jac_t, cost_t
    return LsqSolution(position=q[:2].copy(), jacobian=jac, residuals=res, iterations=it, converged=converged,
                       heading=float(wrap_angle(q[2])))


compiled.keep_fresh(__name__)
