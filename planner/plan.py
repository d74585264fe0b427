"""Route planning between two docks: candidates, criteria, choice, smooth path, schedule.

:func:`plan_route` gathers candidate routes (through the scenario's route network, or by
free-space grid search; :mod:`planner.routes.candidates`), each turned into a drivable path and
scored at the PEF resolution, ranks the admissible ones (:mod:`planner.routes.criteria`),
re-checks the best's clearance at a quarter of the resolution and gives it a measurement schedule
(:mod:`planner.schedule.schedule`); a candidate that fails either is marked inadmissible and the
next one is taken. τ along a path is the one admissibility's
(:func:`planner.routes.admissible.tau_along`: each sample stands for its stretch), the same as
``place``, ``export`` and ``watch`` judge a path by.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.routes import criteria
from planner.routes.admissible import tau_along
from planner.routes.candidates import Candidate, free_candidates, network_candidates
from planner.routes.ranking import Ranking, rank
from planner.schedule import clearance
from planner.schedule.schedule import Schedule
from scenarios.errors import PlanningError
from scenarios.jsonable import json_number
from scenarios.schema import Scenario

# The chosen path is re-checked at this fraction of the PEF resolution.
FINE_FRACTION = 0.25


@dataclass
class Plan:
    """A planned route between two docks.

    Attributes
    ----------
    start, goal : str
        Dock names.
    eps_max : float
        Allowed error [m].
    candidates : list of Candidate
    chosen : int or None
        Index into ``candidates``.
    reason : str
        Why the chosen route won.
    path : ndarray, shape (N, 2)
        Smoothed reference path, samples at most the PEF resolution apart [m].
    s : ndarray, shape (N,)
        Arc length [m].
    speed : ndarray, shape (N,)
        Reference speed [m/s]: slower on arcs, 0 at sharp-corner stops and at the goal.
    schedule : planner.schedule.schedule.Schedule
        Where to take fixes and with which markers.
    """

    start: str
    goal: str
    eps_max: float
    candidates: list[Candidate]
    chosen: int | None
    reason: str
    path: np.ndarray
    s: np.ndarray
    speed: np.ndarray
    schedule: Schedule | None

    def to_dict(self, scenario: Scenario) -> dict:
        """Return the plan as a JSON-ready dict (what ``pefsim plan --json`` prints).

        Parameters
        ----------
        scenario : Scenario
            The scenario planned on: its name, and its marker ids for the schedule's fixes.

        Returns
        -------
        dict
            ``scenario``, ``start``, ``goal``, ``eps_max`` [m], ``candidates`` (each with its
            criteria; inf as null), ``chosen`` (id) and ``chosen_index``, ``reason``, ``path``
            [[x, y]] [m] and ``schedule`` (each fix with its markers' ids and promise [m]).
        """
        cands = [{
            "id": c.id, "nodes": list(c.nodes) if c.nodes is not None else None,
            "length": json_number(c.length), "time": json_number(c.time), "max_tau": json_number(c.max_tau),
            "mean_tau": json_number(c.mean_tau), "traffic": json_number(c.traffic),
            "min_clearance": json_number(c.min_clearance),
            "turning": json_number(c.turning), "slowdown": json_number(c.slowdown), "admissible": c.admissible,
            "pareto": c.pareto,
            "score": json_number(c.score), "why_not": c.why_not or None} for c in self.candidates]
        ids = scenario.marker_ids()
        fixes = [] if self.schedule is None else [
            {"x": f.position[0], "y": f.position[1], "s": f.s, "markers": [ids[i] for i in f.markers],
             "tau": json_number(f.tau), "predicted_tau": json_number(f.predicted_tau), "speed": f.speed,
             "slowed": f.slowed, "switch": f.switch} for f in self.schedule.fixes]
        return {
            "scenario": scenario.name, "start": self.start, "goal": self.goal, "eps_max": self.eps_max,
            "candidates": cands,
            "chosen": self.candidates[self.chosen].id if self.chosen is not None else None,
            "chosen_index": self.chosen, "reason": self.reason,
            "path": [[float(x), float(y)] for x, y in self.path],
            "schedule": fixes,
        }


# ------------------------------------------------------------------------------- choosing


def _rank(scenario: Scenario, cands: list[Candidate]) -> Ranking:
    values = np.array([c.vector() for c in cands]).reshape(-1, len(criteria.CRITERIA))
    adm = np.array([c.admissible for c in cands], bool)
    ranking = rank(values, adm, scenario.planning.weights, scenario.planning.order)
    for c, sc, p in zip(cands, ranking.scores, ranking.pareto, strict=True):
        c.score, c.pareto = float(sc), bool(p)
    return ranking


def _reason(scenario: Scenario, cands: list[Candidate], ranking: Ranking, chosen: int,
            dropped: list[str]) -> str:
    c = cands[chosen]
    n = int(sum(x.admissible for x in cands))
    w = scenario.planning.weights
    if ranking.lexicographic:
        why = f"first in lexicographic order {' > '.join(ranking.lexicographic)} among {n} admissible"
    else:
        ws = ", ".join(f"{k} {getattr(w, k):g}" for k in criteria.CRITERIA)
        why = f"lowest weighted score {c.score:.3f} among {n} admissible (weights {ws})"
    tail = "; on the Pareto front" if c.pareto else ""
    if dropped:
        tail += "; skipped " + ", ".join(dropped)
    return (f"{c.id}: {why} — max tau {c.max_tau * 1000:.2f} mm, {c.time:.1f} s, "
            f"traffic {c.traffic:.2f}, clearance {c.min_clearance:.2f} m, turning {c.turning:.2f} rad{tail}")


def _fine_check(scenario: Scenario, cand: Candidate, pef) -> str:
    """Re-check a path's clearance at a quarter of the resolution; the reason it fails or ''.

    τ needs no re-check: each sample of the path was judged by the bound of τ over the whole
    stretch it stands for (:func:`planner.routes.admissible.tau_along`), as ``export`` judges it.
    """
    pts, _ = criteria.sample_polyline(np.asarray(cand.path.points, dtype=float),
                                      scenario.planning.resolution * FINE_FRACTION)
    cl = float(criteria.clearance(pts, scenario).min())
    if cl < scenario.robot.radius:
        cand.min_clearance = min(cand.min_clearance, cl)
        return f"clearance {cl:.3f} m < robot radius {scenario.robot.radius:g} m on fine re-check"
    return ""


def route_tau(scenario: Scenario, pef):
    """Return ``tau_fn(points (N, 2)) -> (N,)`` [m] by which ``plan`` judges its candidate paths.

    The one admissibility (:func:`planner.routes.admissible.tau_along`) at ``planning.resolution``
    (candidate paths are sampled at most that far apart, :mod:`planner.routes.smoothing`) against
    ``planning.eps_max``.
    """
    return lambda p: tau_along(pef, p, scenario.planning.resolution, scenario.planning.eps_max)


class NoRouteError(PlanningError):
    """No candidate route is admissible.

    Parameters
    ----------
    message : str
        Names the best candidate and why it fails.
    markers_help : bool
        False when every candidate failed on the body's clearance in a way no layout of markers
        mends (:class:`planner.schedule.clearance.ClearanceError`): ``place`` need not try others.
    """

    def __init__(self, message: str, markers_help: bool = True):
        super().__init__(message)
        self.markers_help = markers_help


def _no_route(scenario: Scenario, start: str, goal: str, cands: list[Candidate],
              unmendable: set[str] = frozenset()) -> NoRouteError:
    best = min(cands, key=lambda c: (c.max_tau, -c.min_clearance))
    return NoRouteError(f"no admissible route from {start!r} to {goal!r} among {len(cands)} candidates "
                        f"(eps_max {scenario.planning.eps_max:g} m); best {best.id}: {best.why_not}",
                        markers_help=not all(c.id in unmendable for c in cands))


def _make_schedule(scenario: Scenario, pef, cand: Candidate, start: str, goal: str) -> tuple[Schedule, str, bool]:
    """Schedule the candidate at speeds whose tracking keeps the body clear; or say why not (names the place).

    The third value says whether a layout of markers could mend a refusal
    (:attr:`planner.schedule.clearance.ClearanceError.markers_help`).
    """
    try:
        return clearance.cleared_schedule(scenario, pef, cand.path.points, cand.speed, start, goal), "", True
    except clearance.ClearanceError as exc:
        return None, str(exc), exc.markers_help


def plan_route(scenario: Scenario, start: str, goal: str, free: bool | None = None, pef=None,
               schedule: bool = True) -> Plan:
    """Plan a route from dock ``start`` to dock ``goal``.

    Parameters
    ----------
    scenario : Scenario
    start, goal : str
        Dock names.
    free : bool, optional
        Free-space grid search (True) or the route network (False); default the network
        when the scenario has one.
    pef : planner.pef.map.PEF, optional
        The PEF to plan with (anything with ``at`` and ``grid``); default ``PEF(scenario)``.
    schedule : bool
        Compute the chosen route's measurement schedule (needs a real PEF).

    Returns
    -------
    Plan

    Raises
    ------
    PlanningError
        Unknown or unreachable dock, or no admissible route (names the best candidate's worst
        point and τ there).
    """
    names = [d.name for d in scenario.docks]
    for name in (start, goal):
        if name not in names:
            raise PlanningError(f"unknown dock {name!r} (docks: {', '.join(names) or 'none'})")
    if start == goal:
        raise PlanningError(f"start and goal are the same dock {start!r}")
    from planner.pef.map import PEF

    k = scenario.sensor.markers_per_fix
    if len(scenario.markers) < k and (pef is None or isinstance(pef, PEF)):  # placement's flat PEF needs none
        raise PlanningError(f"no admissible route from {start!r} to {goal!r}: the scenario has "
                            f"{len(scenario.markers)} markers and a fix needs {k}, so tau is inf everywhere "
                            "(pefsim place finds where to put reflectors)")
    if pef is None:
        pef = PEF(scenario)
    tau_fn = route_tau(scenario, pef)
    use_free = scenario.routes is None if free is None else free
    if not use_free and scenario.routes is None:
        raise PlanningError(f"scenario {scenario.name!r} has no route network: plan in free space")
    if use_free:
        cands = free_candidates(scenario, start, goal, pef, tau_fn)
    else:
        cands = network_candidates(scenario, start, goal, tau_fn)
    dropped: list[str] = []
    unmendable: set[str] = set()
    while True:
        ranking = _rank(scenario, cands)
        if not ranking.order:
            raise _no_route(scenario, start, goal, cands, unmendable)
        chosen = ranking.order[0]
        cand = cands[chosen]
        why = _fine_check(scenario, cand, pef)
        sched = None
        if not why and schedule:
            try:
                sched, why, mendable = _make_schedule(scenario, pef, cand, start, goal)
                if not mendable:
                    unmendable.add(cand.id)
            except PlanningError as exc:
                why = f"no measurement schedule ({exc})"
            if not why:
                # the slow-downs for fixes are part of the drive
                cand.slowdown = sched.slowdown_time
                cand.time += sched.slowdown_time
                cand.speed = sched.speed
        if not why:
            break
        cand.admissible, cand.why_not = False, why
        dropped.append(f"{cand.id} ({why})")
    return Plan(start=start, goal=goal, eps_max=scenario.planning.eps_max, candidates=cands,
                chosen=chosen, reason=_reason(scenario, cands, ranking, chosen, dropped),
                path=cand.path.points, s=cand.path.s, speed=cand.speed, schedule=sched)


def plan_task(scenario: Scenario, task_index: int, free: bool | None = None, pef=None) -> Plan:
    """Plan the scenario's task number ``task_index`` (0-based); see :func:`plan_route`."""
    from scenarios.tasks import check_task

    t = scenario.tasks[check_task(scenario, task_index)]
    return plan_route(scenario, t.start, t.goal, free=free, pef=pef)


