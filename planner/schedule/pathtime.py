"""Arc length, time and turning along a path, sampled for the measurement schedule.

:class:`Kinematics` maps time to arc length for vertex speeds with constant acceleration
between vertices; :func:`sample_track` samples a path uniformly in time (plus its vertices),
aligned with the sensor's fix rate, and records where a fix started at each sample completes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from scenarios.errors import PlanningError
from scenarios.limits import MAX_PATH_SAMPLES


@dataclass(frozen=True, eq=False)
class Track:
    """The path sampled at a fine spacing, with time, turning and fix stretches (n samples)."""

    s: np.ndarray          # (n,) arc length [m]
    xy: np.ndarray         # (n, 2) positions [m]
    t: np.ndarray          # (n,) time since departure [s]
    turn_in: np.ndarray    # (n,) absolute turning up to and including this sample [rad]
    turn_ex: np.ndarray    # (n,) absolute turning before this sample [rad]
    t_start: np.ndarray    # (n,) start time of a fix started here [s]
    c: np.ndarray          # (n,) arc length where a fix started here completes [m]
    c_idx: np.ndarray      # (n,) first sample at or after c
    xy_c: np.ndarray       # (n, 2) position at c [m]
    vertex_idx: np.ndarray  # (N,) sample index of each input point
    xy_m: np.ndarray       # (n, k, 2) position at each of the fix's k measurements [m]
    kin: Kinematics        # arc length against time


class Kinematics:
    """Arc length against time along a path, constant acceleration between vertices.

    A speed of 0 at a vertex (a stop) therefore takes finite time.

    Parameters
    ----------
    s_v : ndarray, shape (N,)
        Arc length of the vertices [m], non-decreasing.
    v : ndarray, shape (N,)
        Speed at the vertices [m/s], >= 0; two consecutive zeros only on a zero-length segment.
    """

    def __init__(self, s_v: np.ndarray, v: np.ndarray):
        self.s_v, self.v = s_v, v
        ds, vsum = np.diff(s_v), v[:-1] + v[1:]
        stuck = (vsum <= 0.0) & (ds > 0.0)
        if np.any(stuck):
            q = int(np.flatnonzero(stuck)[0])
            raise PlanningError(f"path speed is zero between s = {s_v[q]:.2f} m and s = {s_v[q + 1]:.2f} m")
        self.dur = np.where(ds > 0.0, 2.0 * ds / np.where(vsum > 0.0, vsum, 1.0), 0.0)
        self.t_v = np.concatenate([[0.0], np.cumsum(self.dur)])
        self.acc = np.where(self.dur > 0.0, np.diff(v) / np.where(self.dur > 0.0, self.dur, 1.0), 0.0)

    def t_at(self, s: np.ndarray) -> np.ndarray:
        """Time at which arc length ``s`` [m] is reached (clipped to the path) [s]."""
        s = np.asarray(s, dtype=float)
        if len(self.dur) == 0:
            return np.zeros(s.shape)
        i = np.clip(np.searchsorted(self.s_v, s, side="right") - 1, 0, len(self.dur) - 1)
        ds = np.clip(s - self.s_v[i], 0.0, np.diff(self.s_v)[i])
        v, a = self.v[i], self.acc[i]
        root = np.sqrt(np.maximum(v * v + 2.0 * a * ds, 0.0))
        # (root - v) / a written as 2 ds / (v + root): no cancellation when a is small
        tau = np.where(v + root > 0.0, 2.0 * ds / np.where(v + root > 0.0, v + root, 1.0), 0.0)
        return self.t_v[i] + np.minimum(tau, self.dur[i])

    def s_at(self, t: np.ndarray) -> np.ndarray:
        """Arc length reached at times ``t`` [s] (clipped to the path) [m]."""
        if len(self.dur) == 0:
            return np.zeros(np.shape(t))
        i = np.clip(np.searchsorted(self.t_v, t, side="right") - 1, 0, len(self.dur) - 1)
        tau = np.clip(t - self.t_v[i], 0.0, self.dur[i])
        return np.minimum(self.s_v[i] + self.v[i] * tau + 0.5 * self.acc[i] * tau * tau, self.s_v[i + 1])


def mean_speed(kin: Kinematics, t0: np.ndarray, duration: float) -> np.ndarray:
    """Mean speed over ``[t0, t0 + duration]`` (any shape) [m/s]; ``duration`` 0: the speed at ``t0``.

    A fix whose ranges take no time (``sensor.measurement_time = 0``) is the limit of ever
    shorter fixes, whose mean speed tends to the speed at their start.
    """
    t0 = np.asarray(t0, dtype=float)
    if duration > 0.0:
        return (kin.s_at(t0 + duration) - kin.s_at(t0)) / duration
    if len(kin.dur) == 0:
        return np.zeros(t0.shape)
    i = np.clip(np.searchsorted(kin.t_v, t0, side="right") - 1, 0, len(kin.dur) - 1)
    tau = np.clip(t0 - kin.t_v[i], 0.0, kin.dur[i])
    at_end = t0 >= kin.t_v[-1]  # the path is done: standing still
    return np.where(at_end, 0.0, kin.v[i] + kin.acc[i] * tau)


def positions_at(kin: Kinematics, s_in: np.ndarray, path: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Positions reached at times ``t`` (any shape) [s] along ``path`` (N, 2), shape ``(*t.shape, 2)`` [m]."""
    s = kin.s_at(np.asarray(t, dtype=float))
    return np.stack([np.interp(s, s_in, path[:, 0]), np.interp(s, s_in, path[:, 1])], axis=-1)


