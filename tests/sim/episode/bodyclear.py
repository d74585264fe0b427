"""Measuring where the simulated robot went against the plan's clearance bounds (tests' helpers)."""

from __future__ import annotations

import numpy as np
import shapely

from planner.plan import Plan
from planner.schedule import clearance
from scenarios.body import body_reach
from scenarios.schema import Scenario


def excess_offset(scenario: Scenario, plan: Plan, xy: np.ndarray, tracking: bool = True) -> np.ndarray:
    """How far each true position lies beyond the plan's offset bound [m], shape (T,): <= 0 inside.

    The bound (:func:`planner.schedule.promise.tracking_bound` plus the certified estimate error,
    as the clearance check takes them: :func:`planner.schedule.clearance.margin`) says the true position lies within
    ``tracking(s) + estimate(s)`` of the path point ``path(s)`` the robot is passing; the robot
    is inside it when some path sample is that close, up to half the samples' spacing (the
    departure from the dock's heading included). With ``tracking`` False the follower's tracking
    and departure bounds are left out (a negative control).
    """
    m = clearance.margin(scenario, plan.path, plan.speed, plan.schedule.s, plan.schedule.predicted_error,
                         scenario.dock(plan.start).pose[2] if tracking else None)
    # the check's samples are a spacing apart: a point on the path lies within half of it of one,
    # which the check adds to what each sample needs (``Margin.sampling``)
    bound = m.estimate + (m.tracking if tracking else 0.0) + m.sampling
    out = np.empty(len(xy))
    for lo in range(0, len(xy), 256):
        p = xy[lo:lo + 256]
        d = np.hypot(p[:, None, 0] - m.points[None, :, 0], p[:, None, 1] - m.points[None, :, 1])
        out[lo:lo + 256] = np.min(d - bound[None, :], axis=1)
    return out


def obstacle_geometry(scenario: Scenario):
    """Return the obstacles' convex pieces and the workspace border as one shapely geometry."""
    pieces = scenario.obstacle_pieces()
    polys = [shapely.Polygon(v[:n]) for v, n in zip(pieces.vertices, pieces.count, strict=True)]
    x0, y0, x1, y1 = scenario.workspace.bounds
    border = shapely.box(x0, y0, x1, y1).exterior
    return shapely.union_all([*polys, border])


def body_clearance(scenario: Scenario, xy: np.ndarray) -> np.ndarray:
    """Gap between the true body and the nearest obstacle at each position [m], shape (T,).

    The body is taken as the disc of its reach (:func:`scenarios.body.body_reach`) around the
    axle midpoint, which contains it whatever its heading: a gap >= 0 means no contact.
    """
    geo = obstacle_geometry(scenario)
    d = shapely.distance(geo, shapely.points(np.asarray(xy, dtype=float)))
    inside = shapely.contains_xy(shapely.union_all(
        [g for g in shapely.get_parts(geo) if isinstance(g, shapely.Polygon)]), xy[:, 0], xy[:, 1])
    return np.where(inside, -d, d) - body_reach(scenario.robot_actual).distance


def footprint_gap(scenario: Scenario, poses: np.ndarray) -> np.ndarray:
    """Distance from the true body's footprint to the nearest obstacle at each pose [m], shape (T,).

    The footprint is the URDF's collision body seen from above (:func:`scenarios.body.robot_geometry`:
    the chassis box, the wheels' contact discs, the casters' discs) at the true pose; 0 where it
    touches or overlaps an obstacle.
    """
    from shapely import affinity

    from scenarios.body import robot_geometry

    spec = scenario.robot_actual
    g = robot_geometry(spec)
    r_w = max(g.left_radius, g.right_radius)
    body = shapely.union_all([
        shapely.box(-g.chassis_length / 2, -g.chassis_width / 2, g.chassis_length / 2, g.chassis_width / 2),
        *(shapely.Point(0.0, sy * spec.wheel_base / 2).buffer(r_w, quad_segs=16) for sy in (1, -1)),
        *(shapely.Point(sx * g.caster_x, 0.0).buffer(g.caster_radius, quad_segs=16) for sx in (1, -1))])
    geo = obstacle_geometry(scenario)
    placed = (affinity.translate(affinity.rotate(body, th, origin=(0, 0), use_radians=True), x, y)
              for x, y, th in np.asarray(poses, dtype=float))
    return np.array([shapely.distance(geo, b) for b in placed])
