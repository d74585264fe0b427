"""What a live view shows, computed from a scenario with what the last edit left unchanged reused.

The PEF map is the costly part (3.84 M cells on the 120 x 80 m hall at 5 cm). A cell's τ depends
on the markers it can see, and a marker is seen only within ``sensor.max_range``; so when an edit
only moves or turns markers (same ids, kinds and count; same obstacles, workspace, sensor and
PEF settings) the map changes only within ``max_range`` of their old and new positions, and
only that window is computed again (:meth:`planner.pef.map.PEF.cells`, the same kernels as
:meth:`~planner.pef.map.PEF.grid`: the values are those of a full map). Any other change
computes the whole map; an edit that changes nothing the map depends on reuses it as it is.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from planner.pef.map import PEF
from planner.pef.result import PefMap, PefResult
from scenarios import PlanningError
from scenarios.schema import Scenario

WINDOW_FRACTION = 0.6
"""A window larger than this share of the map's cells is computed as a whole map (little is saved there)."""


class _Reuse(PEF):
    """A PEF that reuses what the last view computed: its map, and its values at the same points.

    The planner evaluates the PEF (:meth:`at`, :meth:`visible`) at the samples of the candidate
    routes, the same points from one edit to the next while the routes stay. Where only markers
    moved, a point's values change only within ``max_range`` of a moved marker's old or new
    position: those rows are computed again, the others are the last view's.

    Parameters
    ----------
    scenario : Scenario
    pef_map : PefMap
        The map at ``planning.resolution`` (free-space planning asks for it).
    memo : dict, optional
        The last view's values by (method, points' bytes); None: nothing to reuse.
    moved : (n, 2) float
        Old and new positions of the markers that moved [m] (empty: none moved).
    """

    def __init__(self, scenario: Scenario, pef_map: PefMap, memo: dict | None = None,
                 moved: np.ndarray | None = None):
        super().__init__(scenario)
        self._map = pef_map
        self._old = memo or {}
        self.memo: dict = {}
        self._moved = np.zeros((0, 2)) if moved is None else np.asarray(moved, dtype=float).reshape(-1, 2)

    def grid(self, resolution: float | None = None) -> PefMap:
        if resolution is None or resolution == self.scenario.planning.resolution:
            return self._map
        return super().grid(resolution)

    def _stale(self, pts: np.ndarray) -> np.ndarray:
        """Rows of ``pts`` (N, 2) within reach of a moved marker, bool (N,)."""
        reach = self.sensor.max_range * (1.0 + 1e-9) + 1e-9  # the range test's own rounding aside
        out = np.zeros(len(pts), dtype=bool)
        for q in self._moved:
            out |= np.hypot(pts[:, 0] - q[0], pts[:, 1] - q[1]) <= reach
        return out

    def _reused(self, name: str, points: np.ndarray, compute, merge):
        pts = np.ascontiguousarray(np.asarray(points, dtype=float).reshape(-1, 2))
        key = (name, pts.shape, pts.tobytes())
        if key in self.memo:
            return self.memo[key]
        old = self._old.get(key)
        if old is None:
            value = compute(pts)
        else:
            stale = self._stale(pts)
            value = old if not stale.any() else merge(old, np.flatnonzero(stale), compute(pts[stale]))
        self.memo[key] = value
        return value

    def at(self, points: np.ndarray, widen: float = 0.0) -> PefResult:
        def merge(old: PefResult, rows: np.ndarray, new: PefResult) -> PefResult:
            parts = {}
            for f in ("tau", "best", "tau_plain", "fallback"):
                a, b = getattr(old, f), getattr(new, f)
                if a is None or b is None:
                    parts[f] = (None if a is None and b is None
                                else getattr(super(_Reuse, self).at(points, widen), f))
                    continue
                a = a.copy()
                a[rows] = b
                parts[f] = a
            return PefResult(**parts)

        return self._reused(("at", widen), points, lambda p: super(_Reuse, self).at(p, widen), merge)

    def visible(self, points: np.ndarray, widen: float = 0.0) -> np.ndarray:
        def merge(old: np.ndarray, rows: np.ndarray, new: np.ndarray) -> np.ndarray:
            out = old.copy()
            out[rows] = new
            return out

        return self._reused(("visible", widen), points, lambda p: super(_Reuse, self).visible(p, widen), merge)


