"""Pure-pursuit path follower for a differential-drive robot, driven by the *estimated* pose.

The follower never sees the true pose: what the robot believes is what it steers by, so
localisation errors become tracking errors exactly as on a real AGV.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from jit import compiled

# the plan's promise bounds this follower's tracking error from its design (planner.schedule.promise)
from planner.schedule import promise as design


class FollowerCommand(NamedTuple):
    """One control output: forward speed ``v`` [m/s], yaw rate ``omega`` [rad/s], ``done``.

    A named tuple: one is made per control step, and a dataclass costs twice as much.
    """

    v: float
    omega: float
    done: bool
    s: float
    """Arc length of the path point nearest to the estimated pose [m]."""


# PurePursuit.limits (float64, shape (9,)) and PurePursuit.state (float64, shape (3,)).
(MAX_SPEED, MAX_YAW_RATE, MAX_ACCEL, MAX_YAW_ACCEL, LOOKAHEAD_MIN, LOOKAHEAD_GAIN, GOAL_TOLERANCE,
 ROTATE_ABOVE, WINDOW) = range(9)
INDEX, SPEED, YAW_RATE = range(3)


@dataclass
class PurePursuit:
    """Pure pursuit with a speed profile, turn slow-down, acceleration limit and goal stop.

    The parameters are read once, when the follower is built (into :attr:`table` and
    :attr:`limits` for the compiled step): build a new follower to change them.

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
    max_accel: float = design.FOLLOWER_MAX_ACCEL
    max_yaw_accel: float = 2.0
    lookahead_min: float = design.LOOKAHEAD_MIN
    lookahead_gain: float = design.LOOKAHEAD_GAIN
    goal_tolerance: float = 0.05
    rotate_in_place_above: float = design.ROTATE_ABOVE
    window: int = 40
    """Path points searched ahead of the last nearest one (the path is sampled every ~0.1 m)."""
    _s: np.ndarray = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        self.path = np.asarray(self.path, dtype=float)
        seg = np.hypot(*np.diff(self.path, axis=0).T)
        self._s = np.concatenate([[0.0], np.cumsum(seg)])
        # rows x [m], y [m], arc length [m], reference speed [m/s]: one array for the kernel
        self.table = np.ascontiguousarray(np.vstack([self.path[:, 0], self.path[:, 1], self._s,
                                                     np.asarray(self.speed, dtype=float)]))
        self.limits = np.array([self.max_speed, self.max_yaw_rate, self.max_accel, self.max_yaw_accel,
                                 self.lookahead_min, self.lookahead_gain, self.goal_tolerance,
                                 self.rotate_in_place_above, float(self.window)])
        # nearest path index, last v [m/s], last omega [rad/s]: the kernel's memory between calls
        self.state = np.zeros(3)

    def reset(self) -> None:
        self.state[:] = 0.0

    @property
    def length(self) -> float:
        return float(self._s[-1])

    def command(self, pose: np.ndarray, dt: float) -> FollowerCommand:
        """Command for estimated ``pose`` (x, y, theta) over the next ``dt`` seconds."""
        # The control loop runs this at tens of Hz for thousands of runs: one compiled call.
        v, omega, done, s = command_step(self.table, self.limits, self.state,
                                         float(pose[0]), float(pose[1]), float(pose[2]), float(dt))
        return FollowerCommand(v, omega, done, s)


@compiled.njit(cache=True)
def _limit(state, limits, v_ref, w_ref, dt):
    """Apply the speed and acceleration limits to a command; remember it in ``state``."""
    max_yaw_rate, max_accel, max_yaw_accel = limits[MAX_YAW_RATE], limits[MAX_ACCEL], limits[MAX_YAW_ACCEL]
    dv, dw = max_accel * dt, max_yaw_accel * dt
    v = min(max(v_ref, state[SPEED] - dv), state[SPEED] + dv)
    w = min(max(w_ref, -max_yaw_rate), max_yaw_rate)
    w = min(max(w, state[YAW_RATE] - dw), state[YAW_RATE] + dw)
    state[SPEED], state[YAW_RATE] = v, w
    return v, w


@compiled.njit(cache=True)
def _project(xs, ys, sl, i, px, py):
    """Arc length of (px, py) projected on the segment after vertex i, or before it [m]."""
    n = xs.size
    if i + 1 < n:
        tx, ty = xs[i + 1] - xs[i], ys[i + 1] - ys[i]
        L2 = tx * tx + ty * ty
        if L2 > 0.0:
            u = ((px - xs[i]) * tx + (py - ys[i]) * ty) / L2
            if u > 0.0:
                return sl[i] + min(u, 1.0) * (sl[i + 1] - sl[i])
    if i > 0:
        tx, ty = xs[i] - xs[i - 1], ys[i] - ys[i - 1]
        L2 = tx * tx + ty * ty
        if L2 > 0.0:
            u = ((px - xs[i]) * tx + (py - ys[i]) * ty) / L2
            if u < 0.0:
                return sl[i] + max(u, -1.0) * (sl[i] - sl[i - 1])
    return sl[i]


