"""The robot's body along a scheduled path: clear of every obstacle where the robot may be.

The planner keeps a disc of ``robot.radius`` (which contains the simulated body,
:mod:`scenarios.body`) clear of obstacles around each path point; the robot does not drive on the
path but within a bound of it: the follower's tracking bound there
(:func:`planner.schedule.promise.tracking_bound`: corners included, it cuts them and swings wide
leaving them, and the steady offset its wheel radius error holds; and its departure from the dock,
whose heading may differ from the path's) plus the estimate's error the plan certifies there (the
schedule's predicted error). A path is driveable when, at
every point,

    clearance(path(s)) >= radius + tracking(s) + estimate(s)

checked at samples at most :data:`CHECK_SPACING` apart with half that spacing added (the
clearance is 1-Lipschitz along the path, so between samples it falls by at most half a spacing
below the smaller of the two).

The tracking bound shrinks with the follower's lookahead, ``max(LOOKAHEAD_MIN, LOOKAHEAD_GAIN
v)``, so where the check fails at cruising speed :func:`slowed` caps the speed over the stretch
whose lookaheads decide the bound there (halving it, down to the speed whose lookahead is the
shortest); where it fails at that speed the route is refused, naming the place
(:meth:`Shortfall.message`). The estimate's error is the schedule's; slower, it does not grow
(the sensor's rate is in time, so the robot fixes more often per metre).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.routes import criteria
from planner.schedule import promise
from planner.schedule.schedule import Schedule, make_schedule
from scenarios.errors import PlanningError
from scenarios.schema import Scenario

ROUNDS = 4
"""Schedules tried, each slower where the body's clearance fell short (halving the speed there
takes a 1 m/s robot to its shortest lookahead in two)."""
CHECK_SPACING = 0.02
"""Largest spacing of the clearance check's samples along the path [m]."""
SLOWEST_LOOKAHEAD_SPEED = promise.LOOKAHEAD_MIN / promise.LOOKAHEAD_GAIN
"""Speed at and below which the follower's lookahead is its shortest [m/s]: slower does not
shrink the tracking bound."""


@dataclass(frozen=True)
class Margin:
    """The clearance check along a path, at its samples (n).

    Attributes
    ----------
    s : ndarray, shape (n,)
        Arc length of the samples [m].
    points : ndarray, shape (n, 2)
        Their positions [m].
    clearance : ndarray, shape (n,)
        Distance to the nearest obstacle or wall [m].
    radius : float
        The declared robot radius [m].
    tracking, estimate : ndarray, shape (n,)
        Follower's tracking bound and certified estimate error there [m].
    sampling : float
        Half the sample spacing [m].
    """

    s: np.ndarray
    points: np.ndarray
    clearance: np.ndarray
    radius: float
    tracking: np.ndarray
    estimate: np.ndarray
    sampling: float

    @property
    def needed(self) -> np.ndarray:
        """Clearance each sample needs [m], shape (n,)."""
        return self.radius + self.tracking + self.estimate + self.sampling

    @property
    def short(self) -> np.ndarray:
        """Samples whose clearance is below what they need, bool (n,)."""
        return self.clearance < self.needed