@dataclass
class View:
    """One update's content.

    Attributes
    ----------
    scenario : Scenario
    pef_map : PefMap
        At ``planning.resolution``.
    reports : list of planner.routes.edges.SegmentReport
        The route network's segments (empty without one).
    plans : list of planner.plan.Plan or None
        One per task; None where the task has no admissible route.
    unplanned : dict of int to str
        Why a task has no plan.
    map_work : str
        ``"reused"``, ``"window"`` (the part around moved markers) or ``"computed"``.
    seconds : dict of str to float
        Wall time of each part [s].
    planned : bool
        False for the map part of an update (:meth:`ViewBuilder.build_map`): ``plans`` and
        ``unplanned`` follow from :meth:`ViewBuilder.plan`.
    """

    scenario: Scenario
    pef_map: PefMap
    reports: list = field(default_factory=list)
    plans: list = field(default_factory=list)
    unplanned: dict[int, str] = field(default_factory=dict)
    map_work: str = "computed"
    seconds: dict[str, float] = field(default_factory=dict)
    """Wall time of each part [s]: ``map``, ``routes`` (segment τ), ``plans``."""
    planned: bool = True

    def summary(self) -> str:
        """``"14 markers, 3 tasks planned"`` (``"2 of 3 tasks planned"`` when some have no route).

        Before the plans (``planned`` False): ``"14 markers, planning 3 tasks"``.
        """
        n = len(self.scenario.tasks)
        done = sum(p is not None for p in self.plans)
        tasks = f"{n} task{'s' if n != 1 else ''} planned" if done == n else f"{done} of {n} tasks planned"
        if not self.planned:
            tasks = f"planning {n} task{'s' if n != 1 else ''}"
        m = len(self.scenario.markers)
        return f"{m} marker{'s' if m != 1 else ''}, {tasks}"


def _map_key(sc: Scenario) -> tuple:
    """Everything but the markers that the PEF map depends on (frozen dataclasses: equal by their fields)."""
    p = sc.planning
    return (sc.workspace, sc.obstacles, sc.unknown, sc.sensor, p.pef_model, p.resolution, p.redundancy, p.gdop_level)


def _marker_rows(sc: Scenario) -> list[tuple]:
    return [(m.id, m.kind, tuple(m.position), m.facing) for m in sc.markers]


