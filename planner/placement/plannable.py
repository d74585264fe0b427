"""A placement the planner can drive on: cover the routes, plan every task, tighten until it plans.

The cover (:func:`planner.placement.placement.place`) asks each point of the routes for a
subset of markers with static ``tau < eps_max``. A plan asks more (:mod:`planner.schedule`):
the moving fix's promise (earlier ranges carried to the fix time by odometry) and the drift
between fixes must stay under eps_max too. A cover that just meets eps_max at its points can
therefore leave a stretch where the error after the last usable fix crosses eps_max: on the
built-in ``hall`` drawing without reflectors, the 9 markers of the cover left every task of
the plan without a schedule (0.7 mm over eps_max after a fix with tau 29.4 mm).

So the layout is checked with the planner itself, and while a task has no admissible route
the cover is solved again for the tighter target ``eps_max (1 - m)``, ``m`` in
:data:`TIGHTEN`, which leaves the drift room between fixes. The first target whose layout
plans every task is kept; its count is optimal (or bounded) for that target, not for eps_max.
Without tasks, or when the cover leaves points uncovered, the plain cover is returned.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

from planner.placement.placement import MILP_TIME_LIMIT, PlacementResult, place, scenario_with_markers
from scenarios.errors import PlanningError
from scenarios.schema import Scenario

TIGHTEN = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5)
"""Relative margins under eps_max tried for the cover target, in order [-]."""


@dataclass(frozen=True)
class PlannablePlacement:
    """A placement and what the planner said of it.

    Attributes
    ----------
    result : PlacementResult
        The chosen cover.
    target : float
        The cover's target [m]: every covered point has a subset with tau below it.
    unplanned : tuple of str
        ``"A->B: reason"`` for each task that still has no admissible route (empty when
        every task plans, or when the layout was not checked).
    checked : bool
        Whether the tasks were planned at all.
    """

    result: PlacementResult
    target: float
    unplanned: tuple[str, ...]
    checked: bool


Progress = Callable[[str], None]
"""``progress(line)``: told each phase of the placement as it starts (one line, no newline)."""


def _unplanned(scenario: Scenario, progress: Progress | None = None) -> tuple[tuple[str, ...], bool]:
    """Return ``"A->B: reason"`` of each task that does not plan, and whether markers could mend any of them."""
    from planner.pef.map import PEF
    from planner.plan import plan_task

    pef = PEF(scenario)  # one map for all tasks
    bad, mendable = [], False
    for i, t in enumerate(scenario.tasks):
        if progress is not None:
            progress(f"planning task {i + 1} of {len(scenario.tasks)}: {t.start} -> {t.goal}")
        try:
            plan_task(scenario, i, pef=pef)
        except PlanningError as exc:
            bad.append(f"{t.start}->{t.goal}: {exc}")
            mendable = mendable or getattr(exc, "markers_help", True)
    return tuple(bad), mendable


def place_plannable(scenario: Scenario, *, method: str = "auto", time_limit: float = MILP_TIME_LIMIT,
                    tighten: tuple[float, ...] = TIGHTEN, progress: Progress | None = None) -> PlannablePlacement:
    """Place markers so that every task of ``scenario`` has an admissible plan.

    Parameters
    ----------
    scenario : Scenario
        The floor, sensor, robot, routes and tasks (its own markers are ignored).
    method, time_limit
        As for :func:`planner.placement.placement.place`.
    tighten : tuple of float
        Margins ``m`` tried in order; the cover target is ``eps_max (1 - m)``.
    progress : callable, optional
        Told each phase as it starts: each cover and its target, each task planned, each
        tightening of the target (:data:`Progress`).

    Returns
    -------
    PlannablePlacement
        The first layout that plans every task, else the last one tried with the tasks that
        failed.
    """
    eps = scenario.planning.eps_max
    k = scenario.sensor.markers_per_fix
    out = None
    for m in tighten:
        target = eps * (1.0 - m)
        if progress is not None:
            progress(f"cover: target {target * 1e3:.4g} mm")
        result = place(scenario, eps_max=target, method=method, time_limit=time_limit)
        if progress is not None:
            progress(f"cover: {result.count} markers, {len(result.points) - len(result.uncovered)} of "
                     f"{len(result.points)} points covered under {target * 1e3:.4g} mm")
        if not scenario.tasks or len(result.uncovered) or result.count < k:
            return PlannablePlacement(result, target, (), checked=False)
        unplanned, mendable = _unplanned(scenario_with_markers(scenario, result), progress)
        out = PlannablePlacement(dataclasses.replace(result, unplanned=unplanned), target, unplanned, checked=True)
        if not unplanned:
            break
        if not mendable:
            # the body does not clear these routes at any estimate: a tighter cover cannot help
            if progress is not None:
                progress(f"{len(unplanned)} of {len(scenario.tasks)} tasks do not plan ({unplanned[0]}); "
                         "no layout of markers clears the body there, so the target is not tightened")
            break
        if progress is not None and m != tighten[-1]:
            progress(f"{len(unplanned)} of {len(scenario.tasks)} tasks do not plan ({unplanned[0]}); "
                     "tightening the cover target")
    return out
