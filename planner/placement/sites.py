"""Where markers may go and which points they must serve: candidate sites and cover points.

Candidate sites are the scenario's ``placement.candidates`` when given; otherwise points along
the workspace walls (when ``workspace.walls``: a ROS map's border is none) and the obstacle
faces (outer rings and holes' rings), ``placement.spacing`` apart (each edge split into
``ceil(length / spacing)`` equal parts, one site at the middle of each part, so corners, where
line of sight grazes, are avoided; round pillars get
``ceil(perimeter / spacing)`` sites spread over their faces). Sites sit exactly on the faces,
as the built-in markers do; line of sight treats a face point as visible from its open side
(:mod:`planner.pef.visibility`). No site lies in an unknown area or on a face that looks into
one (a wall whose other side the map does not know) or, where the border is no wall, out of
the workspace: probes at :data:`UNKNOWN_PROBES` cells (the map's, else the PEF's) out along
the face's normal must all miss the unknown areas and stay inside the workspace.

Cover points are what placement must keep under ``eps_max`` (``placement.cover``):

- ``routes``: the route network's segments sampled at the PEF resolution (plus a straight
  link from a task dock that is not a network node to its nearest node); without a network,
  the drivable path between each task's docks from :func:`planner.plan.plan_route`, planned as
  if accuracy did not matter (a PEF that is 0 everywhere); without tasks, as ``free``;
- ``free``: the centres of a grid over the free space where the robot fits (clearance to
  walls and obstacles >= robot radius), at the PEF resolution or coarser, so that there are
  at most :data:`MAX_FREE_POINTS` of them.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import shapely

from scenarios.errors import PlanningError
from scenarios.schema import Scenario

MAX_FREE_POINTS = 2000
"""Largest number of free-space cover points; the grid is coarsened to stay under it."""

UNKNOWN_PROBES = (0.5, 1.0, 2.0)
"""Distances, in cells, of the probes out of a site's face that must miss the unknown areas:
traced and simplified separately, an occupied face and the unknown area behind it lie up to a
cell apart or overlap by as much, so one probe at the face could land in either."""


def _edge_sites(a: np.ndarray, b: np.ndarray, spacing: float) -> np.ndarray:
    length = float(np.hypot(*(b - a)))
    if length == 0.0:
        return np.zeros((0, 2))
    n = max(1, math.ceil(length / spacing))
    f = (np.arange(n) + 0.5) / n
    return a + f[:, None] * (b - a)


def candidate_sites(scenario: Scenario, spacing: float | None = None) -> np.ndarray:
    """Candidate marker sites, shape (S, 2) [m] (see module doc).

    Parameters
    ----------
    scenario : Scenario
        Uses ``placement`` (candidates, spacing), the workspace and the obstacles.
    spacing : float, optional
        Distance between sampled sites [m]; default ``scenario.placement.spacing``.
        Ignored when the scenario lists candidates.
    """
    if scenario.placement.candidates:
        return np.array(scenario.placement.candidates, dtype=float).reshape(-1, 2)
    spacing = scenario.placement.spacing if spacing is None else float(spacing)
    if not spacing > 0.0:
        raise PlanningError(f"placement.spacing: expected a positive number of metres, got {spacing}")
    x0, y0, x1, y1 = scenario.workspace.bounds
    rings = [np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])] if scenario.workspace.walls else []
    rings += [ring for ob in scenario.obstacles if ob.kind != "circle" for ring in ob.rings()]  # holes too
    parts = [_edge_sites(r[i], r[(i + 1) % len(r)], spacing) for r in rings for i in range(len(r))]
    parts += [_circle_sites(ob.pieces()[0], spacing) for ob in scenario.obstacles if ob.kind == "circle"]
    sites = np.vstack(parts) if parts else np.zeros((0, 2))
    tol = 1e-9
    ok = (sites[:, 0] >= x0 - tol) & (sites[:, 0] <= x1 + tol) & (sites[:, 1] >= y0 - tol) & (sites[:, 1] <= y1 + tol)
    for ob in scenario.obstacles:
        ok &= ~ob.contains_points(sites, margin=-1e-6)
    sites = np.clip(sites[ok], [x0, y0], [x1, y1])
    _, first = np.unique(np.round(sites, 9), axis=0, return_index=True)
    sites = sites[np.sort(first)]
    if scenario.unknown or not scenario.workspace.walls:
        sites = sites[_facing_known_space(scenario, sites)]
    return sites


def _facing_known_space(scenario: Scenario, sites: np.ndarray) -> np.ndarray:
    """Sites (S, 2) [m] outside the unknown areas whose face looks into the workspace's known space, (S,) bool.

    Where the border is no wall, a face on it (a wall's outer face at a map's edge) looks out of
    the workspace, into what the map does not show: its probes lie outside.
    """
    from planner.placement.facing import face_directions

    cell = scenario.floorplan.resolution if scenario.floorplan is not None and scenario.floorplan.resolution > 0 \
        else scenario.planning.resolution
    facing = face_directions(scenario, sites)
    ang = np.array([np.nan if f is None else f for f in facing], dtype=float)
    normal = np.column_stack([np.cos(ang), np.sin(ang)])
    normal[np.isnan(ang)] = 0.0  # a site on no face: only the site itself is probed
    probes = np.vstack([sites] + [sites + d * cell * normal for d in UNKNOWN_PROBES])
    hit = np.zeros(0, dtype=np.int64)
    if scenario.unknown:
        tree = shapely.STRtree([area.geometry() for area in scenario.unknown])
        hit, _ = tree.query(shapely.points(probes), predicate="intersects")  # boundary counts as in
    x0, y0, x1, y1 = scenario.workspace.bounds
    ok = (probes[:, 0] >= x0) & (probes[:, 0] <= x1) & (probes[:, 1] >= y0) & (probes[:, 1] <= y1)
    ok[hit] = False
    return ok.reshape(len(UNKNOWN_PROBES) + 1, len(sites)).all(axis=0)


def _circle_sites(polygon: np.ndarray, spacing: float) -> np.ndarray:
    """Sites around a circle's polygon: ``ceil(perimeter / spacing)`` face midpoints, evenly spread.

    One site per face (as for straight faces) would crowd a pillar with dozens of sites a few
    centimetres apart; face midpoints are where the polygon touches the circle.
    """
    mids = 0.5 * (polygon + np.roll(polygon, -1, axis=0))
    perimeter = float(np.hypot(*np.diff(np.vstack([polygon, polygon[:1]]), axis=0).T).sum())
    n = min(len(mids), max(1, math.ceil(perimeter / spacing)))
    return mids[np.unique(np.floor(np.arange(n) * len(mids) / n).astype(int))]


def _sample_segment(a: np.ndarray, b: np.ndarray, step: float) -> np.ndarray:
    n = max(1, math.ceil(float(np.hypot(*(b - a))) / step))
    return a + (np.arange(n + 1) / n)[:, None] * (b - a)


def free_points(scenario: Scenario, spacing: float | None = None) -> np.ndarray:
    """Grid centres in free space where the robot fits, shape (N, 2) [m], N <= MAX_FREE_POINTS.

    Parameters
    ----------
    scenario : Scenario
    spacing : float, optional
        Grid step [m]; default the PEF resolution, coarsened to keep N <= MAX_FREE_POINTS.
    """
    from planner.routes.criteria import clearance

    w, h = scenario.workspace.size
    x0, y0 = scenario.workspace.origin
    step = scenario.planning.resolution if spacing is None else float(spacing)
    while True:
        nx, ny = max(1, round(w / step)), max(1, round(h / step))
        x, y = x0 + (np.arange(nx) + 0.5) * w / nx, y0 + (np.arange(ny) + 0.5) * h / ny
        pts = np.column_stack([np.tile(x, ny), np.repeat(y, nx)])
        pts = pts[clearance(pts, scenario) >= scenario.robot.radius]
        if len(pts) <= MAX_FREE_POINTS or spacing is not None:
            return pts
        step *= math.sqrt(len(pts) / MAX_FREE_POINTS) * 1.01


class _FlatPEF:
    """A PEF that is 0 everywhere: plans the drivable route regardless of accuracy."""

    def __init__(self, scenario: Scenario):
        self.scenario = scenario

    def at(self, points, widen=0.0):
        p = np.asarray(points, dtype=float).reshape(-1, 2)
        return SimpleNamespace(tau=np.zeros(len(p)), best=np.zeros((len(p), 0), dtype=int))

    def stretch_bound(self, points, widen, target=np.inf):
        return np.zeros(len(np.asarray(points, dtype=float).reshape(-1, 2)))

    def grid(self, resolution=None):
        from planner.pef.result import grid_centres

        res = self.scenario.planning.resolution if resolution is None else resolution
        x, y = grid_centres(self.scenario.workspace.size, res, self.scenario.workspace.origin)
        size = self.scenario.workspace.size
        return SimpleNamespace(x=x, y=y, tau=np.zeros((y.size, x.size)), free=np.ones((y.size, x.size), bool),
                               cell_size=(size[0] / x.size, size[1] / y.size))


def route_points(scenario: Scenario, step: float | None = None) -> np.ndarray:
    """Points along the routes the robot drives, shape (N, 2) [m] (see module doc).

    Parameters
    ----------
    scenario : Scenario
    step : float, optional
        Sampling step along the routes [m]; default the PEF resolution.
    """
    step = scenario.planning.resolution if step is None else float(step)
    parts = []
    if scenario.routes is not None:
        nodes = {k: np.asarray(v, dtype=float) for k, v in scenario.routes.nodes.items()}
        # segments that may not be driven (imported edges too close to obstacles) need no cover
        parts += [_sample_segment(nodes[a], nodes[b], step) for i, (a, b) in enumerate(scenario.routes.segments)
                  if not scenario.routes.why_not(i)]
        used = {name for t in scenario.tasks for name in (t.start, t.goal)}
        for name in sorted(n for n in used - set(nodes) if scenario.dock(n).node is None):
            p = np.asarray(scenario.dock(name).position, dtype=float)
            nearest = min(nodes.values(), key=lambda q: float(np.hypot(*(q - p))))
            parts.append(_sample_segment(p, nearest, step))
    elif scenario.tasks:
        try:
            from planner.plan import plan_route
        except ImportError:
            return free_points(scenario)
        flat = _FlatPEF(scenario)
        for t in scenario.tasks:
            plan = plan_route(scenario, t.start, t.goal, free=True, pef=flat, schedule=False)
            path = np.asarray(plan.path, dtype=float)
            parts += [_sample_segment(path[i], path[i + 1], step) for i in range(len(path) - 1)]
    else:
        return free_points(scenario)
    pts = np.vstack(parts)
    _, first = np.unique(np.round(pts, 9), axis=0, return_index=True)
    return pts[np.sort(first)]


def cover_points(scenario: Scenario) -> np.ndarray:
    """Return the points placement must cover (``scenario.placement.cover``), shape (N, 2) [m]."""
    if scenario.placement.cover == "free":
        return free_points(scenario)
    return route_points(scenario)