def margin(scenario: Scenario, path: np.ndarray, speed: np.ndarray, s_est: np.ndarray,
           estimate: np.ndarray, heading: float | None = None) -> Margin:
    """Check the body's clearance along ``path`` driven at ``speed`` (module docstring).

    Parameters
    ----------
    scenario : Scenario
        Obstacles, workspace and ``robot.radius``.
    path : ndarray, shape (N, 2)
        Path vertices [m].
    speed : ndarray, shape (N,)
        Planned vertex speeds [m/s].
    s_est, estimate : ndarray, shape (M,)
        Arc lengths [m] and the certified estimate error there [m] (the schedule's
        ``s`` and ``predicted_error``); between them the larger neighbour is taken (the error
        grows between fixes by the drift over one spacing, which the neighbour's covers when it
        lies after the fix, and a fix completing between them lowers it).
    heading : float, optional
        The robot's heading at the start, on its dock [rad]: its departure
        (:func:`planner.schedule.promise.departure_bound`) joins the tracking bound. None: the
        robot starts along the path.

    Returns
    -------
    Margin
    """
    path = np.asarray(path, dtype=float).reshape(-1, 2)
    s_v = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(path, axis=0).T))])
    pts, s = criteria.sample_polyline(path, CHECK_SPACING)
    spacing = float(np.max(np.diff(s), initial=0.0))
    est = np.asarray(estimate, dtype=float)
    # the larger of the two neighbours of each interval, then its largest over the intervals at s
    hi = np.maximum(est, np.concatenate([est[1:], est[-1:]]))
    idx = np.clip(np.searchsorted(np.asarray(s_est, dtype=float), s, side="right") - 1, 0, len(est) - 1)
    est_s = np.maximum(hi[idx], hi[np.maximum(idx - 1, 0)])
    speed = np.asarray(speed, dtype=float)
    tracking = promise.tracking_bound(path, s_v, speed, s, promise.turn_bias(scenario.robot))
    if heading is not None:
        tracking = tracking + promise.departure_bound(path, s_v, speed, s, heading)
    return Margin(s=s, points=pts, clearance=criteria.clearance(pts, scenario), radius=scenario.robot.radius,
                  tracking=tracking, estimate=est_s, sampling=0.5 * spacing)


def slowed(path: np.ndarray, speed: np.ndarray, s_short: np.ndarray) -> np.ndarray | None:
    """Speeds capped where the clearance falls short, or None when slower cannot help.

    The tracking bound at ``s`` depends on the lookaheads of the speeds within
    ``SETTLE_LOOKAHEADS + 1`` lookaheads before ``s`` and one after it
    (:func:`planner.schedule.promise.tracking_bound`); those speeds are halved, not below
    :data:`SLOWEST_LOOKAHEAD_SPEED`, braking into the stretch at the planner's acceleration limit.

    Parameters
    ----------
    path : ndarray, shape (N, 2)
    speed : ndarray, shape (N,)
        Current vertex speeds [m/s].
    s_short : ndarray
        Arc lengths where the clearance falls short [m].
    """
    path = np.asarray(path, dtype=float).reshape(-1, 2)
    speed = np.asarray(speed, dtype=float)
    s_v = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(path, axis=0).T))])
    spacing = float(np.max(np.diff(s_v), initial=0.0))
    slow, moved = [], False
    for s in np.unique(np.round(np.asarray(s_short, dtype=float), 2)):
        look = promise.LOOKAHEAD_MIN + promise.LOOKAHEAD_GAIN * float(speed.max(initial=0.0)) + spacing
        a, b = s - (promise.SETTLE_LOOKAHEADS + 1.0) * look, s + look
        lo = max(int(np.searchsorted(s_v, a, side="right")) - 1, 0)
        hi = min(int(np.searchsorted(s_v, b, side="left")), len(s_v) - 1)
        v_max = float(speed[lo:hi + 1].max(initial=0.0))
        if v_max <= SLOWEST_LOOKAHEAD_SPEED * (1.0 + 1e-9):
            continue
        slow.append((a, b, max(0.5 * v_max, SLOWEST_LOOKAHEAD_SPEED)))
        moved = True
    if not moved:
        return None
    return promise.slowed_speeds(s_v, speed, slow)


