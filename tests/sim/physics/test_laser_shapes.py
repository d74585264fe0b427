"""The PyBullet laser sees polygon, ring and circle obstacles as the planner's visibility does."""

from __future__ import annotations

import math

import numpy as np
import shapely
from shapely.geometry import LineString, Point
from shapely.ops import unary_union

import scenarios
from planner.pef.visibility import scenario_visible_points, visible_points
from sim.physics.laser import LaserSensor
from sim.physics.world import PhysicsWorld

# 16 x 10 m: a concave U, a ring whose hole is a 3 x 3 m room, a round pillar; markers on the
# walls, on the U's inner and outer faces, on the ring's outer face and on its hole's face.
SHAPES = """
name = "shapes"
[workspace]
size = [16.0, 10.0]
origin = [{x0}, {y0}]
{obstacles}
{markers}
[sensor]
relative_error = 1.0e-3
absolute_error = 1.0e-3
max_range = 30.0
[planning]
eps_max = 0.05
"""
MARKERS = [(4.0, 3.0), (5.0, 5.0), (6.0, 4.0), (10.5, 3.0), (12.0, 5.5), (10.5, 7.0), (0.0, 5.0),
           (16.0, 9.0), (14.5, 1.9)]
TOL = 5e-3  # Bullet's collision margin on meshes: rays within this of an edge are not judged


U_SHAPE = [(2, 2), (6, 2), (6, 6), (5, 6), (5, 3), (3, 3), (3, 6), (2, 6)]
RING = [(8, 3), (13, 3), (13, 8), (8, 8)]
HOLE = [(9, 4), (12, 4), (12, 7), (9, 7)]


def shapes(x0: float = 0.0, y0: float = 0.0):
    """Build the scenario with everything shifted by the workspace origin (x0, y0) [m]."""
    def ring(r):
        return "[" + ", ".join(f"[{x + x0}, {y + y0}]" for x, y in r) + "]"
    obstacles = (f"[[obstacles]]\npolygon = {ring(U_SHAPE)}\n[[obstacles]]\npolygon = {ring(RING)}\n"
                 f"holes = [{ring(HOLE)}]\n[[obstacles]]\ncenter = [{14.5 + x0}, {1.5 + y0}]\nradius = 0.4\n")
    marks = "".join(f'[[markers]]\nid = "M{i}"\nposition = [{x + x0}, {y + y0}]\n' for i, (x, y) in enumerate(MARKERS))
    return scenarios.loads(SHAPES.format(x0=x0, y0=y0, obstacles=obstacles, markers=marks))


def _ambiguous(sc, p, markers, post_r) -> bool:
    solid = unary_union([ob.geometry() for ob in sc.obstacles])
    inner, outer = solid.buffer(-TOL), solid.buffer(TOL)
    for i, m in enumerate(markers):
        seg = LineString([p, m])
        if any(abs(seg.distance(Point(o)) - post_r) < 2e-3 for j, o in enumerate(markers) if j != i):
            return True
        far = outer.difference(Point(m).buffer(0.05))
        if far.intersects(seg) and not inner.intersects(seg):
            return True
    return False


def test_laser_agrees_with_the_planner_on_polygons_holes_and_circles():
    sc = shapes()
    markers = sc.marker_positions()
    rng = np.random.default_rng(3)
    solid = unary_union([ob.geometry() for ob in sc.obstacles])
    checked = 0
    counts = np.zeros(len(markers), dtype=int)
    in_hole = 0
    with PhysicsWorld(sc) as w:
        laser = LaserSensor(w, sc.sensor_actual, markers)
        post_r = w.config.post_radius
        while checked < 120:
            p = rng.uniform([0.3, 0.3], [15.7, 9.7]) if checked % 4 else rng.uniform([9.3, 4.3], [11.7, 6.7])
            if solid.distance(Point(p)) < 0.3 or _ambiguous(sc, p, markers, post_r):
                continue
            # the margin-free geometry is the laser's, away from grazing rays (the ambiguity test)
            vis, _ = visible_points(p[None], markers, sc.obstacle_pieces(), sc.sensor.max_range, sc.workspace.bounds)
            usable, _ = scenario_visible_points(sc, p[None])
            # Another marker's post blocks the ray too (the planner does not know posts).
            posts = np.array([[LineString([p, m]).distance(Point(o)) < post_r for j, o in enumerate(markers) if j != i]
                              for i, m in enumerate(markers)]).any(axis=1)
            w.reset((p[0], p[1], rng.uniform(-math.pi, math.pi)))
            got = laser.visible_all()
            assert got.tolist() == (vis[:, 0] & ~posts).tolist(), f"at {p}"
            assert not np.any(usable[:, 0] & ~got), f"at {p}: the plan's rule counts on what the laser does not see"
            counts += got
            in_hole += shapely.contains_xy(shapely.box(9, 4, 12, 7), *p)
            checked += 1
    assert np.all(counts > 0) and np.all(counts < checked) and in_hole > 20


def test_a_far_origin_world_sees_and_ranges_like_the_one_at_zero():
    near, far = shapes(), shapes(250000.0, 80000.0)
    pose = np.array([10.5, 5.5, 0.3])
    shift = np.array([250000.0, 80000.0, 0.0])
    with PhysicsWorld(near, pose=pose) as a, PhysicsWorld(far, pose=pose + shift) as b:
        la = LaserSensor(a, near.sensor_actual, near.marker_positions())
        lb = LaserSensor(b, far.sensor_actual, far.marker_positions())
        assert la.visible_all().tolist() == lb.visible_all().tolist()
        assert np.flatnonzero(la.visible_all()).tolist() == [4, 5]  # in the hole: its two face markers
        assert np.allclose(b.true_pose() - shift, a.true_pose(), atol=1e-9)
        ma = la.measure(4, np.random.default_rng(1))
        mb = lb.measure(4, np.random.default_rng(1))
        assert abs(ma.measured_range - mb.measured_range) < 1e-9
