"""Candidate routes between two docks: generation, smoothing and scoring.

Network candidates come from :mod:`planner.routes.network` (every simple path, or Yen's k
shortest); free-space candidates from :mod:`planner.routes.gridsearch` (diverse A* routes on the
PEF grid, then line-of-sight shortcutting). Each becomes a drivable path
(:mod:`planner.routes.smoothing`) scored at the PEF resolution (:mod:`planner.routes.criteria`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from planner.routes import criteria, gridsearch, network, smoothing
from planner.routes.criteria import RouteScore
from scenarios.errors import PlanningError
from scenarios.schema import Scenario

TauFn = Callable[[np.ndarray], np.ndarray]


@dataclass
class Candidate:
    """One candidate route and its criteria.

    Attributes
    ----------
    id : str
        ``R1, R2, ...`` for network routes, ``F1, ...`` for free-space ones.
    nodes : tuple of str or None
        Network nodes visited (None for free-space routes).
    polyline : ndarray, shape (n, 2)
        The route's vertices before corner rounding [m].
    length, time, max_tau, mean_tau, traffic, min_clearance, turning : float
        Criteria of the drivable path, see :class:`planner.routes.criteria.RouteScore`.
    admissible : bool
    pareto : bool
        Non-dominated among the admissible candidates over the five criteria.
    score : float
        Weighted normalised score (lower is better); NaN if inadmissible.
    why_not : str
        Why the candidate is inadmissible ("" if admissible).
    origin : str
        How it was found (``all simple paths``, ``w=1``, ...).
    path : SmoothPath
        The drivable path sampled at the PEF resolution.
    speed : ndarray, shape (N,)
        Reference speed along ``path`` [m/s]; with the schedule's slow-downs for fixes once
        the candidate has a schedule.
    slowdown : float
        Time the schedule's slow-downs for fixes add [s], included in ``time``; NaN until the
        candidate has a schedule (only the chosen one gets one).
    """

    id: str
    nodes: tuple[str, ...] | None
    polyline: np.ndarray
    length: float
    time: float
    max_tau: float
    mean_tau: float
    traffic: float
    min_clearance: float
    turning: float
    admissible: bool
    pareto: bool
    score: float
    why_not: str
    origin: str
    worst_point: tuple[float, float]
    path: smoothing.SmoothPath = field(repr=False)
    speed: np.ndarray = field(repr=False)
    slowdown: float = math.nan

    def vector(self) -> np.ndarray:
        """Criteria in :data:`planner.routes.criteria.CRITERIA` order, shape (5,)."""
        return np.array([self.max_tau, self.time, self.traffic, -self.min_clearance, self.turning])


# ------------------------------------------------------------------------------ scoring


def admissible_fn(scenario: Scenario, tau_fn: TauFn) -> Callable[[np.ndarray], np.ndarray]:
    """``ok(points (N,2)) -> (N,) bool``: τ < ε_max and clearance ≥ robot radius."""
    eps, radius = scenario.planning.eps_max, scenario.robot.radius

    def ok(points: np.ndarray) -> np.ndarray:
        p = np.asarray(points, float).reshape(-1, 2)
        good = criteria.clearance(p, scenario) >= radius
        if good.any():
            tau = np.full(len(p), np.inf)
            tau[good] = tau_fn(p[good])
            good &= tau < eps
        return good
    return ok


def score_path(scenario: Scenario, polyline: np.ndarray, path: smoothing.SmoothPath, tau: np.ndarray,
               segment_traffic: Sequence[float] | None = None) -> tuple[RouteScore, np.ndarray]:
    """Criteria of a drivable path and its speed profile.

    Parameters
    ----------
    scenario : Scenario
    polyline : ndarray, shape (n, 2)
        The route's vertices (for traffic and turning) [m].
    path : SmoothPath
        The drivable path, N samples at the PEF resolution.
    tau : ndarray, shape (N,)
        τ at ``path.points`` [m].
    segment_traffic : sequence of float, length n - 1, optional
        Traffic density of each polyline segment.

    Returns
    -------
    RouteScore
    speed : ndarray, shape (N,)
        [m/s]
    """
    tau = np.asarray(tau, float)
    speed = smoothing.speed_profile(path, scenario.robot)
    time, n_fix, n_stop = criteria.travel_time(path.s, speed, tau, scenario, path.turn_in_place)
    worst = int(np.argmax(np.where(np.isnan(tau), np.inf, tau)))
    length = path.length
    if np.all(np.isfinite(tau)) and length > 0:
        mean_tau = float(np.sum(np.diff(path.s) * 0.5 * (tau[1:] + tau[:-1])) / length)
    else:
        mean_tau = float(np.mean(tau))
    score = RouteScore(
        length=length, time=time, max_tau=float(tau[worst]), mean_tau=mean_tau,
        worst_point=(float(path.points[worst, 0]), float(path.points[worst, 1])),
        traffic=criteria.traffic_density(polyline, segment_traffic),
        min_clearance=float(criteria.clearance(path.points, scenario).min()),
        turning=criteria.turning(polyline), n_fixes=n_fix, n_stops=n_stop)
    return score, speed


@dataclass(frozen=True)
class RouteSpec:
    """A route to be smoothed and scored.

    Attributes
    ----------
    id : str
    variants : sequence of ndarray, each shape (n, 2)
        Polylines from most to least smoothed (e.g. shortcut grid path, raw grid path).
    nodes : tuple of str or None
    segment_traffic : sequence of float or None
        Traffic of each segment of the (single) variant.
    origin : str
    """

    id: str
    variants: Sequence[np.ndarray]
    nodes: tuple[str, ...] | None = None
    segment_traffic: Sequence[float] | None = None
    origin: str = ""


def make_candidates(scenario: Scenario, specs: Sequence[RouteSpec], tau_fn: TauFn,
                    ok: Callable[[np.ndarray], np.ndarray] | None = None) -> list[Candidate]:
    """Smooth and score routes, falling back to less smoothing when needed.

    Each route's variants are tried in order: the polyline is corner-rounded (arcs only where
    admissible, see :func:`planner.routes.smoothing.round_corners_many`) and scored; the first
    admissible variant is kept, else the last one, scored as inadmissible. All routes of one
    round share one PEF evaluation.

    Parameters
    ----------
    scenario : Scenario
    specs : sequence of RouteSpec
    tau_fn : callable
        ``tau_fn(points (N,2)) -> (N,)`` [m].
    ok : callable, optional
        Admissibility of points; default :func:`admissible_fn`.

    Returns
    -------
    list of Candidate
        In the order of ``specs``.
    """
    ok = ok or admissible_fn(scenario, tau_fn)
    res = scenario.planning.resolution
    r_min = smoothing.min_turn_radius(scenario.robot)
    r_pref = max(smoothing.cruise_turn_radius(scenario.robot), r_min)
    eps, radius = scenario.planning.eps_max, scenario.robot.radius
    out: dict[int, Candidate] = {}
    todo = list(range(len(specs)))
    level = 0
    while todo:
        polys = [specs[i].variants[level] for i in todo]
        paths = smoothing.round_corners_many(polys, ok, r_pref, r_min, res)
        sizes = np.cumsum([len(p.points) for p in paths])[:-1]
        taus = np.split(tau_fn(np.vstack([p.points for p in paths])), sizes)
        nxt = []
        for i, poly, path, tau in zip(todo, polys, paths, taus, strict=True):
            spec = specs[i]
            score, speed = score_path(scenario, poly, path, tau, spec.segment_traffic)
            why = score.why_inadmissible(eps, radius)
            if why and level + 1 < len(spec.variants):
                nxt.append(i)
                continue
            out[i] = Candidate(
                id=spec.id, nodes=spec.nodes, polyline=smoothing.clean_polyline(poly), length=score.length,
                time=score.time, max_tau=score.max_tau, mean_tau=score.mean_tau, traffic=score.traffic,
                min_clearance=score.min_clearance, turning=score.turning, admissible=not why,
                pareto=False, score=math.nan, why_not=why, origin=spec.origin,
                worst_point=score.worst_point, path=path, speed=speed)
        todo, level = nxt, level + 1
    return [out[i] for i in range(len(specs))]


# ----------------------------------------------------------------------------- candidates


def network_candidates(scenario: Scenario, start: str, goal: str, tau_fn: TauFn) -> list[Candidate]:
    """Scored candidate routes through the scenario's route network."""
    g = network.build_graph(scenario.routes)
    radius, res = scenario.robot.radius, scenario.planning.resolution
    clear = lambda pts: criteria.clearance(pts, scenario) >= radius
    ends = []
    for name in (start, goal):
        dock = scenario.dock(name)
        if dock.node is not None:  # the dock sits on a node: routes start there
            ends.append(dock.node)
            continue
        on = [n for n, p in g.pos.items() if math.dist(p, dock.position) < 1e-9]
        if name not in g.pos and on:  # a pose dock placed exactly on a node (an imported graph's)
            ends.append(on[0])
            continue
        network.attach(g, name, dock.position, lambda a, b: smoothing.segment_ok(a, b, clear, res / 2))
        ends.append(name)
    if ends[0] == ends[1]:
        raise PlanningError(f"docks {start!r} and {goal!r} sit on the same node {ends[0]!r}")
    routes, method = network.candidate_routes(g, ends[0], ends[1], names=(start, goal))
    specs = [RouteSpec(f"R{i + 1}", [g.polyline(r)], tuple(r), g.segment_traffic(r), method)
             for i, r in enumerate(routes)]
    return make_candidates(scenario, specs, tau_fn)