@compiled.njit(cache=True)
def command_step(table, limits, state, px, py, th, dt):
    """Run one pure-pursuit step (compiled, so that ``sim.episode.control_tick`` can chain it).

    Parameters
    ----------
    table : ndarray, shape (4, N)
        :attr:`PurePursuit.table`: path x, y [m], arc length [m], reference speed [m/s].
    limits : ndarray, shape (9,)
        :attr:`PurePursuit.limits` (indices ``MAX_SPEED`` ... ``WINDOW``).
    state : ndarray, shape (3,)
        :attr:`PurePursuit.state`: nearest path index, last v [m/s], last omega [rad/s]; updated.
    px, py, th : float
        Estimated pose [m, m, rad].
    dt : float
        Control period [s].

    Returns
    -------
    v, omega, done, s : float, float, bool, float
        Forward speed [m/s], yaw rate [rad/s], goal reached, arc length of the estimate's
        projection on the path next to its nearest vertex [m] (continuous: the schedule's fixes
        start at arc lengths between vertices).
    """
    xs, ys, sl, speed = table[0], table[1], table[2], table[3]
    max_speed, max_yaw_rate = limits[MAX_SPEED], limits[MAX_YAW_RATE]
    max_accel, max_yaw_accel = limits[MAX_ACCEL], limits[MAX_YAW_ACCEL]
    look_min, look_gain = limits[LOOKAHEAD_MIN], limits[LOOKAHEAD_GAIN]
    goal_tol, rotate_above = limits[GOAL_TOLERANCE], limits[ROTATE_ABOVE]
    n = xs.size
    # Search a short window ahead of the last index so that a path passing near itself (a
    # U-turn around an obstacle) cannot make the follower jump ahead or back.
    lo = int(state[INDEX])
    i, best_d2 = lo, np.inf
    for j in range(lo, min(n, lo + int(limits[WINDOW]))):
        d2 = (xs[j] - px) ** 2 + (ys[j] - py) ** 2
        if d2 < best_d2:
            i, best_d2 = j, d2
    state[INDEX] = i
    s_near = sl[i]
    s_i = _project(xs, ys, sl, i, px, py)
    dist_goal = math.hypot(xs[n - 1] - px, ys[n - 1] - py)
    if dist_goal < goal_tol and sl[n - 1] - s_i < 2.0 * look_min:
        state[SPEED] = state[YAW_RATE] = 0.0
        return 0.0, 0.0, True, s_i

    look = max(look_min, look_gain * state[SPEED])
    j = min(np.searchsorted(sl, s_near + look), n - 1)
    dx, dy = xs[j] - px, ys[j] - py
    c, s = math.cos(th), math.sin(th)
    lx, ly = c * dx + s * dy, -s * dx + c * dy  # target in the robot frame
    alpha = math.atan2(ly, lx)
    ld2 = lx * lx + ly * ly

    if abs(alpha) > rotate_above:
        # turn on the spot, braking first if still rolling; the yaw rate is the one from
        # which max_yaw_accel stops the turn exactly at alpha = 0
        w_ref = 0.0 if state[SPEED] > 0.0 else math.copysign(
            min(max_yaw_rate, math.sqrt(1.6 * max_yaw_accel * abs(alpha))), alpha)
        v, omega = _limit(state, limits, 0.0, w_ref, dt)
        return v, omega, False, s_i

    kappa = 2.0 * ly / ld2 if ld2 > 1e-12 else 0.0
    v_ref = min(speed[i], max_speed)
    if abs(kappa) > 1e-9:
        v_ref = min(v_ref, max_yaw_rate / abs(kappa))
    # stop at the goal: the speed from which max_accel brakes to zero within the distance left;
    # brake with 80 % of the deceleration limit so the limit itself never truncates the profile
    v_ref = min(v_ref, math.sqrt(1.6 * max_accel * max(dist_goal - goal_tol, 0.0)))
    v_ref = max(v_ref, 0.02)  # creep instead of stalling short of the goal
    dv = max_accel * dt
    v = min(max(v_ref, state[SPEED] - dv), state[SPEED] + dv)
    v, omega = _limit(state, limits, v, v * kappa, dt)
    return v, omega, False, s_i


def wheel_speeds(v: float, omega: float, wheel_radius: float, wheel_base: float) -> tuple[float, float]:
    """Wheel angular speeds (left, right) [rad/s] for body speeds ``v`` [m/s], ``omega`` [rad/s]."""
    half = 0.5 * wheel_base * omega
    return (v - half) / wheel_radius, (v + half) / wheel_radius