def sample_track(path: np.ndarray, speed: np.ndarray, spacing: float, fix_time: float, gap: float,
                 measurements: int = 1) -> Track:
    """Sample the path uniformly in time (plus its vertices), aligned with the fix rate.

    The time step divides the minimum gap between fix starts (at least 4 steps per gap), so a
    fix can start exactly when the rate allows; its spatial step is at most ``spacing``.

    Parameters
    ----------
    path : ndarray, shape (N, 2)
        Path vertices [m].
    speed : ndarray, shape (N,)
        Speed at the vertices [m/s] (see :class:`Kinematics`).
    spacing : float
        Largest distance between samples [m].
    fix_time : float
        Duration of one fix, ``k * measurement_time`` [s].
    gap : float
        Minimum time between fix starts [s].
    measurements : int
        Measurements per fix (k), taken ``fix_time / k`` apart, the last at the completion.

    Returns
    -------
    Track
        n samples; the first fix (index 0) is taken at standstill before departure
        (``t_start[0] = -fix_time``, completing at ``c[0] = 0``).
    """
    seg = np.diff(path, axis=0)
    seg_len = np.hypot(seg[:, 0], seg[:, 1])
    s_in = np.concatenate([[0.0], np.cumsum(seg_len)])
    moving = seg_len > 0.0
    heading = np.arctan2(seg[moving, 1], seg[moving, 0])
    turns = np.abs((np.diff(heading) + math.pi) % (2.0 * math.pi) - math.pi)
    # the turn between moving segments m and m+1 happens at the start point of segment m+1
    turn_at = np.zeros(len(path))
    turn_at[np.flatnonzero(moving)[1:]] = turns

    kin = Kinematics(s_in, speed)
    dt = gap / max(4, math.ceil(max(speed.max(), 1e-12) * gap / spacing))
    anchor = (gap - fix_time) % dt  # grid holds t = gap - fix_time: the first rate-allowed start
    t_end = kin.t_v[-1]
    samples = (t_end - anchor) / dt
    if not samples <= MAX_PATH_SAMPLES:  # checked before the grid is allocated (NaN refused too)
        raise PlanningError(f"robot.max_speed: the {s_in[-1]:.4g} m path at up to {speed.max():.3g} m/s takes "
                            f"{t_end:.3g} s, {samples:.3g} path samples, at most {MAX_PATH_SAMPLES:.0e}")
    t_grid = np.concatenate([[0.0], np.arange(anchor, t_end, dt), [t_end]])
    s = np.concatenate([kin.s_at(t_grid), s_in])
    t = np.concatenate([t_grid, kin.t_v])
    order = np.lexsort((t, s))
    s, t = s[order], t[order]
    keep = np.concatenate([[True], np.diff(t) > 1e-9 * dt])
    s, t = s[keep], t[keep]
    vertex_idx = np.minimum(np.searchsorted(t, kin.t_v - 1e-9 * dt), len(s) - 1)
    xy = np.column_stack([np.interp(s, s_in, path[:, 0]), np.interp(s, s_in, path[:, 1])])

    cum_turn = np.cumsum(turn_at)
    turn_in = np.zeros(len(s))
    turn_in[vertex_idx] = cum_turn
    turn_in = np.maximum.accumulate(turn_in)
    turn_ex = turn_in.copy()
    turn_ex[vertex_idx] -= turn_at

    t_start = t.copy()
    t_start[0] = -fix_time  # the first fix is taken at standstill before departure
    c = kin.s_at(t + fix_time)
    c[0] = 0.0
    c_idx = np.minimum(np.searchsorted(s, c, side="left"), len(s) - 1)
    xy_c = np.column_stack([np.interp(c, s_in, path[:, 0]), np.interp(c, s_in, path[:, 1])])
    offsets = fix_time * np.arange(1, measurements + 1) / measurements
    xy_m = positions_at(kin, s_in, path, t_start[:, None] + offsets[None, :])
    xy_m[0] = path[0]  # the standstill fix before departure
    return Track(s, xy, t, turn_in, turn_ex, t_start, c, c_idx, xy_c, vertex_idx, xy_m, kin)
