"""Zone control of a fleet: robots reserve the floor ahead of them and wait where they block nobody.

What AGV master controls do on a route network (reserve the nodes and segments ahead, wait at a
node while the next one is held), for any planned path, on or off a network. Pure logic: no
physics. The planner runs it offline to predict when each robot is where
(:func:`predict_timeline`); the simulation asks it every control step whether a robot may go on
(:meth:`ZoneControl.request`) and tells it what the robot has left behind
(:meth:`ZoneControl.release`).

**Zones.** The floor is cut into square cells (the zones) of side ``cell``. A robot standing at a
sample of its path occupies every cell that meets the disc of radius ``radius + margin`` around
the sample (its *footprint*). Two robots whose footprints share no cell are apart by at least
``r_1 + r_2 + 2 margin`` (centre to centre): with the robots within ``margin`` of their path
samples (tracking error, the spacing of the samples, overshoot where they stop), their bodies
do not touch. A cell is held by at most one robot.

**Reservations.** Robot i holds the cells of its path samples ``lo_i .. end_i``: from where it is
to where it may drive. It releases the cells of the samples it has passed (a cell stays held
while a later held sample still covers it). It may drive up to sample ``end_i``; to go further
it reserves the stretch ``end_i + 1 .. k`` where k is its next *stop*, atomically: all its cells
or none. A stop is a *safe* sample: one whose
footprint meets no cell of any other robot's *remaining* path (samples ``lo_j ..`` to the end,
the cells robot j will still need). On a route network the stops are where a robot's path
leaves the shared stretches: before a junction or an aisle another robot will use, the "wait at
a node" of AGV practice, with the node being the last point of the robot's path clear of the
others.

**Docks.** A robot's final dock is a stop like any other sample: only once it is safe. A robot
that finishes where another must still pass waits at its last safe stop until that one has
passed (:meth:`ZoneControl.next_stop` finds no stop; the robot whose remaining path still meets
its way is ``refused_by``). A start dock is free once its robot has left it.

**The stop rule cannot deadlock when every start and final dock is clear of the other robots'
paths** (:attr:`ZoneControl.dock_conflict` is None). Then:

1. A robot only ever waits at the end of its reservation, which is a stop: its start, its
   final dock, or a sample that was safe when it was reserved. Other robots' remaining paths only
   shrink as they advance, so a safe sample stays safe. A robot standing there holds that
   sample's cells alone (:meth:`ZoneControl.stand`), so a waiting or arrived robot holds only
   cells no other robot will ever need again. **A waiting robot blocks nobody.** (Only the stop
   itself is safe: the samples just before it are not when it ends a shared stretch, nor those
   just before a final dock on a short spur. The simulation used to free only the cells it had
   passed by a slack behind its estimate, so a robot waiting there, or parked at its dock, kept
   cells of another robot's path: two such robots waited for each other, or for the parked one,
   for ever, in 100 of 100 runs on a floor of spur docks. ``tests/planner/fleet/test_deadlock_search.py`` drives
   random fleets with the simulation's real stopping points and releases.)
2. A robot that is not waiting holds every cell up to its next stop, so it reaches that stop
   without needing anything else, in finite time (it drives).
3. So a refused request waits only for cells held by driving robots, which release them when
   they pass (they stop, by 1, where they do not hold any of them). A cycle of robots each
   waiting for the next cannot form, since the robots a waiting robot waits for are driving.
   Each grant moves a robot to a later stop, and each path has finitely many: every robot
   reaches its final dock (no livelock either: the robot refused for a cell gets it once its
   holder has passed, unless another robot got it first, which can happen only finitely often).

**Docks on other robots' paths: the plan's order of passage.** Fleets trade docks (a swap, a
rotation, a robot parked on the only corridor), and then 1 fails: a robot standing on its start
holds cells another robot needs, and a robot waiting for a dock to clear may wait for one that
waits for it. Whether that happens depends on who comes first, which a real fleet's timing
changes. So the planner drives the fleet once through the stop rule (:func:`predict_timeline`;
it refuses the fleet when no robot can move, as three robots rotating through one hub, each on
a spur the next must leave first), recording in which order the robots held each cell
(``record=True``), and the robots keep that order whatever their timing
(:meth:`ZoneControl.precedence`, ``after=``): robot i may reserve its sample k only when, for
each cell of k, every robot whose holding of the cell came before i's in the plan has passed
the holding's last sample; samples are reserved one by one (no stops needed). It cannot
deadlock: suppose every robot not yet arrived is refused, standing at the end of its
reservation (it has freed all behind it). Take the refused robot i whose refused sample k the
plan reserved earliest. The cell that refused it is either still held by a robot j whose holding
comes first in the plan (a robot holding it in a later holding would have needed i's holding
done, which it is not), or owed to such a j that has not passed that holding's last sample
b. In the plan j passed b, so reserved b + 1, before i reserved k; standing short of b, j is
refused at a sample the plan reserved no later than b + 1: earlier than k, against the choice
of i. The order is a total order of the plan's events, so every chain of waits ends. Cells stay
exclusive, so the clearance holds as under the stop rule. ``tests/planner/fleet/test_dock_trades.py``
drives the hard cases with timings the plan never saw; without stops or the order the same
fleets deadlock.

**Parking.** A robot whose last dock another robot passes later may name a parking place, a dock
off every other robot's path (or get one from the planner where the fleet could not move
otherwise, :mod:`planner.fleet.parking`): it drives on to it, planned like a
task, and its last task's dock becomes a sample of its path like any other. Zone control sees only
a longer path ending on a dock clear of the others' paths: the stop rule's argument holds when the
starts are clear too, the order of passage's in any case. A robot parked on the only corridor,
which neither could drive before (it had nowhere to stand aside: no robot can move), is driven in
``tests/planner/fleet/test_parking.py`` with timings the plan never saw.

The adversarial cases (head-on on one segment, three robots in a cycle, a crossing) are in
``tests/planner/fleet/test_zones.py``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from planner.schedule.pathtime import Kinematics
from scenarios.errors import PlanningError

#: Clearance each robot keeps beyond its radius [m]: the tracking error of the path follower
#: (a few cm), half the path's sample spacing (5 cm at 0.1 m) and the overshoot of a stop; two
#: robots on disjoint zones are apart by at least twice this between their bodies.
DEFAULT_MARGIN = 0.15
#: Side of a zone cell [m]: fine against the footprint (a 0.55 m disc covers ~25 cells), so the
#: zones hold little floor beyond the footprints.
DEFAULT_CELL = 0.25
#: Most cells of a zone grid (a 250 m square at 0.25 m): a grid over a larger floor gets coarser
#: cells instead. Each robot keeps two int32 arrays over the grid (8 MB at the most, 190 MB for
#: the largest fleet, :data:`scenarios.limits.MAX_ROBOTS`).
MAX_CELLS = 1_000_000


@dataclass(frozen=True)
class ZoneGrid:
    """The square cells the floor is cut into.

    Lower-left corner ``origin`` [m], side ``cell`` [m], ``shape`` (nx, ny) cells.
    """

    origin: tuple[float, float]
    cell: float
    shape: tuple[int, int]

    @property
    def size(self) -> int:
        return self.shape[0] * self.shape[1]

    def boxes(self, ids: np.ndarray) -> np.ndarray:
        """Cells ``ids`` (flat indices) as boxes (x0, y0, x1, y1) [m], shape (n, 4)."""
        ids = np.asarray(ids, dtype=np.int64).reshape(-1)
        ix, iy = np.divmod(ids, self.shape[1])
        x0 = self.origin[0] + ix * self.cell
        y0 = self.origin[1] + iy * self.cell
        return np.stack([x0, y0, x0 + self.cell, y0 + self.cell], axis=1)


def make_grid(paths: Sequence[np.ndarray], reach: float, cell: float = DEFAULT_CELL) -> ZoneGrid:
    """Return a grid covering every path point widened by ``reach`` [m] (cells at least ``cell`` [m])."""
    pts = np.concatenate([np.asarray(p, float).reshape(-1, 2) for p in paths])
    lo = pts.min(axis=0) - reach - cell
    hi = pts.max(axis=0) + reach + cell
    extent = hi - lo
    # a footprint covers at most ~(2 reach / cell + 3)^2 cells: a big robot gets coarser cells
    cell = max(cell, reach / 4.0, math.sqrt(float(extent[0] * extent[1]) / MAX_CELLS))
    shape = tuple(int(n) for n in np.ceil(extent / cell).astype(int) + 1)
    return ZoneGrid((float(lo[0]), float(lo[1])), float(cell), (shape[0], shape[1]))


def footprints(grid: ZoneGrid, xy: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Return the cells meeting the disc of radius ``reach`` [m] around each point of ``xy`` (N, 2).

    Returns
    -------
    indptr : ndarray of int, shape (N + 1,)
    ids : ndarray of int
        Point n's cells (flat indices) are ``ids[indptr[n]:indptr[n + 1]]``; never empty.
    """
    xy = np.asarray(xy, float).reshape(-1, 2)
    c = grid.cell
    base = np.floor((xy - np.asarray(grid.origin)) / c).astype(np.int64)      # (N, 2)
    w = int(math.ceil(reach / c)) + 1
    d = np.arange(-w, w + 1)
    dx, dy = (a.reshape(-1) for a in np.meshgrid(d, d, indexing="ij"))         # (K,)
    ix = base[:, :1] + dx                                                       # (N, K)
    iy = base[:, 1:] + dy
    x0 = grid.origin[0] + ix * c
    y0 = grid.origin[1] + iy * c
    # distance from the point to each cell's square
    ex = np.maximum(np.maximum(x0 - xy[:, :1], xy[:, :1] - (x0 + c)), 0.0)
    ey = np.maximum(np.maximum(y0 - xy[:, 1:], xy[:, 1:] - (y0 + c)), 0.0)
    meet = (ex * ex + ey * ey <= reach * reach) & (ix >= 0) & (iy >= 0) & (ix < grid.shape[0]) & (iy < grid.shape[1])
    ids = (ix * grid.shape[1] + iy)[meet]
    indptr = np.concatenate([[0], np.cumsum(meet.sum(axis=1))])
    return indptr, ids


