"""What a run did: contacts, stalls and waits, watched once a control tick, and the run's status.

Every robot's driver (:class:`sim.episode.driver.RobotDriver`, alone or in a fleet) builds one
:class:`RunWatch` and calls :meth:`RunWatch.tick` at each control tick, after the physics has
stepped. It tells

* ``collisions``: contact episodes of the robot's body with anything but the floor
  (:class:`sim.physics.contacts.ContactMonitor`), with the first one's time, true position, arc
  length along the plan and what was touched;
* ``stuck``: the robot, told to drive, made no progress along its path for longer than
  :func:`stuck_bound` (progress is the *true* position's projection on the path, not the
  estimate's: a robot pressed against a pillar whose estimate drives on is stuck);
* ``deadlocked``: a fleet robot waited for a zone without a break for longer than
  :func:`wait_bound`, or stood in a circle of robots each waiting for the next
  (:func:`wait_cycles`) for longer than :data:`CYCLE_TIME`: a circular wait is a deadlock by
  definition (a waiting robot releases nothing), whenever it forms.

The status names the worst of them, in the order of :data:`sim.episode.types.RUN_STATUSES`
(ok < collided < stuck < deadlocked). A run whose status is not ``ok`` never counts as having
reached its goal.
"""

from __future__ import annotations

import math

import numpy as np

from sim.episode.types import RUN_STATUSES

PROGRESS_STEP = 0.05
"""Progress along the path that counts as progress [m] (the true position's projection moving on
by this much restarts the stall clock); above the follower's tracking jitter."""
CREEP_SPEED = 0.02
"""The slowest the follower drives forward while steering [m/s] (``sim.episode.follower``'s creep
floor; it only stops to turn on the spot)."""
STALL_MARGIN = 2.0
"""Factor on the slowest legitimate progress (:func:`stuck_bound`) before a stall counts as stuck:
wheel slip and the drive's lag behind its command stretch a turn or a creep, by far less."""
WAIT_SLACK = 1.5
"""How much later than planned a simulated fleet may run (:func:`wait_bound`) [-]."""
WAIT_MARGIN = 10.0
"""Fixed part of the wait bound [s]: the fixes a robot takes at its goals and zone-stops' braking."""
CYCLE_TIME = 1.0
"""A circle of waiting robots that lasts this long is a deadlock [s]: a waiting robot releases nothing,
so a circle never breaks; the second only absorbs the tick on which waits and refusals are read."""
CHECK_EVERY = 30
"""Control ticks of driving between two projections of the true position on the path (0.5 s at 60 Hz)."""


def stuck_bound(max_yaw_rate: float, max_yaw_accel: float, max_speed: float, max_accel: float) -> float:
    """Return the longest a robot told to drive may legitimately make no progress [s].

    The follower makes no progress along the path only while it brakes and turns on the spot
    (at most a half turn: pi at the yaw-rate limit, with the yaw acceleration's ramps at both
    ends) or creeps (never slower than :data:`CREEP_SPEED`, so :data:`PROGRESS_STEP` takes
    ``PROGRESS_STEP / CREEP_SPEED``). The bound is :data:`STALL_MARGIN` times their sum.

    Parameters
    ----------
    max_yaw_rate, max_yaw_accel : float
        The follower's limits [rad/s], [rad/s^2].
    max_speed, max_accel : float
        Its speed and acceleration limits [m/s], [m/s^2] (braking before a turn on the spot).

    Returns
    -------
    float
        [s]
    """
    turn = math.pi / max_yaw_rate + max_yaw_rate / max_yaw_accel
    brake = max_speed / max_accel
    creep = PROGRESS_STEP / CREEP_SPEED
    return STALL_MARGIN * (brake + turn + creep)


def wait_bound(predicted_longest_wait: float, predicted_end: float) -> float:
    """Return the longest a fleet robot may legitimately wait for a zone without a break [s].

    Zone control keeps every final dock off the others' paths (:mod:`planner.fleet.zones`), so a
    robot that has arrived holds nothing another needs: a wait ends, at the latest, when the robot
    holding the zone arrives, which the plan predicts before the fleet's predicted end. The bound is
    the robot's longest predicted wait plus the fleet's predicted end stretched by
    :data:`WAIT_SLACK` (a simulated robot runs late on its plan: fixes at its goals, tracking,
    braking for its zones), plus :data:`WAIT_MARGIN`.

    Parameters
    ----------
    predicted_longest_wait : float
        The robot's longest predicted wait (``Timeline.waiting``, in one piece) [s].
    predicted_end : float
        When the plan predicts the last robot arrives [s].
    """
    return predicted_longest_wait + WAIT_SLACK * predicted_end + WAIT_MARGIN