def nearest_obstacle_point(scenario: Scenario, p: np.ndarray) -> tuple[float, float]:
    """Return the point of an obstacle or the workspace's border nearest ``p`` (2,) [m]."""
    p = np.asarray(p, dtype=float)
    x0, y0, x1, y1 = scenario.workspace.bounds
    best = min(((abs(p[0] - x0), (x0, p[1])), (abs(x1 - p[0]), (x1, p[1])),
                (abs(p[1] - y0), (p[0], y0)), (abs(y1 - p[1]), (p[0], y1))), key=lambda t: t[0])
    pieces = scenario.obstacle_pieces()
    for verts, n in zip(pieces.vertices, pieces.count, strict=True):
        a = verts[:n]
        b = np.roll(a, -1, axis=0)
        ab = b - a
        w = np.clip(((p - a) * ab).sum(axis=1) / np.maximum((ab * ab).sum(axis=1), 1e-300), 0.0, 1.0)
        q = a + w[:, None] * ab
        d = np.hypot(*(q - p).T)
        i = int(np.argmin(d))
        if d[i] < best[0]:
            best = (float(d[i]), (float(q[i, 0]), float(q[i, 1])))
    return best[1]


@dataclass(frozen=True)
class Shortfall:
    """Where a path's clearance falls shortest of what the body needs."""

    s: float
    point: tuple[float, float]
    obstacle: tuple[float, float]
    clearance: float
    radius: float
    tracking: float
    estimate: float
    sampling: float

    @classmethod
    def worst(cls, scenario: Scenario, m: Margin) -> Shortfall:
        """Return the sample of ``m`` short by the most."""
        i = int(np.argmax(m.needed - m.clearance))
        return cls(float(m.s[i]), (float(m.points[i, 0]), float(m.points[i, 1])),
                   nearest_obstacle_point(scenario, m.points[i]), float(m.clearance[i]), m.radius,
                   float(m.tracking[i]), float(m.estimate[i]), m.sampling)

    def message(self, start: str, goal: str) -> str:
        """One line naming the place, the clearance and what it needs."""
        need = self.radius + self.tracking + self.estimate + self.sampling
        ox, oy = self.obstacle
        x, y = self.point
        return (f"route {start} -> {goal} passes {self.clearance:.3f} m from the obstacle at ({ox:.2f}, {oy:.2f}) "
                f"at s = {self.s:.1f} m ({x:.2f}, {y:.2f}), needs {need:.3f} m (radius {self.radius:.2f} + "
                f"tracking {self.tracking:.2f} + estimate {self.estimate:.3f} + sampling {self.sampling:.2f})")


def cleared_schedule(scenario: Scenario, pef, path: np.ndarray, speed: np.ndarray, start: str, goal: str,
                     **kwargs) -> Schedule:
    """Schedule ``path``'s fixes at speeds whose tracking keeps the body clear.

    The schedule (:func:`planner.schedule.schedule.make_schedule`, ``kwargs`` passed on) is
    checked (:func:`margin`); where the clearance falls short the stretch is slowed
    (:func:`slowed`) and scheduled again, until it clears.

    Raises
    ------
    PlanningError
        Slower does not clear it (or :data:`ROUNDS` schedules did not): names the place
        (:meth:`Shortfall.message`); or no schedule exists.
    """
    slowest = False
    for _ in range(ROUNDS):
        sched = make_schedule(scenario, pef, path, speed, **kwargs)
        m = margin(scenario, path, sched.speed, sched.s, sched.predicted_error, scenario.dock(start).pose[2])
        if not m.short.any():
            return sched
        speed = slowed(path, sched.speed, m.s[m.short])
        if speed is None:
            slowest = True
            break
    worst = Shortfall.worst(scenario, m)
    # the estimate is the only term markers change, and it is >= 0: where the body falls short
    # without it, at the slowest drive that helps, no layout of markers clears the path
    short_without = worst.clearance < worst.radius + worst.tracking + worst.sampling
    raise ClearanceError(worst.message(start, goal), markers_help=not (slowest and short_without))


class ClearanceError(PlanningError):
    """The body's clearance falls short on a path at any speed that helps (names the place).

    Parameters
    ----------
    message : str
        The one line of :meth:`Shortfall.message`.
    markers_help : bool
        False when the body falls short even with no estimate error at the slowest speed that
        helps: no placement of markers makes the path drivable (``place`` stops tightening).
    """

    def __init__(self, message: str, markers_help: bool = True):
        super().__init__(message)
        self.markers_help = markers_help
