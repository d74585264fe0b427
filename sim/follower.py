"""Pure-pursuit path follower for a differential-drive robot, driven by the *estimated* pose.

The follower never sees the true pose: what the robot believes is what it steers by, so
localisation errors become tracking errors exactly as on a real AGV.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field

import numpy as np


@dataclass
class FollowerCommand:
    """One control output: forward speed ``v`` [m/s], yaw rate ``omega`` [rad/s], ``done``."""

    v: float
    omega: float
    done: bool
    s: float
    """Arc length of the path point nearest to the estimated pose [m]."""


@dataclass
class PurePursuit:
    """Pure pursuit with a speed profile, turn slow-down, acceleration limit and goal stop.

    Parameters
    ----------
    path : (N, 2) float
        Reference path [m], densely sampled (spacing well below the lookahead).
    speed : (N,) float
        Reference speed at each path point [m/s].
    max_speed, max_yaw_rate : float
        Limits [m/s], [rad/s].
    max_accel, max_yaw_accel : float
        Limits on the change of forward speed [m/s^2] and of yaw rate [rad/s^2]: a stepped
        wheel command slips on the floor (about 1 cm at 0.5 m/s in the physics), and slip is
        odometry error the filter does not model.
    lookahead_min, lookahead_gain : float
        Lookahead distance = max(lookahead_min, lookahead_gain * v) [m], [s].
    goal_tolerance : float
        The follower is done when the estimate is this close to the last path point [m].
    """

    path: np.ndarray
    speed: np.ndarray
    max_speed: float
    max_yaw_rate: float
    max_accel: float = 0.5
    max_yaw_accel: float = 2.0
    lookahead_min: float = 0.3
    lookahead_gain: float = 0.8
    goal_tolerance: float = 0.05
    rotate_in_place_above: float = math.radians(60.0)
    window: int = 40
    """Path points searched ahead of the last nearest one (the path is sampled every ~0.1 m)."""
    _index: int = field(default=0, init=False)
    _v: float = field(default=0.0, init=False)
    _w: float = field(default=0.0, init=False)
    _s: np.ndarray = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        self.path = np.asarray(self.path, dtype=float)
        seg = np.hypot(*np.diff(self.path, axis=0).T)
        self._s = np.concatenate([[0.0], np.cumsum(seg)])
        # The control loop runs this at tens of Hz for thousands of runs: plain floats and
        # lists beat numpy's per-call overhead on these few-element operations.
        self._xs = self.path[:, 0].tolist()
        self._ys = self.path[:, 1].tolist()
        self._sl = self._s.tolist()
        self._speed = np.asarray(self.speed, dtype=float).tolist()

    def reset(self) -> None:
        self._index = 0
        self._v = 0.0
        self._w = 0.0

    @property
    def length(self) -> float:
        return float(self._s[-1])

    def _nearest_ahead(self, x: float, y: float) -> int:
        # Search a short window ahead of the last index so that a path passing near itself (a
        # U-turn around an obstacle) cannot make the follower jump ahead or back.
        xs, ys = self._xs, self._ys
        lo = self._index
        best, best_d2 = lo, math.inf
        for j in range(lo, min(len(xs), lo + self.window)):
            d2 = (xs[j] - x) ** 2 + (ys[j] - y) ** 2
            if d2 < best_d2:
                best, best_d2 = j, d2
        self._index = best
        return best

    def command(self, pose: np.ndarray, dt: float) -> FollowerCommand:
        """Command for estimated ``pose`` (x, y, theta) over the next ``dt`` seconds."""
        px, py, th = float(pose[0]), float(pose[1]), float(pose[2])
        i = self._nearest_ahead(px, py)
        s_i = self._sl[i]
        dist_goal = math.hypot(self._xs[-1] - px, self._ys[-1] - py)
        remaining = self._sl[-1] - s_i
        if dist_goal < self.goal_tolerance and remaining < 2 * self.lookahead_min:
            self._v = self._w = 0.0
            return FollowerCommand(0.0, 0.0, True, s_i)

        look = max(self.lookahead_min, self.lookahead_gain * self._v)
        j = min(bisect.bisect_left(self._sl, s_i + look), len(self._sl) - 1)
        dx, dy = self._xs[j] - px, self._ys[j] - py
        c, s = math.cos(th), math.sin(th)
        lx, ly = c * dx + s * dy, -s * dx + c * dy  # target in the robot frame
        alpha = math.atan2(ly, lx)
        ld2 = lx * lx + ly * ly

        if abs(alpha) > self.rotate_in_place_above:
            # turn on the spot, braking first if still rolling; the yaw rate is the one from
            # which max_yaw_accel stops the turn exactly at alpha = 0
            w_ref = 0.0 if self._v > 0.0 else math.copysign(
                min(self.max_yaw_rate, math.sqrt(1.6 * self.max_yaw_accel * abs(alpha))), alpha)
            v, omega = self._limit(0.0, w_ref, dt)
            return FollowerCommand(v, omega, False, s_i)

        kappa = 2.0 * ly / ld2 if ld2 > 1e-12 else 0.0
        v_ref = min(self._speed[i], self.max_speed)
        if abs(kappa) > 1e-9:
            v_ref = min(v_ref, self.max_yaw_rate / abs(kappa))
        # stop at the goal: the speed from which max_accel brakes to zero within the distance left
        # brake with 80 % of the deceleration limit so the limit itself never truncates the profile
        v_ref = min(v_ref, math.sqrt(1.6 * self.max_accel * max(dist_goal - self.goal_tolerance, 0.0)))
        v_ref = max(v_ref, 0.02)  # creep instead of stalling short of the goal
        dv = self.max_accel * dt
        v = min(max(v_ref, self._v - dv), self._v + dv)
        v, omega = self._limit(v, v * kappa, dt)
        return FollowerCommand(v, omega, False, s_i)

    def _limit(self, v_ref: float, w_ref: float, dt: float) -> tuple[float, float]:
        """Apply the speed and acceleration limits to a command; remember it."""
        dv, dw = self.max_accel * dt, self.max_yaw_accel * dt
        self._v = min(max(v_ref, self._v - dv), self._v + dv)
        w = min(max(w_ref, -self.max_yaw_rate), self.max_yaw_rate)
        self._w = min(max(w, self._w - dw), self._w + dw)
        return self._v, self._w


def wheel_speeds(v: float, omega: float, wheel_radius: float, wheel_base: float) -> tuple[float, float]:
    """Wheel angular speeds (left, right) [rad/s] for body speeds ``v`` [m/s], ``omega`` [rad/s]."""
    half = 0.5 * wheel_base * omega
    return (v - half) / wheel_radius, (v + half) / wheel_radius
