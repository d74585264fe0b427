"""Turning a polyline into a path a differential-drive robot can follow, and its speeds.

Two steps, each checked against an admissibility predicate ``ok(points (N,2)) -> (N,) bool``
(τ < ε_max and clear of the inflated obstacles):

1. :func:`shortcut` — greedy line-of-sight shortcutting of a grid path;
2. :func:`round_corners` — each corner replaced by a circular arc tangent to both legs,
   radius as large as the legs allow up to ``radius`` and never below ``min_radius``
   (curvature ≤ 1/min_radius); a corner whose arc cannot be admissible at any radius, or
   whose legs are too short, stays sharp and the robot stops and turns on the spot there.

:func:`speed_profile` then limits speed by ``max_speed``, by ``max_yaw_rate · R`` on arcs,
and by an acceleration limit before stops and the goal.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from scenarios.schema import RobotSpec

OkFn = Callable[[np.ndarray], np.ndarray]

# Acceleration limit of the speed profile [m/s^2]; RobotSpec has no such key yet.
MAX_ACCEL = 0.5


def min_turn_radius(robot: RobotSpec) -> float:
    """Smallest arc radius [m] the smoother uses: half the wheel base.

    Below it the inner wheel would have to run backwards; the robot can still turn on the
    spot at sharp corners, which the path marks as stops.
    """
    return robot.wheel_base / 2.0


def cruise_turn_radius(robot: RobotSpec) -> float:
    """Arc radius [m] at which the robot can keep ``max_speed``: ``max_speed / max_yaw_rate``."""
    return robot.max_speed / robot.max_yaw_rate


@dataclass(frozen=True)
class SmoothPath:
    """A sampled reference path.

    Attributes
    ----------
    points : ndarray, shape (N, 2)
        Samples [m], consecutive ones at most the requested spacing apart.
    s : ndarray, shape (N,)
        Arc length [m].
    curvature : ndarray, shape (N,)
        Unsigned curvature [1/m]: 1/R on arcs, 0 on straight legs.
    stop : ndarray of bool, shape (N,)
        Sharp corners kept: the robot stops and turns on the spot.
    turn_in_place : float
        Total rotation on the spot at those corners [rad].
    """

    points: np.ndarray
    s: np.ndarray
    curvature: np.ndarray
    stop: np.ndarray
    turn_in_place: float

    @property
    def length(self) -> float:
        return float(self.s[-1])


def clean_polyline(polyline: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Drop repeated vertices and vertices where the path goes straight on, shape (m, 2)."""
    v = np.asarray(polyline, float).reshape(-1, 2)
    keep = [v[0]]
    for p in v[1:]:
        if math.dist(p, keep[-1]) > tol:
            keep.append(p)
    out = [keep[0]]
    for i in range(1, len(keep) - 1):
        a, b = keep[i] - out[-1], keep[i + 1] - keep[i]
        cross = a[0] * b[1] - a[1] * b[0]
        if abs(cross) > tol * np.hypot(*a) * np.hypot(*b) or np.dot(a, b) < 0:
            out.append(keep[i])
    if len(keep) > 1:
        out.append(keep[-1])
    return np.array(out)


def _segment_samples(a: np.ndarray, b: np.ndarray, spacing: float) -> np.ndarray:
    n = max(1, math.ceil(math.dist(a, b) / spacing - 1e-9))
    u = np.arange(1, n + 1) / n
    return a + u[:, None] * (b - a)


def segment_ok(a: np.ndarray, b: np.ndarray, ok: OkFn, spacing: float) -> bool:
    """Whether every sample of segment a–b (``spacing`` apart, ends included) passes ``ok``."""
    pts = np.vstack([a[None], _segment_samples(np.asarray(a, float), np.asarray(b, float), spacing)])
    return bool(np.all(ok(pts)))