def longest_run(flags: np.ndarray, t: np.ndarray) -> float:
    """Return the longest stretch of consecutive True samples of ``flags`` at times ``t`` [s]."""
    flags = np.asarray(flags, bool)
    if not flags.any():
        return 0.0
    dt = np.diff(t, prepend=t[0])
    best = run = 0.0
    for f, d in zip(flags.tolist(), dt.tolist(), strict=True):
        run = run + d if f else 0.0
        best = max(best, run)
    return best


def wait_cycles(waiting: list[bool], holder: list[int]) -> list[bool]:
    """Tell which robots stand in a circle of waits: i waits for holder[i], who waits for ..., who waits for i.

    Parameters
    ----------
    waiting : list of bool
        Robot i stands waiting for a zone.
    holder : list of int
        The robot holding the zone robot i waits for (-1: none).
    """
    n = len(waiting)
    out = [False] * n
    for i in range(n):
        j, seen = i, 0
        while waiting[j] and 0 <= holder[j] < n and seen < n:
            j, seen = holder[j], seen + 1
            if j == i:
                out[i] = True
                break
    return out


def worst_status(collisions: int, stuck: bool, deadlocked: bool) -> str:
    """Return the worst status of a run: ``deadlocked`` > ``stuck`` > ``collided`` > ``ok``."""
    causes = (True, collisions > 0, stuck, deadlocked)
    return [s for s, c in zip(RUN_STATUSES, causes, strict=True) if c][-1]


