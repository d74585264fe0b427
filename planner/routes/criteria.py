"""Route criteria (paper fig. 7-8): scoring a path; choosing is :mod:`planner.routes.ranking`.

Five criteria, all "lower is better", in the order of :class:`scenarios.Weights`:

=============  ==================================================  ========
criterion      value                                               unit
=============  ==================================================  ========
accuracy       max τ along the path                                m
length         travel time (see :func:`travel_time`)               s
traffic        length-weighted mean traffic density of segments    -
clearance      minus the minimum clearance to obstacles and walls  m
smoothness     total turning                                       rad
=============  ==================================================  ========

A route is admissible when τ < ε_max at every sample and its clearance is at least the
robot radius.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from planner.pef.convex import signed_distance_min
from planner.pef.visibility import prepare
from scenarios.schema import Scenario

CRITERIA: tuple[str, ...] = ("accuracy", "length", "traffic", "clearance", "smoothness")

# Criteria are compared at this many significant digits, so that two mirror-image routes
# whose lengths differ by floating-point noise tie instead of being ordered (or one
# "dominating" the other) by that noise.
TIE_DIGITS = 9


def tie_round(values: np.ndarray) -> np.ndarray:
    """Values rounded to :data:`TIE_DIGITS` significant digits (inf and NaN unchanged)."""
    v = np.asarray(values, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        mag = np.where(np.isfinite(v) & (v != 0), np.floor(np.log10(np.abs(v))), 0.0)
    scale = 10.0 ** (TIE_DIGITS - 1 - mag)
    return np.where(np.isfinite(v), np.round(v * scale) / scale, v)


@dataclass(frozen=True)
class RouteScore:
    """The measured criteria of one route.

    Attributes
    ----------
    length : float
        Path length [m].
    time : float
        Travel time including turning slow-downs and measurement stops [s].
    max_tau, mean_tau : float
        Largest and arc-length mean predicted error τ along the path [m] (inf if a sample
        sees too few markers).
    worst_point : tuple[float, float]
        Where τ is largest [m].
    traffic : float
        Length-weighted mean traffic density [-].
    min_clearance : float
        Smallest distance from the path to an obstacle or wall [m] (negative inside one).
    turning : float
        Total absolute heading change [rad].
    n_fixes, n_stops : int
        Estimated fixes along the route and how many of them need the robot to stop.
    """

    length: float
    time: float
    max_tau: float
    mean_tau: float
    worst_point: tuple[float, float]
    traffic: float
    min_clearance: float
    turning: float
    n_fixes: int
    n_stops: int

    def vector(self) -> np.ndarray:
        """Criteria in :data:`CRITERIA` order, shape (5,), lower is better."""
        return np.array([self.max_tau, self.time, self.traffic, -self.min_clearance, self.turning])

    def why_inadmissible(self, eps_max: float, robot_radius: float) -> str:
        """Empty if admissible, else a short reason naming the value that fails."""
        if not self.max_tau < eps_max:
            x, y = self.worst_point
            # in mm, as the plan table shows tau (positions and clearances stay in m)
            return f"tau {self.max_tau * 1e3:.4g} mm >= eps_max {eps_max * 1e3:g} mm at ({x:.2f}, {y:.2f})"
        if self.min_clearance < robot_radius:
            return f"clearance {self.min_clearance:.3f} m < robot radius {robot_radius:g} m"
        return ""


# ---------------------------------------------------------------------------- geometry


def clearance(points: np.ndarray, scenario: Scenario) -> np.ndarray:
    """Distance from each point to the nearest obstacle or workspace wall.

    Parameters
    ----------
    points : ndarray, shape (N, 2)
        Positions [m].
    scenario : Scenario
        Supplies the obstacles (any shape, through their convex pieces) and the workspace.

    Returns
    -------
    ndarray, shape (N,)
        Clearance [m]; negative inside an obstacle or outside the workspace.
    """
    p = np.ascontiguousarray(np.asarray(points, dtype=float).reshape(-1, 2))
    x0, y0, x1, y1 = scenario.workspace.bounds
    d = np.minimum.reduce([p[:, 0] - x0, x1 - p[:, 0], p[:, 1] - y0, y1 - p[:, 1]])
    pa = prepare(scenario.obstacle_pieces())
    signed_distance_min(np.ascontiguousarray(p[:, 0]), np.ascontiguousarray(p[:, 1]), pa.vertices, pa.count,
                        pa.bbox, d)
    return d


def polyline_length(polyline: np.ndarray) -> float:
    """Length [m] of a polyline, shape (n, 2)."""
    return float(np.hypot(*np.diff(np.asarray(polyline, float), axis=0).T).sum())


def turning(polyline: np.ndarray) -> float:
    """Total absolute heading change [rad] along a polyline, shape (n, 2).

    Zero-length pieces are skipped; a U-turn counts π.
    """
    d = np.diff(np.asarray(polyline, float), axis=0)
    d = d[np.hypot(d[:, 0], d[:, 1]) > 1e-12]
    if len(d) < 2:
        return 0.0
    cross = d[:-1, 0] * d[1:, 1] - d[:-1, 1] * d[1:, 0]
    dot = (d[:-1] * d[1:]).sum(axis=1)
    return float(np.abs(np.arctan2(cross, dot)).sum())


def traffic_density(polyline: np.ndarray, segment_traffic: Sequence[float] | None) -> float:
    """Length-weighted mean traffic of the polyline's segments (0 without traffic data).

    Parameters
    ----------
    polyline : ndarray, shape (n, 2)
        Vertices [m].
    segment_traffic : sequence of float, length n - 1, or None
        Density of each segment [-].
    """
    if segment_traffic is None:
        return 0.0
    seg = np.hypot(*np.diff(np.asarray(polyline, float), axis=0).T)
    total = seg.sum()
    return float(np.dot(seg, np.asarray(segment_traffic, float)) / total) if total > 0 else 0.0


def sample_polyline(polyline: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Points along a polyline no farther apart than ``spacing``, vertices included.

    Parameters
    ----------
    polyline : ndarray, shape (n, 2)
        Vertices [m].
    spacing : float
        Largest distance between consecutive samples [m].

    Returns
    -------
    points : ndarray, shape (N, 2)
    s : ndarray, shape (N,)
        Arc length at each sample [m].
    """
    v = np.asarray(polyline, float).reshape(-1, 2)
    seg = np.hypot(*np.diff(v, axis=0).T)
    pts, ss = [v[:1]], [np.zeros(1)]
    s0 = 0.0
    for a, b, L in zip(v[:-1], v[1:], seg, strict=True):
        n = max(1, math.ceil(L / spacing - 1e-9))
        u = np.arange(1, n + 1) / n
        pts.append(a + u[:, None] * (b - a))
        ss.append(s0 + u * L)
        s0 += L
    return np.concatenate(pts), np.concatenate(ss)