def shortcut(polyline: np.ndarray, ok: OkFn, spacing: float, lookahead: int = 400) -> np.ndarray:
    """Greedy line-of-sight shortcutting.

    From each kept vertex jump to the farthest later vertex (within ``lookahead``) whose
    straight segment passes ``ok`` at ``spacing``; neighbouring vertices are always kept as a
    fallback, so the result passes wherever the input's legs did.

    Parameters
    ----------
    polyline : ndarray, shape (n, 2)
    ok : callable
        Admissibility of points.
    spacing : float
        Sample spacing of the line-of-sight test [m].
    lookahead : int
        Farthest vertex index offset tried.

    Returns
    -------
    ndarray, shape (m, 2)
        A subsequence of the input vertices.
    """
    v = np.asarray(polyline, float)
    out, i, n = [0], 0, len(v)
    while i < n - 1:
        js = np.arange(i + 1, min(n, i + 1 + lookahead))
        lens = np.hypot(*(v[js] - v[i]).T)
        counts = np.maximum(1, np.ceil(lens / spacing - 1e-9).astype(int))
        owner = np.repeat(np.arange(len(js)), counts)
        start = np.concatenate([[0], np.cumsum(counts)[:-1]])
        u = (np.arange(counts.sum()) - start[owner] + 1) / counts[owner]
        pts = v[i] + u[:, None] * (v[js][owner] - v[i])
        bad = np.zeros(len(js), bool)
        np.logical_or.at(bad, owner, ~ok(pts))
        good = np.flatnonzero(~bad)
        j = int(js[good[-1]]) if len(good) else i + 1
        out.append(j)
        i = j
    return v[out]


def _arc(corner: np.ndarray, d_in: np.ndarray, d_out: np.ndarray, radius: float,
         spacing: float) -> tuple[np.ndarray, float]:
    """Sample the arc rounding ``corner`` (entry tangent point first); also return the tangent length."""
    theta = math.atan2(d_in[0] * d_out[1] - d_in[1] * d_out[0], float(np.dot(d_in, d_out)))
    t = radius * math.tan(abs(theta) / 2.0)
    entry = corner - d_in * t
    normal = np.array([-d_in[1], d_in[0]]) * math.copysign(1.0, theta)
    centre = entry + normal * radius
    phi0 = math.atan2(entry[1] - centre[1], entry[0] - centre[0])
    n = max(2, math.ceil(radius * abs(theta) / spacing))
    phi = phi0 + theta * np.arange(n + 1) / n
    return centre + radius * np.column_stack([np.cos(phi), np.sin(phi)]), t


def round_corners(polyline: np.ndarray, ok: OkFn, radius: float, min_radius: float,
                  spacing: float) -> SmoothPath:
    """Replace the polyline's corners by admissible tangent arcs and sample the result.

    Parameters
    ----------
    polyline : ndarray, shape (n, 2)
        Vertices [m]; its legs are assumed admissible.
    ok : callable
        ``ok(points (N,2)) -> (N,) bool``; arcs are accepted only if all samples pass.
    radius : float
        Preferred arc radius [m].
    min_radius : float
        Smallest allowed arc radius [m]; tighter corners stay sharp (stop and turn).
    spacing : float
        Largest sample spacing [m].

    Returns
    -------
    SmoothPath
    """
    return round_corners_many([polyline], ok, radius, min_radius, spacing)[0]


def _turn(d_in: np.ndarray, d_out: np.ndarray) -> float:
    return math.atan2(d_in[0] * d_out[1] - d_in[1] * d_out[0], float(np.dot(d_in, d_out)))


def round_corners_many(polylines: list[np.ndarray], ok: OkFn, radius: float, min_radius: float,
                       spacing: float) -> list[SmoothPath]:
    """:func:`round_corners` for several polylines, with one ``ok`` call per radius tried.

    Each corner first gets the largest radius its legs allow (up to ``radius``); corners
    whose arc fails ``ok`` are retried at half the radius while it stays ≥ ``min_radius``.
    """
    geo = []
    pending: dict[tuple[int, int], float] = {}
    for j, polyline in enumerate(polylines):
        v = clean_polyline(polyline)
        n = len(v)
        if n < 2:
            geo.append((v.reshape(-1, 2), None))
            continue
        legs = np.diff(v, axis=0)
        leg_len = np.hypot(legs[:, 0], legs[:, 1])
        dirs = legs / leg_len[:, None]
        geo.append((v, dirs))
        for c in range(1, n - 1):
            # A leg's length is shared by the corners at its two ends; end legs by one corner.
            budget = min(leg_len[c - 1] / (1.0 if c == 1 else 2.0), leg_len[c] / (1.0 if c == n - 2 else 2.0))
            half = 0.5 * abs(_turn(dirs[c - 1], dirs[c]))
            r = min(radius, budget / math.tan(half)) if half < math.pi / 2 - 1e-9 else 0.0
            if r >= min_radius:
                pending[(j, c)] = r
    arcs: dict[tuple[int, int], tuple[np.ndarray, float, float]] = {}
    while pending:
        trial = {}
        for (j, c), r in pending.items():
            v, dirs = geo[j]
            trial[(j, c)] = _arc(v[c], dirs[c - 1], dirs[c], r, spacing)
        good = ok(np.vstack([a for a, _ in trial.values()]))
        nxt, k = {}, 0
        for key, (a, t) in trial.items():
            if np.all(good[k:k + len(a)]):
                arcs[key] = (a, t, pending[key])
            elif pending[key] / 2.0 >= min_radius:
                nxt[key] = pending[key] / 2.0
            k += len(a)
        pending = nxt
    return [_assemble(v, dirs, {c: arcs[(j, c)] for (jj, c) in arcs if jj == j}, spacing)
            for j, (v, dirs) in enumerate(geo)]


