"""Does a straight segment keep clear of the obstacles? Geometry by shapely.

A segment is clear of an obstacle when it does not touch the obstacle's area and stays at
least the robot radius away from it (the robot's footprint is a disc of that radius centred
on the path). Every obstacle kind goes through :func:`obstacle_geometry`, so the check holds
for boxes as for any other shape the schema gives a geometry.
"""

from __future__ import annotations

from collections.abc import Sequence

import shapely
from shapely.geometry import LineString

from scenarios.obstacles import Obstacle


def obstacle_geometry(obstacle: Obstacle) -> shapely.Geometry:
    """Return the obstacle's solid region as a shapely geometry [m] (box, circle or polygon).

    A circle is its circumscribed polygon (:meth:`scenarios.obstacles.Obstacle.geometry`), the
    shape the planner and the physics use, so a segment clear here is clear for them.
    """
    return obstacle.geometry()


def segment_conflict(a: Sequence[float], b: Sequence[float], obstacles: Sequence[Obstacle],
                     radius: float, geometries: Sequence[shapely.Geometry] | None = None) -> str:
    """Why the straight segment a-b is not clear of the obstacles, or "" if it is.

    Parameters
    ----------
    a, b : sequence of float, length 2
        End points (x, y) [m].
    obstacles : sequence of Obstacle
        Named in the reason by their index (``obstacles[j]``).
    radius : float
        Robot radius [m]: the segment must stay at least this far from every obstacle.
    geometries : sequence of shapely geometries, optional
        ``obstacle_geometry`` of each obstacle, precomputed for many segments.

    Returns
    -------
    str
        ``"crosses obstacles[j]"`` when the segment touches obstacle j, ``"passes 0.12 m from
        obstacles[j], closer than robot.radius 0.3"`` when it comes closer than ``radius``;
        the first obstacle in file order that fails, "" when none does.
    """
    geoms = geometries if geometries is not None else [obstacle_geometry(o) for o in obstacles]
    line = LineString([tuple(map(float, a)), tuple(map(float, b))]) if tuple(a) != tuple(b) \
        else shapely.Point(float(a[0]), float(a[1]))
    for j, g in enumerate(geoms):
        if line.intersects(g):
            return f"crosses obstacles[{j}]"
        d = line.distance(g)
        # A hair under the radius is floating-point noise of a segment laid out at exactly it.
        if d < radius - 1e-9:
            return f"passes {d:.2f} m from obstacles[{j}], closer than robot.radius {radius:g}"
    return ""
