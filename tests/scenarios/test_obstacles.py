"""Polygon and circle obstacles: loading, validation messages, geometry and convex pieces."""

from __future__ import annotations

import math

import numpy as np
import pytest
from shapely.geometry import Polygon
from shapely.ops import unary_union

import scenarios
from scenarios import Obstacle, ScenarioError
from scenarios.geometry import CIRCLE_SAGITTA, circle_vertices, convex_pieces
from tests.scenarios.worlds import MINIMAL

U_SHAPE = "[[3.0, 2.0], [7.0, 2.0], [7.0, 6.0], [6.0, 6.0], [6.0, 3.0], [4.0, 3.0], [4.0, 6.0], [3.0, 6.0]]"


def _with_obstacle(body: str) -> str:
    head, tail = MINIMAL.split("[[markers]]", 1)
    return head + "[[obstacles]]\n" + body + "\n[[markers]]" + tail


def test_polygon_hole_and_circle_load_with_their_geometry():
    text = _with_obstacle(f"polygon = {U_SHAPE}\n[[obstacles]]\n"
                          "polygon = [[1, 5], [2.5, 5], [2.5, 7.5], [1, 7.5], [1, 5]]\n"
                          "holes = [[[1.5, 5.5], [2, 5.5], [2, 7]]]\n"
                          "[[obstacles]]\ncenter = [8.5, 5.0]\nradius = 0.3")
    s = scenarios.loads(text, "hall.toml")
    box, u, ring, pillar = s.obstacles
    assert [o.kind for o in s.obstacles] == ["box", "polygon", "polygon", "circle"]
    assert u.geometry().area == pytest.approx(4 * 4 - 2 * 3)
    assert ring.geometry().area == pytest.approx(1.5 * 2.5 - 0.5 * 1.5 / 2)
    assert len(ring.rings()) == 2
    # The circle's polygon covers the circle and stays within the sagitta of it.
    r = np.hypot(*(pillar.pieces()[0] - pillar.center).T)
    assert np.all(r >= 0.3) and np.all(r <= 0.3 + CIRCLE_SAGITTA)
    assert u.contains((3.5, 4.0)) and not u.contains((5.0, 4.0))
    assert u.contains((5.0, 3.05), margin=0.1) and not u.contains((3.5, 4.0), margin=-0.6)
    assert not ring.contains((1.8, 6.0))  # in the hole
    assert box.contains((5.0, 4.0)) == Obstacle.box((5.0, 4.0), (2.0, 1.0), math.radians(30)).contains((5.0, 4.0))
    pieces = s.obstacle_pieces()
    assert len(pieces) == 1 + len(u.pieces()) + len(ring.pieces()) + 1
    assert list(pieces.owner[:2]) == [0, 1]


def test_a_circle_marker_or_dock_inside_a_polygon_is_rejected():
    text = _with_obstacle(f"polygon = {U_SHAPE}").replace("pose = [1.0, 1.0, 90.0]", "pose = [3.5, 4.0, 90.0]")
    with pytest.raises(ScenarioError, match=r"docks\[0\]\.pose: expected \[x, y, yaw_deg\] outside obstacles "
                                            r"\(inside obstacles\[1\]\)"):
        scenarios.loads(text, "hall.toml")


@pytest.mark.parametrize("body, pattern", [
    ("polygon = [[0, 0], [2, 0], [0, 2], [2, 2]]",
     r"^hall\.toml: obstacles\[1\]\.polygon: expected a simple polygon \(edges 1 and 3 cross\), got \[\[0, 0\]"),
    ("polygon = [[0, 0], [2, 0]]", r"obstacles\[1\]\.polygon: expected a list of at least 3 \[x, y\] vertices"),
    ("polygon = [[0, 0], [2, 0], [2, 0], [1, 1]]",
     r"obstacles\[1\]\.polygon: expected distinct consecutive vertices \(vertices 1 and 2 coincide\)"),
    ("polygon = [[0, 0], [1, 1], [2, 2]]", r"obstacles\[1\]\.polygon: expected a simple polygon"),
    ("polygon = [[0, 0], [2, 0], [1, \"a\"]]", r"obstacles\[1\]\.polygon: expected a list of at least 3"),
    ("polygon = [[0, 0], [4, 0], [4, 4], [0, 4]]\nholes = [[[1, 1], [5, 1], [1, 2]]]",
     r"obstacles\[1\]\.holes\[0\]: expected a hole strictly inside the polygon, got \[\[1, 1\]"),
    ("polygon = [[0, 0], [4, 0], [4, 4], [0, 4]]\nholes = [[[1, 1], [3, 1], [1, 3]], [[2, 1.5], [3, 3], [1.5, 3]]]",
     r"obstacles\[1\]\.holes\[1\]: expected holes apart from each other \(meets holes\[0\]\)"),
    ("polygon = [[0, 0], [4, 0], [4, 4], [0, 4]]\nholes = [[[1, 1], [3, 3], [3, 1], [1, 3]]]",
     r"obstacles\[1\]\.holes\[0\]: expected a simple polygon \(edges 0 and 2 cross\)"),
    ("polygon = [[0, 0], [4, 0], [4, 4]]\nradius = 1.0", r"obstacles\[1\]\.radius: not a key of a polygon obstacle"),
    ("center = [1, 1]\nradius = 0.0", r"obstacles\[1\]\.radius: expected a radius in metres >= 1e-09, got 0\.0"),
    ("center = [1, 1]\nradius = 1.0\nsize = [1, 1]", r"obstacles\[1\]\.size: not a key of a circle obstacle"),
    ("center = [1, 1]", r"obstacles\[1\]: expected center \+ size \[\+ yaw_deg\] \(a box\), center \+ radius"),
    ("center = [1, 1]\nholes = []", r"obstacles\[1\]\.holes: holes need a polygon"),
    ("polygon = [[0, 0], [4, 0], [4, 4]]\nhole = []", r"obstacles\[1\]\.hole: unknown key"),
])
def test_bad_obstacles_name_file_key_and_value(body, pattern):
    with pytest.raises(ScenarioError, match=pattern):
        scenarios.loads(_with_obstacle(body), "hall.toml")