class RunWatch:
    """One robot's contacts, stalls and waits over a run.

    Parameters
    ----------
    contacts : sim.physics.contacts.ContactMonitor
        Reads the robot's contacts.
    path : ndarray, shape (N, 2)
        The path it drives (its first task's; :meth:`follow` sets the next) [m].
    bound : float
        :func:`stuck_bound` [s].
    dt : float
        Control period [s].
    wait_limit : float
        :func:`wait_bound` [s] (infinite for a lone robot).
    names : list of str
        Robot names (who a fleet robot waited for).
    """

    def __init__(self, contacts, path: np.ndarray, bound: float, dt: float, wait_limit: float = math.inf,
                 names: list[str] | None = None) -> None:
        self.contacts = contacts
        self.bound, self.dt, self.wait_limit = float(bound), float(dt), float(wait_limit)
        self.names = names or []
        self.contact_at = (math.nan, math.nan, math.nan)   # x, y [m], s [m]
        self.stuck = False
        self.longest_stall, self.stall_at = 0.0, (math.nan, math.nan, math.nan, math.nan)   # t, x, y, s
        self.longest_wait, self.wait_at, self.waited_for = 0.0, (math.nan, math.nan, math.nan), ""
        self._wait, self._wait_start = 0.0, (math.nan, math.nan, math.nan)
        self.waiting = False   # waiting for a zone at the last tick
        self.circular, self._circle = False, 0.0
        self._n = 0
        self.follow(path, 0.0)

    def follow(self, path: np.ndarray, offset: float) -> None:
        """Watch progress along ``path`` (the next task's) from now on; ``offset``: its start on the whole path [m]."""
        path = np.asarray(path, float).reshape(-1, 2)
        self._xy = path
        self._s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(path, axis=0).T))])
        self._offset = float(offset)
        self._i = 0
        self._best = -math.inf
        self._stall = 0.0
        self._stall_start = (math.nan, math.nan, math.nan, math.nan)

    def tick(self, t: float, pose: tuple[float, float, float], driving: bool, waiting: bool = False,
             holder: int = -1) -> None:
        """Read the contacts and account for one control period.

        Parameters
        ----------
        t : float
            Now [s].
        pose : (x, y, theta)
            The robot's true pose [m, m, rad].
        driving : bool
            The follower steers it along the path (not held for a fix, not at its goal, not
            waiting for its start or a zone).
        waiting : bool
            It stands at the end of its reservation, waiting for a zone (fleets).
        holder : int
            The robot holding the zone it waits for (-1: unknown).
        """
        if self.contacts.poll(t, pose[0], pose[1]) and self.contacts.episodes == 1:
            self.contact_at = (pose[0], pose[1], self._offset + self._project(pose[0], pose[1]))
        self.waiting = waiting
        if waiting:
            if self._wait == 0.0:
                self._wait_start = (t, pose[0], pose[1])
            self._wait += self.dt
            if self._wait > self.longest_wait:
                self.longest_wait, self.wait_at = self._wait, self._wait_start
                self.waited_for = self.names[holder] if 0 <= holder < len(self.names) else ""
        elif self._wait:
            self._wait = 0.0
        if driving and not waiting:
            self._n += 1
            if self._n >= CHECK_EVERY:   # the stall clock's resolution, far below any bound
                self._n = 0
                self._progress(t, pose)

    def _progress(self, t: float, pose: tuple[float, float, float]) -> None:
        """Project the true position on the path; restart the stall clock or advance it by CHECK_EVERY ticks."""
        s = self._project(pose[0], pose[1])
        if s >= self._best + PROGRESS_STEP:
            self._best, self._stall = s, 0.0
            return
        if self._stall == 0.0:
            self._stall_start = (t, pose[0], pose[1], self._offset + s)
        self._stall += CHECK_EVERY * self.dt
        if self._stall > self.longest_stall:
            self.longest_stall, self.stall_at = self._stall, self._stall_start
        self.stuck |= self._stall > self.bound

    def _project(self, x: float, y: float) -> float:
        """Arc length of (x, y) on the path, searched a short window around the last one [m]."""
        lo = max(self._i - 10, 0)
        xy = self._xy[lo:self._i + 60]
        if len(xy) < 2:
            self._i = lo
            return float(self._s[lo])
        a, d = xy[:-1], np.diff(xy, axis=0)
        L2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-18)
        u = np.clip(((x - a[:, 0]) * d[:, 0] + (y - a[:, 1]) * d[:, 1]) / L2, 0.0, 1.0)
        px, py = a[:, 0] + u * d[:, 0] - x, a[:, 1] + u * d[:, 1] - y
        k = int(np.argmin(px * px + py * py))
        self._i = lo + k
        return float(self._s[lo + k] + u[k] * (self._s[lo + k + 1] - self._s[lo + k]))

    def circle(self, in_circle: bool) -> None:
        """Account for one control period in (or out of) a circle of waiting robots (:func:`wait_cycles`)."""
        self._circle = self._circle + self.dt if in_circle else 0.0
        self.circular |= self._circle > CYCLE_TIME

    @property
    def deadlocked(self) -> bool:
        return self.longest_wait > self.wait_limit or self.circular

    @property
    def status(self) -> str:
        """``ok``, ``collided``, ``stuck`` or ``deadlocked`` (the worst of them)."""
        return worst_status(self.contacts.episodes, self.stuck, self.deadlocked)

    def summary(self) -> dict:
        """Return the columns of the runs table (:data:`sim.montecarlo.rows.RUN_SCHEMA`) this watch fills."""
        first_t, first_with = self.contacts.first if self.contacts.first is not None else (math.nan, None)
        out = {"status": self.status, "collisions": int(self.contacts.episodes),
               "contact_t": first_t, "contact_x": self.contact_at[0], "contact_y": self.contact_at[1],
               "contact_s": self.contact_at[2], "contact_with": first_with,
               "stuck": bool(self.stuck), "stall_time": float(self.longest_stall), "stuck_bound": self.bound,
               "stall_t": self.stall_at[0], "stall_x": self.stall_at[1], "stall_y": self.stall_at[2],
               "stall_s": self.stall_at[3], "deadlocked": bool(self.deadlocked)}
        if math.isfinite(self.wait_limit):
            out.update(longest_wait=float(self.longest_wait), wait_bound=self.wait_limit,
                       wait_t=self.wait_at[0], wait_x=self.wait_at[1], wait_y=self.wait_at[2],
                       waited_for=self.waited_for or None)
        # none of it happened: null in the runs table (NaN would not equal itself between two sweeps)
        return {k: None if isinstance(v, float) and math.isnan(v) else v for k, v in out.items()}
