"""Plans around concave polygons, rings and pillars keep the robot's clearance."""

from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry import LineString
from shapely.ops import unary_union

import scenarios
from planner.plan import plan_route
from planner.routes.criteria import clearance

# A 20 x 14 m hall; dock A sits in the cup of a U that opens upwards, dock B below the U:
# the straight line runs through the U's bottom bar, the route must climb out of the cup.
HALL = """
name = "cup"
[workspace]
size = [20.0, 14.0]
[[obstacles]]
polygon = [[6, 3], [14, 3], [14, 10], [12.5, 10], [12.5, 4.5], [7.5, 4.5], [7.5, 10], [6, 10]]
[[obstacles]]
center = [3.0, 11.5]
radius = 0.6
[[obstacles]]
polygon = [[15.5, 11], [19, 11], [19, 13.5], [15.5, 13.5]]
holes = [[[16.5, 11.8], [18, 11.8], [18, 12.7], [16.5, 12.7]]]
{markers}
[sensor]
relative_error = 1e-4
absolute_error = 0.001
max_range = 40.0
[robot]
radius = 0.4
[planning]
eps_max = 0.05
resolution = 0.1
[[docks]]
name = "A"
pose = [10.0, 7.0, 90.0]
[[docks]]
name = "B"
pose = [10.0, 1.2, 0.0]
[[tasks]]
from = "A"
to = "B"
"""
MARKERS = [(0, 2), (0, 7), (0, 12), (20, 2), (20, 7), (20, 12), (4, 0), (10, 0), (16, 0), (5, 14), (10, 14),
           (14, 14), (10, 4.5), (7.5, 8), (12.5, 8), (6, 6), (14, 6)]


def hall():
    text = "".join(f'[[markers]]\nid = "M{i}"\nposition = [{float(x)}, {float(y)}]\n'
                   for i, (x, y) in enumerate(MARKERS))
    return scenarios.loads(HALL.format(markers=text), "cup.toml")


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