def test_closed_and_clockwise_rings_give_the_same_obstacle_geometry():
    ccw = [(0, 0), (4, 0), (4, 3), (2, 1), (0, 3)]
    a = Obstacle.from_polygon(ccw)
    b = Obstacle.from_polygon(ccw[::-1])
    assert a.geometry().equals(b.geometry())


@pytest.mark.parametrize("poly", [
    Polygon([(0, 0), (6, 0), (6, 4), (4, 4), (4, 1), (2, 1), (2, 4), (0, 4)]),
    Polygon([(0, 0), (10, 0), (10, 10), (0, 10)], [[(3, 3), (7, 3), (7, 7), (3, 7)], [(8, 8), (9, 8), (8.5, 9)]]),
    Polygon([(math.cos(a) * (2 + math.sin(5 * a)), math.sin(a) * (2 + math.sin(5 * a)))
             for a in np.linspace(0, 2 * math.pi, 60, endpoint=False)]),
])
def test_convex_pieces_tile_the_polygon_and_are_convex(poly):
    pieces = convex_pieces(poly)
    union = unary_union([Polygon(p) for p in pieces])
    assert union.symmetric_difference(poly).area < 1e-9 * poly.area
    assert sum(Polygon(p).area for p in pieces) == pytest.approx(poly.area)  # interiors disjoint
    for p in pieces:
        e = np.roll(p, -1, axis=0) - p
        turn = e[:, 0] * np.roll(e[:, 1], -1) - e[:, 1] * np.roll(e[:, 0], -1)
        assert np.all(turn > 0)  # counter-clockwise, strictly convex, no collinear vertex
    # Hertel-Mehlhorn keeps at most 2 r + 1 pieces for r reflex vertices, fewer than the triangles.
    n_tri = sum(len(r.coords) - 1 for r in (poly.exterior, *poly.interiors)) + 2 * len(poly.interiors) - 2
    assert len(pieces) <= 2 * _reflex(poly) + 1 and len(pieces) < n_tri


def _reflex(poly: Polygon) -> int:
    """Reflex vertices of the region: concave shell corners and convex hole corners."""
    def turns(ring, ccw):
        v = np.asarray(ring.coords)[:-1]
        v = v if Polygon(v).exterior.is_ccw == ccw else v[::-1]
        e = np.roll(v, -1, axis=0) - v
        return e[:, 0] * np.roll(e[:, 1], -1) - e[:, 1] * np.roll(e[:, 0], -1)
    n = int(np.sum(turns(poly.exterior, True) < 0))
    return n + sum(int(np.sum(turns(h, True) > 0)) for h in poly.interiors)


def test_circle_polygon_is_the_fewest_sides_within_the_sagitta():
    v = circle_vertices((0.0, 0.0), 1.0)
    n = len(v)
    assert 1.0 / math.cos(math.pi / n) - 1.0 <= CIRCLE_SAGITTA < 1.0 / math.cos(math.pi / (n - 1)) - 1.0


def test_to_dict_reads_back_as_the_same_obstacle():
    obs = [Obstacle.box((1, 2), (3, 1), 0.4), Obstacle.circle((2, 2), 0.5),
           Obstacle.from_polygon([(0, 0), (4, 0), (4, 4), (0, 4)], [[(1, 1), (2, 1), (1, 2)]])]
    from scenarios.fields import Table
    from scenarios.obstacle_table import read_obstacle
    for ob in obs:
        back = read_obstacle(Table(ob.to_dict(), "x.toml", "obstacles[0]"))
        assert back.geometry().equals_exact(ob.geometry(), 1e-12)
