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

from dataclasses import dataclass, field, replace

import numpy as np

from planner.pef.map import PEF
from planner.pef.result import PefMap
from scenarios import PlanningError
from scenarios.schema import Scenario

WINDOW_FRACTION = 0.6
"""A window larger than this share of the map's cells is computed as a whole map (cheaper)."""


class _GridOnce(PEF):
    """A PEF whose map at the scenario's resolution is one already computed (free-space planning asks for it)."""

    def __init__(self, scenario: Scenario, pef_map: PefMap):
        super().__init__(scenario)
        self._map = pef_map

    def grid(self, resolution: float | None = None) -> PefMap:
        if resolution is None or resolution == self.scenario.planning.resolution:
            return self._map
        return super().grid(resolution)


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
    """

    scenario: Scenario
    pef_map: PefMap
    reports: list = field(default_factory=list)
    plans: list = field(default_factory=list)
    unplanned: dict[int, str] = field(default_factory=dict)
    map_work: str = "computed"

    def summary(self) -> str:
        """``"14 markers, 3 tasks planned"`` (``"2 of 3 tasks planned"`` when some have no route)."""
        n = len(self.scenario.tasks)
        done = sum(p is not None for p in self.plans)
        tasks = f"{n} task{'s' if n != 1 else ''} planned" if done == n else f"{done} of {n} tasks planned"
        m = len(self.scenario.markers)
        return f"{m} marker{'s' if m != 1 else ''}, {tasks}"


def _map_key(sc: Scenario) -> tuple:
    """Everything but the markers that the PEF map depends on (frozen dataclasses: equal by their fields)."""
    p = sc.planning
    return (sc.workspace, sc.obstacles, sc.sensor, p.pef_model, p.resolution, p.redundancy, p.gdop_level)


def _marker_rows(sc: Scenario) -> list[tuple]:
    return [(m.id, m.kind, tuple(m.position), m.facing) for m in sc.markers]


class ViewBuilder:
    """Compute :class:`View` s one after another, reusing the last PEF map where it still holds."""

    def __init__(self):
        self._key: tuple | None = None
        self._markers: list[tuple] = []
        self._map: PefMap | None = None

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
            return replace(old), "window"
        if ix.size * iy.size > WINDOW_FRACTION * old.tau.size:
            return pef.grid(), "computed"
        part = pef.cells(old.x[ix[0]:ix[-1] + 1], old.y[iy[0]:iy[-1] + 1], cell_size=old.cell_size)
        rows_, cols = slice(iy[0], iy[-1] + 1), slice(ix[0], ix[-1] + 1)
        tau, best = old.tau.copy(), old.best.copy()
        tau[rows_, cols], best[rows_, cols] = part.tau, part.best
        plain = None
        if old.tau_plain is not None and part.tau_plain is not None:
            plain = old.tau_plain.copy()
            plain[rows_, cols] = part.tau_plain
        return replace(old, tau=tau, best=best, tau_plain=plain), "window"

    def build(self, sc: Scenario) -> View:
        """Compute the view of ``sc``: PEF map, route segments' τ, every task's plan.

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
        from planner.plan import plan_task
        from planner.routes.edges import segment_reports

        key = _map_key(sc)
        pef_map, work = self._pef_map(sc, key, PEF(sc))
        self._key, self._markers, self._map = key, _marker_rows(sc), pef_map
        pef = _GridOnce(sc, pef_map)
        reports = segment_reports(sc, pef) if sc.routes is not None else []
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
        return View(sc, pef_map, reports, plans, unplanned, work)
