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
    return np.array(_arc((float(pose[0]), float(pose[1]), float(pose[2])), d_left, d_right, wheel_base))


def _arc(pose: tuple[float, float, float], d_left: float, d_right: float,
         wheel_base: float) -> tuple[float, float, float]:
    x, y, th = pose
    ds = 0.5 * (d_left + d_right)
    dth = (d_right - d_left) / wheel_base
    if abs(dth) < 1e-9:
        # Straight (to first order): the chord equals the arc.
        c, s = math.cos(th + 0.5 * dth), math.sin(th + 0.5 * dth)
        return x + ds * c, y + ds * s, th + dth
    radius = ds / dth
    return (x + radius * (math.sin(th + dth) - math.sin(th)),
            y - radius * (math.cos(th + dth) - math.cos(th)), th + dth)


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
    slip_std : float
        Random slip of the simulated floor, standard deviation per metre of wheel travel [m/m]
        (the physics' contacts do not slip randomly, so it is added to the readings); 0 = none.
    rng : numpy.random.Generator, optional
        Source of the slip noise (required when ``slip_std > 0``); drawn left then right wheel
        at each update, in blocks (the numbers are those of one scalar draw after another).
    """

    _BLOCK = 1024   # slip normals drawn per refill: a scalar draw per wheel costs ~1 us

    def __init__(self, spec: RobotSpec, angles: np.ndarray, pose: np.ndarray, slip_std: float = 0.0,
                 rng: np.random.Generator | None = None) -> None:
        if slip_std > 0.0 and rng is None:
            raise ValueError("WheelOdometry: slip_std > 0 needs a random generator")
        self.spec = spec
        self.slip_std = float(slip_std)
        self._rng = rng
        self._normals: list[float] = []
        self._next = 0
        self._metres_per_tick = 2.0 * math.pi * spec.wheel_radius / spec.encoder_ticks
        self.reset(angles, pose)

    def reset(self, angles: np.ndarray, pose: np.ndarray) -> None:
        """Restart from wheel ``angles`` (2,) [rad] and ``pose`` (3,)."""
        n = self.spec.encoder_ticks
        self._ticks = (encoder_ticks(float(angles[0]), n), encoder_ticks(float(angles[1]), n))
        x, y, th = np.array(pose, dtype=float).reshape(3)
        self._pose = (float(x), float(y), float(th))

    def _normal(self) -> float:
        if self._next == len(self._normals):
            self._normals = self._rng.standard_normal(self._BLOCK).tolist()
            self._next = 0
        self._next += 1
        return self._normals[self._next - 1]

    def update(self, angles) -> WheelTravel:
        """Read the encoders at wheel ``angles`` (left, right) [rad]; return the travel since the last read.

        The travel includes the floor's random slip; it also advances the dead-reckoned
        :attr:`pose`.
        """
        n, two_pi = self.spec.encoder_ticks, 2.0 * math.pi  # as encoder_ticks(), to the last bit
        ticks = (math.floor(float(angles[0]) * n / two_pi), math.floor(float(angles[1]) * n / two_pi))
        dl = (ticks[0] - self._ticks[0]) * self._metres_per_tick
        dr = (ticks[1] - self._ticks[1]) * self._metres_per_tick
        self._ticks = ticks
        if self.slip_std > 0.0:
            dl += self.slip_std * abs(dl) * self._normal()
            dr += self.slip_std * abs(dr) * self._normal()
        self._pose = _arc(self._pose, dl, dr, self.spec.wheel_base)
        return WheelTravel(dl, dr)

    @property
    def pose(self) -> np.ndarray:
        """Dead-reckoned pose (x [m], y [m], theta [rad], theta unwrapped), shape (3,)."""
        return np.array(self._pose)