def free_candidates(scenario: Scenario, start: str, goal: str, pef, tau_fn: TauFn,
                    n_routes: int = 4) -> list[Candidate]:
    """Scored free-space candidate routes from grid search on the PEF map.

    Free-space routes carry no traffic data (traffic 0), even when the scenario has a
    route network with traffic densities.
    """
    pm = pef.grid(scenario.planning.resolution)
    grid = gridsearch.Grid(np.asarray(pm.x), np.asarray(pm.y))
    h = math.hypot(grid.hx, grid.hy)
    eps, radius = scenario.planning.eps_max, scenario.robot.radius
    clear = criteria.clearance(grid.centres().reshape(-1, 2), scenario).reshape(grid.shape)
    # A cell is safe when every point of it is: its centre's clearance minus the half diagonal.
    safe = clear - h / 2 >= radius
    tau_c = gridsearch.conservative_tau(np.asarray(pm.tau, float))
    allowed = safe & (tau_c < eps)
    cells = []
    for name in (start, goal):
        p = np.asarray(scenario.dock(name).position, float)
        cells.append(_dock_cell(grid, allowed, p, name, scenario, tau_fn))
    # Routes that leave room for the estimate's error (under eps_max) beside the body first: the
    # plan keeps radius + tracking + estimate clear (planner.schedule.clearance), so a route
    # hugging the radius is refused on a straight. The docks may stand closer: cells near them
    # need the radius only; where no roomy route exists, the radius alone everywhere.
    centres = grid.centres()
    near_dock = np.zeros(grid.shape, bool)
    for name in (start, goal):
        d = np.hypot(*(centres - np.asarray(scenario.dock(name).position, float)).transpose(2, 0, 1))
        near_dock |= d <= radius + eps + 2.0 * h
    mask = allowed & ((clear - h / 2 >= radius + eps) | near_dock)
    found = gridsearch.alternatives(grid, tau_c, mask, eps, cells[0], cells[1],
                                    scenario.planning.weights.accuracy, n_routes)
    if not found:
        mask = allowed
        found = gridsearch.alternatives(grid, tau_c, mask, eps, cells[0], cells[1],
                                        scenario.planning.weights.accuracy, n_routes)
    if not found:
        raise _free_infeasible(scenario, start, goal, grid, safe, tau_c, cells, tau_fn)
    grid_ok = lambda pts: grid.lookup(mask, pts)
    specs = []
    a, b = np.asarray(scenario.dock(start).position), np.asarray(scenario.dock(goal).position)
    for i, (label, gp) in enumerate(found):
        raw = np.vstack([a, gp.points, b])
        short = smoothing.shortcut(raw, grid_ok, min(grid.hx, grid.hy) / 2)
        specs.append(RouteSpec(f"F{i + 1}", [short, raw], origin=label))
    cands = _distinct(make_candidates(scenario, specs, tau_fn), scenario.planning.resolution)
    for i, c in enumerate(cands):
        c.id = f"F{i + 1}"
    return cands


