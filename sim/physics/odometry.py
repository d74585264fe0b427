"""Wheel odometry: quantised encoders, the nominal wheel radius, dead reckoning.

The encoders see the true joint angles, quantised to ``encoder_ticks`` per revolution; the
odometry converts ticks to travel with the *declared* (nominal) wheel radius, so the physical
difference between the simulated wheels (``robot_actual.wheel_radius_error``) becomes the
classic systematic odometry error. Pure Python floats: a control step handles two numbers and
numpy's per-call overhead would dominate.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from scenarios.schema import RobotSpec


class WheelTravel(NamedTuple):
    """Distance each wheel rolled in one control step, from the encoders [m]."""

    d_left: float
    d_right: float


def encoder_ticks(angle: float, ticks_per_rev: int) -> int:
    """Return the encoder count at wheel ``angle`` [rad] (floor: the count changes at each tick edge)."""
    return math.floor(angle * ticks_per_rev / (2.0 * math.pi))


def integrate_arc(pose: np.ndarray, d_left: float, d_right: float, wheel_base: float) -> np.ndarray:
    """Dead-reckon one step of a differential drive along a circular arc.

    Parameters
    ----------
    pose : (3,) array_like
        Pose before the step (x [m], y [m], theta [rad]).
    d_left, d_right : float
        Wheel travel in the step [m].
    wheel_base : float
        Distance between the wheels [m].

    Returns
    -------
    ndarray, shape (3,)
        Pose after the step; theta is not wrapped (it accumulates).
    """
    x, y, th = float(pose[0]), float(pose[1]), float(pose[2])
    ds = 0.5 * (d_left + d_right)
    dth = (d_right - d_left) / wheel_base
    if abs(dth) < 1e-9:
        # Straight (to first order): the chord equals the arc.
        c, s = math.cos(th + 0.5 * dth), math.sin(th + 0.5 * dth)
        return np.array([x + ds * c, y + ds * s, th + dth])
    radius = ds / dth
    return np.array([x + radius * (math.sin(th + dth) - math.sin(th)),
                     y - radius * (math.cos(th + dth) - math.cos(th)), th + dth])


class WheelOdometry:
    """Encoder odometry of a differential drive with the nominal (declared) geometry.

    Parameters
    ----------
    spec : RobotSpec
        The declared robot (``scenario.robot``): nominal wheel radius, wheel base, ticks.
    angles : (2,) array_like
        Wheel angles (left, right) [rad] at the start.
    pose : (3,) array_like
        Dead-reckoning start pose (x [m], y [m], theta [rad]).
    """

    def __init__(self, spec: RobotSpec, angles: np.ndarray, pose: np.ndarray) -> None:
        self.spec = spec
        self._metres_per_tick = 2.0 * math.pi * spec.wheel_radius / spec.encoder_ticks
        self.reset(angles, pose)

    def reset(self, angles: np.ndarray, pose: np.ndarray) -> None:
        """Restart from wheel ``angles`` (2,) [rad] and ``pose`` (3,)."""
        n = self.spec.encoder_ticks
        self._ticks = (encoder_ticks(float(angles[0]), n), encoder_ticks(float(angles[1]), n))
        self._pose = np.array(pose, dtype=float).reshape(3)

    def update(self, angles: np.ndarray) -> WheelTravel:
        """Read the encoders at wheel ``angles`` (left, right) [rad]; return the travel since the last read.

        Also advances the dead-reckoned :attr:`pose`.
        """
        n = self.spec.encoder_ticks
        ticks = (encoder_ticks(float(angles[0]), n), encoder_ticks(float(angles[1]), n))
        travel = WheelTravel((ticks[0] - self._ticks[0]) * self._metres_per_tick,
                             (ticks[1] - self._ticks[1]) * self._metres_per_tick)
        self._ticks = ticks
        self._pose = integrate_arc(self._pose, travel.d_left, travel.d_right, self.spec.wheel_base)
        return travel

    @property
    def pose(self) -> np.ndarray:
        """Dead-reckoned pose (x [m], y [m], theta [rad], theta unwrapped), shape (3,)."""
        return self._pose.copy()