def _assemble(v: np.ndarray, dirs: np.ndarray | None, arcs: dict, spacing: float) -> SmoothPath:
    """Sample legs and accepted arcs into a SmoothPath; corners without an arc are stops."""
    n = len(v)
    if dirs is None:
        return SmoothPath(v, np.zeros(n), np.zeros(n), np.zeros(n, bool), 0.0)
    pts, curv, stop = [v[:1]], [np.zeros(1)], [np.zeros(1, bool)]
    turn_spot = 0.0
    cursor = v[0]
    for c in range(1, n):
        leg_end = v[c] - dirs[c - 1] * arcs[c][1] if c in arcs else v[c]
        # Two arcs may share a leg exactly; then there is no straight piece between them.
        seg = _segment_samples(cursor, leg_end, spacing) if math.dist(cursor, leg_end) > 1e-9 else v[:0]
        pts.append(seg)
        curv.append(np.zeros(len(seg)))
        stop.append(np.zeros(len(seg), bool))
        if c == n - 1:
            break
        if c in arcs:
            a, _, r = arcs[c]
            pts.append(a[1:])
            curv.append(np.full(len(a) - 1, 1.0 / r))
            stop.append(np.zeros(len(a) - 1, bool))
            cursor = a[-1]
        else:
            # The leg before a sharp corner has positive length: a neighbouring arc takes at
            # most half of it.
            stop[-1][-1] = True
            turn_spot += abs(_turn(dirs[c - 1], dirs[c]))
            cursor = v[c]
    p = np.vstack(pts)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(p, axis=0).T))])
    return SmoothPath(p, s, np.concatenate(curv), np.concatenate(stop), turn_spot)


def speed_profile(path: SmoothPath, robot: RobotSpec, max_accel: float = MAX_ACCEL) -> np.ndarray:
    """Compute the reference speed along a path [m/s], shape (N,).

    ``v ≤ max_speed``, ``v ≤ max_yaw_rate / κ`` on arcs, ``v = 0`` at sharp-corner stops and
    at the goal, and ``|dv²/ds| ≤ 2 · max_accel`` everywhere after the start (a forward pass
    for speeding up, a backward one for braking). The start is not ramped: the follower
    leaves the dock at its own acceleration.
    """
    k = path.curvature
    v = np.where(k > 0, robot.max_yaw_rate / np.where(k > 0, k, 1.0), robot.max_speed)
    v = np.minimum(v, robot.max_speed)
    v = np.where(path.stop, 0.0, v)
    v[-1] = 0.0
    return acceleration_limited(path.s, v, max_accel)


def acceleration_limited(s: np.ndarray, v: np.ndarray, max_accel: float = MAX_ACCEL) -> np.ndarray:
    """Lower speeds so that ``|dv²/ds| ≤ 2 · max_accel`` between vertices [m/s], shape (N,).

    A forward pass for speeding up and a backward one for braking; ``v[0]`` only brakes (the
    follower leaves the dock at its own acceleration). Used by :func:`speed_profile` and for
    the schedule's slow-downs at fixes.

    Parameters
    ----------
    s : ndarray, shape (N,)
        Arc length of the vertices [m].
    v : ndarray, shape (N,)
        Speed caps at the vertices [m/s].
    max_accel : float
        Acceleration limit [m/s^2].
    """
    v = np.array(v, dtype=float)
    shape = v.shape
    two_a_ds = (2.0 * max_accel * np.diff(s)).tolist()
    w = v.ravel().tolist()  # plain floats: the same IEEE arithmetic, without numpy's per-element cost
    for i in range(1, len(w)):
        w[i] = min(w[i], math.sqrt(w[i - 1] ** 2 + two_a_ds[i - 1]))
    for i in range(len(w) - 2, -1, -1):
        w[i] = min(w[i], math.sqrt(w[i + 1] ** 2 + two_a_ds[i]))
    return np.array(w, dtype=float).reshape(shape)