class ZoneControl:
    """Reservations of a fleet's paths (module docstring: zones, the rule, why it cannot deadlock).

    Parameters
    ----------
    paths : sequence of ndarray, shape (N_i, 2)
        Each robot's whole path (all its tasks, in order), points at most a few cm apart [m].
    radii : sequence of float
        Each robot's footprint radius [m].
    names : sequence of str, optional
        Robot names for messages (default ``robot 0``, ...).
    margin : float
        Clearance each robot keeps beyond its radius [m].
    cell : float
        Side of a zone cell [m].
    record : bool
        Record the order in which the robots hold each cell (:meth:`precedence`).
    after : sequence of ndarray, optional
        A recorded run's :meth:`precedence`: requests keep that order of passage, sample by
        sample (module docstring), instead of reserving stop by stop.

    Raises
    ------
    PlanningError
        Two robots' starts, or two robots' final docks, lie within each other's clearance.
    """

    def __init__(self, paths: Sequence[np.ndarray], radii: Sequence[float], names: Sequence[str] | None = None,
                 *, margin: float = DEFAULT_MARGIN, cell: float = DEFAULT_CELL, record: bool = False,
                 after: Sequence[np.ndarray] | None = None) -> None:
        self.paths = [np.asarray(p, float).reshape(-1, 2) for p in paths]
        n = len(self.paths)
        if len(radii) != n or any(len(p) == 0 for p in self.paths):
            raise PlanningError(f"zone control: expected one non-empty path and one radius per robot "
                                f"({n} paths, {len(radii)} radii)")
        self.names = list(names) if names is not None else [f"robot {i}" for i in range(n)]
        self.s = [np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(p, axis=0).T))]) for p in self.paths]
        self.reach = [float(r) + margin for r in radii]
        self.grid = make_grid(self.paths, max(self.reach), cell)
        self._feet = [footprints(self.grid, p, r) for p, r in zip(self.paths, self.reach, strict=True)]
        g = self.grid.size
        # last[j][c]: the last sample of robot j whose footprint covers cell c (-1: none)
        self._last = []
        for (indptr, ids), p in zip(self._feet, self.paths, strict=True):
            last = np.full(g, -1, dtype=np.int32)
            sample = np.repeat(np.arange(len(p)), np.diff(indptr))
            np.maximum.at(last, ids, sample)
            self._last.append(last)
        # need[i][j, k]: the last sample of robot j that shares a cell with robot i's sample k
        self._need = []
        for i, (indptr, ids) in enumerate(self._feet):
            rows = np.full((n, len(self.paths[i])), -1, dtype=np.int64)
            for j in range(n):
                if j != i:
                    rows[j] = np.maximum.reduceat(self._last[j][ids], indptr[:-1])
            self._need.append(rows)
        #: Why the stop rule alone cannot keep this fleet from deadlock (None: every robot's start
        #: and final dock lie clear of the others' paths, module docstring).
        self.dock_conflict = self._dock_conflict()
        self._check_apart()
        #: The plan's order of passage (:meth:`precedence`): ``after[i][j, k]`` is the sample robot
        #: j must have passed before robot i may reserve its sample k (-1: none). Given, requests
        #: follow it sample by sample instead of stop by stop.
        self.after = None if after is None else [np.asarray(a, dtype=np.int64) for a in after]
        self._record = record
        #: A recording run's holdings, per cell: (robot, last sample of the holding) in the order freed.
        self._history: dict[int, list[tuple[int, int]]] = {}
        self.owner = np.full(g, -1, dtype=np.int32)
        self._count = [np.zeros(g, dtype=np.int32) for _ in range(n)]
        self.lo = [0] * n
        self.end = [0] * n
        #: The robot holding a cell robot i's last refused request needed (-1: none refused yet).
        self.refused_by = [-1] * n
        for i in range(n):
            self._take(i, 0, 1)

    # -- the rule ---------------------------------------------------------------------------

    def _check_apart(self) -> None:
        """Refuse two robots whose starts, or whose final docks, share a cell: they would stand on each other."""
        for k, what in ((0, "starts"), (-1, "final docks")):
            seen: dict[int, int] = {}
            for i, (indptr, ids) in enumerate(self._feet):
                kk = k % (len(indptr) - 1)
                for c in ids[indptr[kk]:indptr[kk + 1]].tolist():
                    j = seen.setdefault(c, i)
                    if j != i:
                        raise PlanningError(f"zone control: {self.names[j]}'s and {self.names[i]}'s {what} lie within "
                                            f"{self.reach[i] + self.reach[j]:.2f} m of each other: one robot would "
                                            f"stand on the other")

    def _dock_conflict(self) -> str | None:
        for i, need in enumerate(self._need):
            for k, what in ((0, "start"), (len(self.paths[i]) - 1, "final dock")):
                j = int(np.argmax(need[:, k]))
                if need[j, k] >= 0:
                    x, y = self.paths[i][k]
                    return (f"{self.names[i]}'s {what} ({x:.2f}, {y:.2f}) lies within "
                            f"{self.reach[i] + self.reach[j]:.2f} m of {self.names[j]}'s path")
        return None

    def meets(self, i: int, k: int) -> np.ndarray:
        """Return, per robot j, the last sample of j's path sharing a zone cell with robot i's sample ``k``.

        -1 where none does, and for i itself; shape (n,).
        """
        return self._need[i][:, k].copy()

    def _cells(self, i: int, a: int, b: int) -> np.ndarray:
        """Cells of robot i's samples a .. b-1."""
        indptr, ids = self._feet[i]
        return ids[indptr[a]:indptr[b]]

    def _take(self, i: int, a: int, b: int) -> None:
        cells = self._cells(i, a, b)
        np.add.at(self._count[i], cells, 1)
        self.owner[cells] = i

    def safe(self, i: int, k: int | np.ndarray) -> np.ndarray | bool:
        """Tell whether robot i's sample(s) ``k`` meet no cell of another robot's remaining path."""
        lo = np.asarray(self.lo)
        need = self._need[i][:, k]
        return np.all(need < (lo[:, None] if np.ndim(k) else lo), axis=0)

    def next_stop(self, i: int) -> int | None:
        """Robot i's next stop after its reservation end: the first safe sample (None: none is safe yet).

        Its final dock is a stop only when safe, as any other sample: a dock another robot has
        still to pass is reserved once that robot has passed it.
        """
        e, last = self.end[i], len(self.paths[i]) - 1
        if e >= last:
            return last
        ks = np.arange(e + 1, last + 1)
        ok = np.flatnonzero(self.safe(i, ks))
        return int(ks[ok[0]]) if len(ok) else None

    def request(self, i: int, s: float) -> bool:
        """Extend robot i's reservation to arc length ``s`` [m] (on its path); tell whether it reaches it.

        Reserves stop by stop, each stretch all or nothing; on a refusal the reservation ends
        at the last stop granted (:meth:`reserved_to`), where the robot must wait.
        """
        n = len(self.paths[i])
        target = min(int(np.searchsorted(self.s[i], s, side="left")), n - 1)
        if self.after is not None:
            return self._request_in_order(i, target)
        while self.end[i] < target:
            k = self.next_stop(i)
            if k is None:
                # every sample ahead is on a path another robot has still to drive: wait for it
                need, lo = self._need[i][:, self.end[i] + 1:], np.asarray(self.lo)[:, None]
                self.refused_by[i] = int(np.argmax(np.any(need >= lo, axis=1)))
                return False
            cells = self._cells(i, self.end[i] + 1, k + 1)
            held = self.owner[cells]
            others = held[(held >= 0) & (held != i)]
            if len(others):
                self.refused_by[i] = int(others[0])
                return False
            self._take(i, self.end[i] + 1, k + 1)
            self.end[i] = k
        return True

    def _request_in_order(self, i: int, target: int) -> bool:
        """Reserve robot i's samples up to ``target`` one by one, in the plan's order of passage."""
        lo = np.asarray(self.lo)
        after = self.after[i]
        while self.end[i] < target:
            k = self.end[i] + 1
            late = np.flatnonzero(after[:, k] >= lo)
            if len(late):
                self.refused_by[i] = int(late[0])
                return False
            held = self.owner[self._cells(i, k, k + 1)]
            others = held[(held >= 0) & (held != i)]
            if len(others):
                self.refused_by[i] = int(others[0])
                return False
            self._take(i, k, k + 1)
            self.end[i] = k
        return True

    def stand(self, i: int) -> None:
        """Robot i stands at the end of its reservation: free every cell but its stop's.

        The simulation calls it when a robot waits (it stands within ``STOP_MARGIN`` of the
        reservation's end, :mod:`sim.episode.fleet`) and when it has arrived at its final dock
        (within the follower's goal tolerance of it): ``margin`` covers that gap, and the rule's
        argument (module docstring, 1) needs a standing robot to hold its stop's cells alone.
        """
        self.release(i, float(self.s[i][self.end[i]]))

    def release(self, i: int, s: float) -> None:
        """Robot i is at arc length ``s`` [m]: free the cells only its passed samples cover."""
        k = int(np.searchsorted(self.s[i], s, side="right")) - 1
        k = min(max(k, self.lo[i]), self.end[i])
        if k <= self.lo[i]:
            return
        cells = self._cells(i, self.lo[i], k)
        np.subtract.at(self._count[i], cells, 1)
        free = cells[self._count[i][cells] == 0]
        self.owner[free] = -1
        if self._record and len(free):
            # the holding of each freed cell ends at the last released sample covering it
            indptr = self._feet[i][0]
            sample = np.repeat(np.arange(self.lo[i], k), np.diff(indptr[self.lo[i]:k + 1]))
            last = {}
            for c, q in zip(cells.tolist(), sample.tolist(), strict=True):
                last[c] = q
            for c in np.unique(free).tolist():
                self._history.setdefault(c, []).append((i, last[c]))
        self.lo[i] = k

    def precedence(self) -> list[np.ndarray]:
        """Return the order of passage of a recording run (``record=True``), driven to its end.

        For each robot i an int array (n, N_i): entry [j, k] is the last sample of robot j's
        path that robot j must have passed (freed) before robot i may reserve its sample k:
        over the cells of sample k, the largest last sample of j's holdings of the cell that
        came before i's holding of it in this run (-1: none). Cells still held (the final
        docks) count as held for ever.
        """
        n = len(self.paths)
        hist = {c: list(h) for c, h in self._history.items()}
        for c in np.flatnonzero(self.owner >= 0).tolist():
            hist.setdefault(c, []).append((int(self.owner[c]), np.iinfo(np.int64).max))
        out = []
        for i in range(n):
            indptr, ids = self._feet[i]
            sample = np.repeat(np.arange(len(self.paths[i])), np.diff(indptr))
            after = np.full((n, len(self.paths[i])), -1, dtype=np.int64)
            order = np.argsort(ids, kind="stable")
            cells, starts = np.unique(ids[order], return_index=True)
            for c, ks in zip(cells.tolist(), np.split(sample[order], starts[1:]), strict=True):
                h = hist.get(c, [])
                if not any(r != i for r, _ in h):
                    continue
                prefix = np.full((len(h) + 1, n), -1, dtype=np.int64)   # largest b per robot before each holding
                for m, (r, b) in enumerate(h):
                    prefix[m + 1] = prefix[m]
                    if r != i:
                        prefix[m + 1, r] = max(prefix[m, r], b)
                mine = [(m, b) for m, (r, b) in enumerate(h) if r == i]
                if not mine:
                    raise PlanningError(f"zone control: {self.names[i]} never held a cell of its path: "
                                        "the recording run did not reach its end")
                pos = np.array([m for m, _ in mine])
                ends = np.array([b for _, b in mine])
                which = np.minimum(np.searchsorted(ends, ks, side="left"), len(mine) - 1)
                after[:, ks] = np.maximum(after[:, ks], prefix[pos[which]].T)
            out.append(after)
        return out

    # -- reading ------------------------------------------------------------------------------

    def reserved_to(self, i: int) -> float:
        """Arc length up to which robot i may drive [m] (its reservation's end)."""
        return float(self.s[i][self.end[i]])

    def length(self, i: int) -> float:
        """Length of robot i's path [m]."""
        return float(self.s[i][-1])

    def held(self, i: int) -> np.ndarray:
        """Flat indices of the cells robot i holds, sorted."""
        return np.flatnonzero(self.owner == i)

    def point(self, i: int, s: np.ndarray | float) -> np.ndarray:
        """Position on robot i's path at arc length(s) ``s`` [m], shape (..., 2)."""
        p = self.paths[i]
        return np.stack([np.interp(s, self.s[i], p[:, 0]), np.interp(s, self.s[i], p[:, 1])], axis=-1)


