"""Plans around concave polygons, rings and pillars keep the robot's clearance."""

from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry import LineString
from shapely.ops import unary_union

from planner.plan import plan_route
from planner.routes.criteria import clearance
from tests.scenarios.worlds import hall


def test_the_route_climbs_out_of_the_cup_with_the_robot_radius_clear():
    sc = hall()
    solid = unary_union([ob.geometry() for ob in sc.obstacles])
    a, b = sc.dock("A").position, sc.dock("B").position
    assert LineString([a, b]).intersects(solid)           # the direct way is blocked
    p = plan_route(sc, "A", "B", free=True, schedule=False)
    path = np.asarray(p.path)
    dist = shapely.distance(solid, shapely.points(path))
    assert dist.min() >= sc.robot.radius - 1e-9
    assert path[:, 1].max() > 10.0 + sc.robot.radius      # over the top of an arm
    assert not LineString(path).intersects(solid.buffer(sc.robot.radius - 0.01))
    # The planner's own clearance agrees with shapely's distance (outside the obstacles).
    walls = np.minimum.reduce([path[:, 0], 20 - path[:, 0], path[:, 1], 14 - path[:, 1]])
    assert np.allclose(clearance(path, sc), np.minimum(dist, walls), atol=1e-9)
    c = p.candidates[p.chosen]
    assert c.admissible and c.min_clearance >= sc.robot.radius
