"""One control step of an episode as one compiled call: odometry, EKF predict, log row, command.

At 60 Hz the control step runs ~2,500 times per minute-long episode, and thousands of episodes
make a sweep. Done as Python calls (encoders, dead reckoning, filter predict, logging, pure
pursuit) it cost ~30 us per step against ~225 us of physics; chained here it is one dispatch of
the same compiled kernels the classes use (:func:`sim.physics.odometry.odometry_step`,
:func:`estimators.predict.predict_step` with the motion kernels of :mod:`estimators.motion` and
:mod:`estimators.motion_quantised`, :func:`sim.episode.follower.command_step`), so the two paths cannot
drift apart. The objects stay the owners of their state: the kernel works on their arrays.

numba caches ``_tick`` compiled with those kernels inlined; :func:`jit.compiled.njit` keys
that cache on their files too, so an edit of any of them is compiled on the next run.
"""

from __future__ import annotations

import numpy as np

from estimators.predict import predict_step
from jit import compiled
from sim.episode.follower import command_step
from sim.physics.odometry import odometry_step

# Columns of the episode log: time [s], true pose (x, y, theta), estimated pose, the estimate's
# pose covariance (3x3, row-major), arc length of the estimate along the path [m].
LOG_T = 0
LOG_TRUE = slice(1, 4)
LOG_EST = slice(4, 7)
LOG_COV = slice(7, 16)
LOG_S = 16
LOG_COLUMNS = 17
_TRUE0, _EST0, _COV0 = LOG_TRUE.start, LOG_EST.start, LOG_COV.start  # numba indexes with ints


@compiled.njit(cache=True)
def _tick(odo_state, odo_params, normals, angle_left, angle_right, kf_x, kf_P, ekf_params, phase,
          table, limits, follower_state, log, n, t, true_x, true_y, true_theta, s_prev, steer, dt):
    d_left, d_right, used_up = odometry_step(odo_state, odo_params, normals, angle_left, angle_right)
    predict_step(kf_x, kf_P, d_left, d_right, ekf_params, phase)
    row = log[n]
    row[LOG_T] = t
    row[_TRUE0], row[_TRUE0 + 1], row[_TRUE0 + 2] = true_x, true_y, true_theta
    for i in range(3):
        row[_EST0 + i] = kf_x[i]
        for j in range(3):
            row[_COV0 + 3 * i + j] = kf_P[i, j]
    v, omega, done, s = 0.0, 0.0, False, s_prev
    if steer:
        v, omega, done, s = command_step(table, limits, follower_state, kf_x[0], kf_x[1], kf_x[2], dt)
    row[LOG_S] = s
    return v, omega, done, s, used_up


class ControlTick:
    """The compiled control step over an episode's odometry, localiser, follower and log.

    Parameters
    ----------
    odometry : sim.physics.odometry.WheelOdometry
    localizer : estimators.ekf.Localizer
    follower : sim.episode.follower.PurePursuit
    log : ndarray, shape (N, LOG_COLUMNS)
        Row ``n`` is written by the ``n``-th call.
    dt : float
        Control period [s].
    """

    def __init__(self, odometry, localizer, follower, log: np.ndarray, dt: float) -> None:
        self.odo, self.loc, self.follower, self.log, self.dt = odometry, localizer, follower, log, float(dt)
        # The arrays the kernel works on, bound once: every object updates its own in place (the
        # odometry's noise block excepted: its refills replace it, read at each call). Each
        # attribute lookup in __call__ runs between physics steps, from cold caches, 2,500 times
        # an episode.
        x, P = localizer.state_arrays()
        self._arrays = (odometry.state, odometry.params)
        self._filter = (x, P, localizer.predict_params, localizer.phase, follower.table, follower.limits,
                        follower.state, log)
        self._rows = len(log)

    def __call__(self, angles: tuple[float, float], true_pose: tuple[float, float, float], t: float, n: int,
                 s_prev: float, steer: bool, turn_slip: float | None = None,
                 steps: int | None = None) -> tuple[float, float, bool, float]:
        """Read the encoders at ``angles`` [rad], predict, log row ``n``, and command if ``steer``.

        ``turn_slip`` and ``steps`` are the read's (:meth:`estimators.ekf.Localizer.predict`), by
        default the declared turn slip and an unknown span. Returns (v [m/s], omega [rad/s],
        done, s [m]); without ``steer`` the robot is held (0, 0, False) and ``s_prev`` is logged.
        """
        if not 0 <= n < self._rows:  # the compiled step does not check bounds
            raise IndexError(f"ControlTick: log row {n} outside 0..{self._rows - 1}")
        self.loc.set_turn_slip(turn_slip)
        self.loc.set_read_steps(steps)
        v, omega, done, s, used_up = _tick(*self._arrays, self.odo.normals, angles[0], angles[1], *self._filter,
                                           n, t, *true_pose, s_prev, steer, self.dt)
        if used_up:
            self.odo.refill()
        return v, omega, done, s


# numba keys a cache on its own file only: flush the kernels above when a file they inline changed
compiled.keep_fresh(__name__)