@dataclass(frozen=True)
class Timeline:
    """One robot's predicted drive in space and time (T samples).

    Attributes
    ----------
    t : ndarray, shape (T,)
        Time [s] (the fleet's clock: 0 when the first robot may start).
    s : ndarray, shape (T,)
        Arc length along the robot's whole path [m].
    xy : ndarray, shape (T, 2)
        Position [m].
    waiting : ndarray of bool, shape (T,)
        The robot stood waiting for a zone during the step ending at this sample.
    holder : ndarray of int, shape (T,), optional
        At a waiting sample, the robot holding the zone it waited for (-1 elsewhere); None:
        not recorded (no waits).
    wait_time : float
        Time spent waiting for zones [s] (not counting the wait for its start time).
    end_time : float
        When it reaches its final dock [s].
    """

    t: np.ndarray
    s: np.ndarray
    xy: np.ndarray
    waiting: np.ndarray
    wait_time: float
    end_time: float
    holder: np.ndarray | None = None


def predict_timeline(zones: ZoneControl, kinematics: Sequence[Kinematics], start_times: Sequence[float],
                     dt: float = 0.1, max_time: float | None = None) -> list[Timeline]:
    """Drive the fleet through ``zones`` at its planned speeds: who is where when, waits included.

    Each robot follows its own clock along its planned time profile (``kinematics[i]``, arc
    length of ``zones.paths[i]`` against time) from ``start_times[i]``, asks for the zones up to
    where the next step takes it and, refused, drives to its reservation's end and waits there
    (its clock stands still). Robots ask in index order each step. ``zones`` is consumed.

    Parameters
    ----------
    zones : ZoneControl
        Fresh zone control of the fleet's paths.
    kinematics : sequence of Kinematics
        Arc length against time of each robot's undisturbed drive.
    start_times : sequence of float
        When each robot leaves its first dock [s].
    dt : float
        Time step [s].
    max_time : float, optional
        Give up after this long [s]; default 10 x (the latest start + the longest drive) + 60 s.

    Returns
    -------
    list of Timeline

    Raises
    ------
    PlanningError
        No robot could move while some had not arrived (cannot happen under the rule, see the
        module docstring), or the fleet had not arrived by ``max_time``.
    """
    n = len(zones.paths)
    total = [float(k.t_v[-1]) if len(k.t_v) else 0.0 for k in kinematics]
    if max_time is None:
        max_time = 10.0 * (max(start_times) + max(total)) + 60.0
    clock = [0.0] * n
    s_now = [0.0] * n
    done = [zones.length(i) <= 0.0 for i in range(n)]
    rows: list[list[tuple[float, float, bool, int]]] = [[(0.0, 0.0, False, -1)] for _ in range(n)]
    waited = [0.0] * n
    end_time = [0.0 if done[i] else math.nan for i in range(n)]
    t = 0.0
    while not all(done):
        if t > max_time:
            late = ", ".join(zones.names[i] for i in range(n) if not done[i])
            raise PlanningError(f"zone control: {late} had not arrived after {max_time:.0f} s")
        t_next = t + dt
        moved = False
        for i in range(n):
            if done[i]:
                continue
            if t_next <= start_times[i]:
                rows[i].append((t_next, 0.0, False, -1))
                moved = True   # waiting for its start time is progress of the clock, not a jam
                continue
            step = min(dt, t_next - start_times[i])
            goal_s = float(kinematics[i].s_at(clock[i] + step))
            if zones.request(i, goal_s):
                s_new, c_new, wait = goal_s, clock[i] + step, 0.0
            else:
                s_new = max(s_now[i], min(goal_s, zones.reserved_to(i)))
                c_new = min(clock[i] + step, max(clock[i], float(kinematics[i].t_at(s_new))))
                wait = step - (c_new - clock[i])
            waited[i] += wait
            moved |= s_new > s_now[i] or c_new > clock[i]
            s_now[i], clock[i] = s_new, c_new
            zones.release(i, s_new)
            rows[i].append((t_next, s_new, wait > 1e-9, zones.refused_by[i] if wait > 1e-9 else -1))
            if c_new >= total[i] or s_new >= zones.length(i):
                done[i] = True
                end_time[i] = t_next - max(0.0, c_new - total[i])
        if not moved:
            stuck = ", ".join(f"{zones.names[i]} at s = {s_now[i]:.2f} m" for i in range(n) if not done[i])
            raise PlanningError(f"zone control: no robot can move ({stuck})")
        t = t_next
    out = []
    for i in range(n):
        arr = np.array([(a, b) for a, b, _, _ in rows[i]], dtype=float).reshape(-1, 2)
        out.append(Timeline(t=arr[:, 0], s=arr[:, 1], xy=zones.point(i, arr[:, 1]),
                            waiting=np.array([w for _, _, w, _ in rows[i]], dtype=bool),
                            wait_time=float(waited[i]), end_time=float(end_time[i]),
                            holder=np.array([h for _, _, _, h in rows[i]], dtype=int)))
    return out
