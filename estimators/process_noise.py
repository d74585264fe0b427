"""Process noise of the odometry motion model: each wheel's travel variance per step and ``Q``.

The model is described in :mod:`estimators.motion` (slip per increment, the white encoder
quantisation of the plain model, the variance floor, the optional systematic term).
"""

from __future__ import annotations

import math

import numpy as np

from estimators.motion import VARIANCE_FLOOR, jacobians
from scenarios.schema import RobotSpec


def variance_terms(robot: RobotSpec, include_systematic: bool = False) -> tuple[float, float]:
    """Coefficients of the per-wheel travel variance ``var_w = rel_var * d_w**2 + base_var``.

    Parameters
    ----------
    robot : RobotSpec
        The declared robot (``odometry_noise``, ``wheel_radius``, ``encoder_ticks``,
        ``wheel_radius_error``).
    include_systematic : bool
        Add ``wheel_radius_error**2`` to ``rel_var``: the declared systematic wheel-radius
        error bound taken as a one-sigma white error per step (module docstring).

    Returns
    -------
    rel_var : float
        Variance per squared metre of travel [-].
    base_var : float
        Quantisation variance ``(2 pi wheel_radius / encoder_ticks)**2 / 12`` plus
        ``VARIANCE_FLOOR`` [m^2].
    """
    tick = 2.0 * math.pi * robot.wheel_radius / robot.encoder_ticks
    rel_var = robot.odometry_noise**2
    if include_systematic:
        rel_var += robot.wheel_radius_error**2
    return rel_var, tick * tick / 12.0 + VARIANCE_FLOOR


def wheel_variances(d_left, d_right, robot: RobotSpec, include_systematic: bool = False):
    """Variance of each wheel's travel error over one step (see :func:`variance_terms`).

    Parameters
    ----------
    d_left, d_right : float or numpy.ndarray
        Measured wheel travel over the step [m].
    robot : RobotSpec
        The declared robot.
    include_systematic : bool
        See :func:`variance_terms`.

    Returns
    -------
    var_left, var_right : float or numpy.ndarray
        Travel variances [m^2], same shape as the inputs.
    """
    rel_var, base_var = variance_terms(robot, include_systematic)
    return rel_var * d_left * d_left + base_var, rel_var * d_right * d_right + base_var


def process_cov(state, d_left: float, d_right: float, robot: RobotSpec,
                include_systematic: bool = False) -> np.ndarray:
    """Process noise ``Q = G diag(var_left, var_right) G^T`` of one step.

    Parameters
    ----------
    state : array_like, shape (3,)
        Pose the step starts from (x [m], y [m], theta [rad]).
    d_left, d_right : float
        Measured wheel travel over the step [m].
    robot : RobotSpec
        The declared robot.
    include_systematic : bool
        See :func:`wheel_variances`.

    Returns
    -------
    numpy.ndarray, shape (3, 3)
        Covariance added to the pose over the step [m^2, m rad, rad^2].
    """
    _, G = jacobians(state, d_left, d_right, robot.wheel_base)
    var_left, var_right = wheel_variances(d_left, d_right, robot, include_systematic)
    return (G * np.array([var_left, var_right])) @ G.T