# ------------------------------------------------------------------------- travel time


def fix_positions(s: np.ndarray, tau: np.ndarray, scenario: Scenario) -> np.ndarray:
    """Estimate the sample indices where the robot takes a fix.

    Model: after a fix at a point with error τ the robot dead-reckons; its odometry drifts
    by about ``(odometry_noise + wheel_radius_error)`` per metre, so the next fix is due when
    the drift eats the margin ``ε_max − τ``. Fixes are never closer than the sensor allows
    at full speed (``max_speed / fix_rate_hz``). This estimate only ranks routes; the
    measurement schedule of the chosen route is computed by :mod:`planner.schedule.schedule`.

    Parameters
    ----------
    s : ndarray, shape (N,)
        Arc length of the samples [m], increasing.
    tau : ndarray, shape (N,)
        τ at the samples [m].
    scenario : Scenario

    Returns
    -------
    ndarray of int, shape (F,)
    """
    eps = scenario.planning.eps_max
    drift = max(scenario.robot.odometry_noise + abs(scenario.robot.wheel_radius_error), 1e-9)
    min_step = scenario.robot.max_speed / scenario.sensor.fix_rate_hz
    idx, sf = [], 0.0
    while True:
        i = int(np.searchsorted(s, sf - 1e-12))
        if i >= len(s):
            break
        idx.append(i)
        margin = eps - tau[i] if np.isfinite(tau[i]) else 0.0
        sf = s[i] + max(margin / drift, min_step)
    return np.asarray(idx, dtype=int)


def travel_time(s: np.ndarray, speed: np.ndarray, tau: np.ndarray, scenario: Scenario,
                turn_in_place: float = 0.0) -> tuple[float, int, int]:
    """Travel time of a path with its speed profile, turning stops and measurement stops.

    Model: driving time ``Σ Δs / mean(v_i, v_i+1)`` (exact for piecewise constant
    acceleration); ``turn_in_place`` radians of on-the-spot rotation at ``max_yaw_rate``
    (sharp corners that could not be rounded); and at each estimated fix
    (:func:`fix_positions`) a stop of ``k · measurement_time`` when measuring on the move
    would smear the fix past the bound, i.e. when ``τ + v · k · measurement_time ≥ ε_max``
    (the robot moves ``v · measurement_time`` between the k sequential range readings).

    Parameters
    ----------
    s : ndarray, shape (N,)
        Arc length [m].
    speed : ndarray, shape (N,)
        Reference speed [m/s].
    tau : ndarray, shape (N,)
        τ at the samples [m].
    scenario : Scenario
    turn_in_place : float
        Total on-the-spot rotation [rad].

    Returns
    -------
    time : float
        [s]
    n_fixes, n_stops : int
    """
    ds = np.diff(s)
    vm = 0.5 * (speed[:-1] + speed[1:])
    moving = ds > 0
    if np.any(moving & (vm <= 0)):
        raise ValueError("speed profile is zero over a segment of positive length")
    t = float(np.sum(ds[moving] / vm[moving]))
    t += turn_in_place / scenario.robot.max_yaw_rate
    fixes = fix_positions(s, tau, scenario)
    dwell = scenario.sensor.markers_per_fix * scenario.sensor.measurement_time
    smear = speed[fixes] * dwell
    stops = int(np.count_nonzero(~(tau[fixes] + smear < scenario.planning.eps_max)))
    return t + stops * dwell, len(fixes), stops