def _distinct(cands: list[Candidate], tol: float) -> list[Candidate]:
    """Drop candidates whose path lies within ``tol`` [m] of an earlier one's, and vice versa."""
    from scipy.spatial import cKDTree

    kept: list[Candidate] = []
    for c in cands:
        pc = c.path.points
        same = False
        for k in kept:
            pk = k.path.points
            gap = max(cKDTree(pk).query(pc)[0].max(), cKDTree(pc).query(pk)[0].max())
            if gap < tol:
                same = True
                break
        if not same:
            kept.append(c)
    return kept


def _dock_cell(grid, allowed, p, name, scenario, tau_fn) -> tuple[int, int]:
    """Find the allowed cell nearest a dock (within two cells), or raise PlanningError saying why not."""
    r, c, _ = grid.cell_of(p[None])
    r, c = int(r[0]), int(c[0])
    best = None
    for dr in range(-2, 3):
        for dc in range(-2, 3):
            rr, cc = r + dr, c + dc
            if 0 <= rr < grid.shape[0] and 0 <= cc < grid.shape[1] and allowed[rr, cc]:
                d = math.hypot(grid.x[cc] - p[0], grid.y[rr] - p[1])
                if best is None or d < best[0]:
                    best = (d, (rr, cc))
    if best is None:
        tau = float(tau_fn(p[None])[0])
        cl = float(criteria.clearance(p[None], scenario)[0])
        raise PlanningError(
            f"dock {name!r} at ({p[0]:g}, {p[1]:g}) is outside the navigation region: tau {tau:.4g} m "
            f"(eps_max {scenario.planning.eps_max:g} m), clearance {cl:.3f} m "
            f"(robot radius {scenario.robot.radius:g} m)")
    return best[1]


def _free_infeasible(scenario, start, goal, grid, safe, tau_c, cells, tau_fn) -> PlanningError:
    """Build the 'no free-space route' error: the best route ignoring τ, and where it fails."""
    eps = scenario.planning.eps_max
    open_cost = gridsearch.cell_cost(np.minimum(np.where(safe, tau_c, 0.0), 10 * eps), eps, 1.0)
    gp = gridsearch.grid_astar(grid, open_cost, safe, cells[0], cells[1])
    if gp is None:
        return PlanningError(f"unreachable dock: obstacles separate docks {start!r} and {goal!r}")
    tau = np.asarray(tau_fn(gp.points), float)
    i = int(np.argmax(np.where(np.isnan(tau), np.inf, tau)))
    x, y = gp.points[i]
    return PlanningError(
        f"no admissible route from {start!r} to {goal!r}: the navigation region tau < eps_max = {eps:g} m "
        f"does not connect them; the best route leaving it reaches tau {tau[i]:.4g} m at ({x:.2f}, {y:.2f})")
