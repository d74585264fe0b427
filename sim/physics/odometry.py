"""Wheel odometry: quantised encoders, the nominal wheel radius, dead reckoning.

The encoders see the true joint angles, quantised to ``encoder_ticks`` per revolution; the
odometry converts ticks to travel with the *declared* (nominal) wheel radius, so the physical
difference between the simulated wheels (``robot_actual.wheel_radius_error``) becomes the
classic systematic odometry error. The step is compiled (:func:`odometry_step`): a control
loop calls it thousands of times per run, and numpy's per-call overhead would dominate.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from estimators.motion import arc_step
from jit import compiled
from scenarios.schema import RobotSpec


class WheelTravel(NamedTuple):
    """Distance each wheel rolled in one control step, from the encoders [m]."""

    d_left: float
    d_right: float


def encoder_ticks(angle: float, ticks_per_rev: int, phase: float = 0.0) -> int:
    """Return the encoder count at wheel ``angle`` [rad] (floor: the count changes at each tick edge).

    ``phase`` [ticks, in ``[0, 1)``] is where the encoder disc's edges sit on the wheel: the count
    is ``floor(angle ticks_per_rev / (2 pi) + phase)``.
    """
    return math.floor(angle * ticks_per_rev / (2.0 * math.pi) + phase)


def centred_residual(angle: float, spec: RobotSpec, phase: float = 0.0) -> float:
    """Part of the wheel's rotation at ``angle`` [rad] below its last tick edge, as travel, centred [m].

    ``r angle + tick * phase - tick * count - tick / 2`` (nominal radius ``r``,
    ``tick = 2 pi r / encoder_ticks``, the encoder's ``phase`` as in :func:`encoder_ticks`): in
    ``[-tick/2, tick/2)``, the quantisation residual the filter's encoder state
    (:mod:`estimators.motion_quantised`) holds.
    """
    tick = 2.0 * math.pi * spec.wheel_radius / spec.encoder_ticks
    return (spec.wheel_radius * angle + tick * phase - tick * encoder_ticks(angle, spec.encoder_ticks, phase)
            - 0.5 * tick)


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
    return np.array(arc_step((float(pose[0]), float(pose[1]), float(pose[2])), float(d_left), float(d_right),
                             float(wheel_base)))


# WheelOdometry.state (float64, shape (9,)): encoder counts, dead-reckoned pose, next slip draw,
# the running sum of (d_left^2 + d_right^2) / 4 over the reads [m^2] (SLIP_WEIGHT: the wheels'
# mean travel has slip variance slip_std^2 times its increase, whatever the reads' spacing), and
# each wheel's running sum of |d| over the reads [m] (PATH_LEFT, PATH_RIGHT: a bounded slip's sum
# between two reads is at most sqrt(3) slip_std times its increase).
TICKS_LEFT, TICKS_RIGHT, POSE_X, POSE_Y, POSE_THETA, NEXT_NORMAL, SLIP_WEIGHT, PATH_LEFT, PATH_RIGHT = range(9)
# WheelOdometry.params (float64, shape (6,)); PHASE_*: each encoder's phase [ticks] (encoder_ticks).
METRES_PER_TICK, TICKS_PER_REV, SLIP_STD, WHEEL_BASE, PHASE_LEFT, PHASE_RIGHT = range(6)


@compiled.njit(cache=True)
def odometry_step(state, params, normals, angle_left, angle_right):
    """Read the encoders at the wheel angles [rad]; advance ``state`` in place.

    Compiled so that a control loop can call it from compiled code (``sim.episode.control_tick``).

    Parameters
    ----------
    state : ndarray, shape (9,)
        :attr:`WheelOdometry.state` (indices ``TICKS_LEFT`` ... ``PATH_RIGHT``); updated.
    params : ndarray, shape (6,)
        :attr:`WheelOdometry.params` (indices ``METRES_PER_TICK`` ... ``PHASE_RIGHT``).
    normals : ndarray, shape (B,)
        Unit-variance draws for the slip (normal, or uniform on ``[-sqrt 3, sqrt 3]`` for a bounded
        slip), consumed from ``state[NEXT_NORMAL]``, left first.
    angle_left, angle_right : float
        Wheel joint angles now [rad].

    Returns
    -------
    d_left, d_right : float
        Wheel travel since the last read, with the floor's slip [m].
    used_up : bool
        The slip normals are used up: the caller draws the next block before the next step.
    """
    two_pi = 2.0 * math.pi
    n = params[TICKS_PER_REV]
    ticks_left = math.floor(angle_left * n / two_pi + params[PHASE_LEFT])   # as encoder_ticks(), to the last bit
    ticks_right = math.floor(angle_right * n / two_pi + params[PHASE_RIGHT])
    d_left = (ticks_left - state[TICKS_LEFT]) * params[METRES_PER_TICK]
    d_right = (ticks_right - state[TICKS_RIGHT]) * params[METRES_PER_TICK]
    state[TICKS_LEFT], state[TICKS_RIGHT] = ticks_left, ticks_right
    state[SLIP_WEIGHT] += 0.25 * (d_left * d_left + d_right * d_right)
    state[PATH_LEFT] += abs(d_left)
    state[PATH_RIGHT] += abs(d_right)
    slip = params[SLIP_STD]
    if slip > 0.0:
        k = int(state[NEXT_NORMAL])
        d_left += slip * abs(d_left) * normals[k]
        d_right += slip * abs(d_right) * normals[k + 1]
        state[NEXT_NORMAL] = k + 2
    x, y, th = arc_step((state[POSE_X], state[POSE_Y], state[POSE_THETA]), d_left, d_right, params[WHEEL_BASE])
    state[POSE_X], state[POSE_Y], state[POSE_THETA] = x, y, th
    return d_left, d_right, slip > 0.0 and state[NEXT_NORMAL] + 2.0 > normals.size


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
    bounded : bool
        Draw the slip uniform in ``+-sqrt(3) slip_std |d|`` per read (same variance) instead of
        normal: the floor of a bounded-noise world (``noise = "uniform"``), where every random
        error the simulation draws has a bound and the realised fault area must hold the truth
        at every fix (a normal slip 4 sigma out broke it on random-23-037).
    phase : (2,) array_like
        Where each encoder's tick edges sit on its wheel (left, right) [ticks, in ``[0, 1)``]
        (:func:`encoder_ticks`). An episode draws them per run: a robot's wheels stop wherever
        they stopped, so a run starts at a sub-tick phase that is random and that the encoder
        cannot report.
    """

    _BLOCK = 1024   # slip normals drawn per refill (even: a block holds whole left/right pairs)

    def __init__(self, spec: RobotSpec, angles: np.ndarray, pose: np.ndarray, slip_std: float = 0.0,
                 rng: np.random.Generator | None = None, bounded: bool = False, phase=(0.0, 0.0)) -> None:
        if slip_std > 0.0 and rng is None:
            raise ValueError(f"WheelOdometry: slip_std = {slip_std} > 0 needs a random generator, got rng=None")
        self.spec = spec
        self.slip_std = float(slip_std)
        self._rng = rng
        self.bounded = bool(bounded)
        phase_l, phase_r = (float(p) for p in phase)
        if not (0.0 <= phase_l < 1.0 and 0.0 <= phase_r < 1.0):
            raise ValueError(f"WheelOdometry: phase = {list(phase)}, each in [0, 1) ticks")
        self.params = np.array([2.0 * math.pi * spec.wheel_radius / spec.encoder_ticks,
                                float(spec.encoder_ticks), self.slip_std, spec.wheel_base, phase_l, phase_r])
        self.state = np.zeros(9)
        self.normals = np.zeros(2)
        if self.slip_std > 0.0:
            self.refill()
        self.reset(angles, pose)

    def reset(self, angles: np.ndarray, pose: np.ndarray) -> None:
        """Restart from wheel ``angles`` (2,) [rad] and ``pose`` (3,) (the slip stream goes on)."""
        n = self.spec.encoder_ticks
        self.state[TICKS_LEFT] = encoder_ticks(float(angles[0]), n, self.params[PHASE_LEFT])
        self.state[TICKS_RIGHT] = encoder_ticks(float(angles[1]), n, self.params[PHASE_RIGHT])
        self.state[POSE_X:POSE_THETA + 1] = np.array(pose, dtype=float).reshape(3)

    def refill(self) -> None:
        """Draw the next block of slip draws (call when :func:`odometry_step` says so)."""
        if self.bounded:
            self.normals = self._rng.uniform(-math.sqrt(3.0), math.sqrt(3.0), self._BLOCK)
        else:
            self.normals = self._rng.standard_normal(self._BLOCK)
        self.state[NEXT_NORMAL] = 0.0

    def update(self, angles) -> WheelTravel:
        """Read the encoders at wheel ``angles`` (left, right) [rad]; return the travel since the last read.

        The travel includes the floor's random slip; it also advances the dead-reckoned
        :attr:`pose`.
        """
        d_left, d_right, used_up = odometry_step(self.state, self.params, self.normals,
                                                 float(angles[0]), float(angles[1]))
        if used_up:
            self.refill()
        return WheelTravel(d_left, d_right)

    @property
    def pose(self) -> np.ndarray:
        """Dead-reckoned pose (x [m], y [m], theta [rad], theta unwrapped), shape (3,)."""
        return self.state[POSE_X:POSE_THETA + 1].copy()

    @property
    def slip_weight(self) -> float:
        """Running sum over the reads of ``(d_left^2 + d_right^2) / 4`` [m^2] (wheel travel per read).

        The slip of the wheels' mean travel between two reads of it has variance
        ``slip_std^2`` times its increase: unequal reads (a fix's measurements fall between
        control ticks) weigh more than ``d^2 / (2 n)`` for ``n`` equal ones.
        """
        return float(self.state[SLIP_WEIGHT])

    @property
    def wheel_paths(self) -> tuple[float, float]:
        """Running sums over the reads of each wheel's ``|d|`` (left, right) [m], slip excluded.

        A bounded slip (``bounded``) adds at most ``sqrt(3) slip_std`` times a wheel's increase
        of it to the wheel's reported travel between two reads.
        """
        return float(self.state[PATH_LEFT]), float(self.state[PATH_RIGHT])


# numba keys a cache on its own file only: flush the kernels above when a file they inline changed
compiled.keep_fresh(__name__)