class ViewBuilder:
    """Compute :class:`View` s one after another, reusing the last PEF map where it still holds.

    The builder owns the map: a view's ``pef_map`` is updated in place by the next
    :meth:`build` that only moves markers (copy it to keep it).
    """

    def __init__(self):
        self._key: tuple | None = None
        self._markers: list[tuple] = []
        self._map: PefMap | None = None
        self._memo: dict = {}
        self._pef: _Reuse | None = None

    def _pef_map(self, sc: Scenario, key: tuple, pef: PEF) -> tuple[PefMap, str]:
        rows = _marker_rows(sc)
        old = self._map
        if old is None or key != self._key or [r[:2] for r in rows] != [r[:2] for r in self._markers]:
            return pef.grid(), "computed"
        moved = [i for i, (a, b) in enumerate(zip(rows, self._markers, strict=True)) if a != b]
        if not moved:
            return old, "reused"
        pts = np.array([p for i in moved for p in (rows[i][2], self._markers[i][2])], dtype=float)
        reach = sc.sensor.max_range + 2.0 * max(old.cell_size)
        lo, hi = pts.min(axis=0) - reach, pts.max(axis=0) + reach
        ix = np.flatnonzero((old.x >= lo[0]) & (old.x <= hi[0]))
        iy = np.flatnonzero((old.y >= lo[1]) & (old.y <= hi[1]))
        if ix.size == 0 or iy.size == 0:
            return old, "window"
        if ix.size * iy.size > WINDOW_FRACTION * old.tau.size:
            return pef.grid(), "computed"
        part = pef.cells(old.x[ix[0]:ix[-1] + 1], old.y[iy[0]:iy[-1] + 1], cell_size=old.cell_size)
        rows_, cols = slice(iy[0], iy[-1] + 1), slice(ix[0], ix[-1] + 1)
        # in place: copying the hall's 100 MB of arrays costs more than computing the window
        old.tau[rows_, cols], old.best[rows_, cols] = part.tau, part.best
        if old.tau_plain is not None and part.tau_plain is not None:
            old.tau_plain[rows_, cols] = part.tau_plain
        return old, "window"

    def build(self, sc: Scenario) -> View:
        """Compute the view of ``sc``: PEF map, route segments' τ, every task's plan.

        :meth:`build_map` then :meth:`plan`.

        Parameters
        ----------
        sc : Scenario

        Returns
        -------
        View

        Raises
        ------
        PefsimError
            What the planner refuses in the scenario as a whole (a task that has no admissible
            route is not an error: it is listed in ``unplanned``).
        """
        return self.plan(self.build_map(sc))

    def build_map(self, sc: Scenario) -> View:
        """Compute what is shown before the plans: the PEF map and the route segments' τ.

        The plans follow from :meth:`plan` (call it next, with the view returned here: the
        values the planner reads are those of this map).

        Parameters
        ----------
        sc : Scenario

        Returns
        -------
        View
            With ``planned`` False and no plans yet.

        Raises
        ------
        PefsimError
            What the planner refuses in the scenario as a whole.
        """
        from planner.routes.edges import segment_reports

        t0 = time.perf_counter()
        key, rows = _map_key(sc), _marker_rows(sc)
        pef_map, work = self._pef_map(sc, key, PEF(sc))
        t1 = time.perf_counter()
        memo, moved = None, None
        if work != "computed":  # same markers but for positions and facings: values away from them hold
            memo = self._memo
            moved = [p for a, b in zip(rows, self._markers, strict=True) if a != b for p in (a[2], b[2])]
        self._key, self._markers, self._map = key, rows, pef_map
        pef = _Reuse(sc, pef_map, memo, np.array(moved, dtype=float).reshape(-1, 2) if moved else None)
        reports = segment_reports(sc, pef) if sc.routes is not None else []
        self._memo = pef.memo
        self._pef = pef
        seconds = {"map": t1 - t0, "routes": time.perf_counter() - t1}
        return View(sc, pef_map, reports, [], {}, work, seconds, planned=False)

    def plan(self, view: View) -> View:
        """Plan every task of a view from :meth:`build_map` (the last one this builder made).

        Parameters
        ----------
        view : View

        Returns
        -------
        View
            The same view with ``plans``, ``unplanned`` and ``seconds["plans"]``, ``planned`` True.
        """
        from planner.plan import plan_task

        sc, pef = view.scenario, self._pef
        if pef is None or pef.scenario is not sc:
            raise ValueError("plan: expected the view of this builder's last build_map")
        t0 = time.perf_counter()
        plans, unplanned = [], {}
        for i in range(len(sc.tasks)):
            if len(sc.markers) < sc.sensor.markers_per_fix:
                plans.append(None)
                unplanned[i] = "fewer markers than a fix needs"
                continue
            try:
                plans.append(plan_task(sc, i, pef=pef))
            except PlanningError as exc:
                plans.append(None)
                unplanned[i] = str(exc)
        self._memo = pef.memo
        return dataclasses.replace(view, plans=plans, unplanned=unplanned, planned=True,
                                   seconds={**view.seconds, "plans": time.perf_counter() - t0})
