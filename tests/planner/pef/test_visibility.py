"""Visibility: range limit, occluding boxes, markers on faces, points inside obstacles.

And the agreement of the grid path (shadow rasterisation) with the points path (segment clipping).
"""

from __future__ import annotations

import numpy as np
import pytest

import scenarios
from planner.pef.convex import piece_arrays
from planner.pef.visibility import (
    scenario_visible_grid,
    scenario_visible_points,
    visible_grid,
    visible_points,
)
from scenarios.obstacles import pack_pieces
from scenarios.schema import Obstacle

WS = (0.0, 0.0, 20.0, 10.0)  # workspace bounds (x0, y0, x1, y1)


def _corners(*boxes: Obstacle) -> np.ndarray:
    return np.stack([b.corners() for b in boxes]) if boxes else np.zeros((0, 4, 2))


def _vis(points, markers, boxes=(), max_range=100.0):
    vis, free = visible_points(np.asarray(points, float), np.asarray(markers, float), _corners(*boxes),
                               max_range, WS)
    return vis.T, free


def test_piece_arrays_hold_unit_outward_normals_and_shrunk_corners():
    ob = Obstacle(center=(3.0, 4.0), size=(2.0, 1.0), yaw=0.3)
    pa = piece_arrays(pack_pieces([ob]), 0.01)
    n, c = pa.planes[0, :4, :2], pa.planes[0, :4, 2]
    assert np.hypot(n[:, 0], n[:, 1]) == pytest.approx(np.ones(4))
    corners = ob.corners()
    # Edges bottom, right, top, left: the centre lies half a width or half a length inside each.
    assert n @ corners.mean(axis=0) - c == pytest.approx([-0.5, -1.0, -0.5, -1.0])
    # The shrunk corners are the box of half-sizes (1 - 0.01, 0.5 - 0.01) around the centre.
    shrunk = Obstacle(center=(3.0, 4.0), size=(2.0 - 0.02, 1.0 - 0.02), yaw=0.3).corners()
    assert pa.shrunk[0, :4] == pytest.approx(shrunk)
    assert pa.blocks[0] and not piece_arrays(pack_pieces([ob]), 0.6).blocks[0]


def test_box_between_point_and_marker_blocks_and_beside_does_not():
    box = Obstacle(center=(10.0, 5.0), size=(2.0, 2.0))
    marker = [[2.0, 5.0]]
    pts = [[18.0, 5.0],   # straight behind the box
           [18.0, 5.9],   # behind, line passes through the box
           [18.0, 7.5],   # line passes above the box (y at x=11 is 6.57 > 6)
           [5.0, 5.0],    # in front of the box
           [10.0, 8.0]]   # beside
    vis, free = _vis(pts, marker, [box])
    assert free.all()
    assert vis[:, 0].tolist() == [False, False, True, True, True]


def test_grazing_a_corner_is_not_blocked():
    # Box [8, 10] x [4, 6]; the line from (6, 8) to (14, 4) touches only its corner (10, 6).
    box = Obstacle(center=(9.0, 5.0), size=(2.0, 2.0))
    vis, _ = _vis([[14.0, 4.0], [14.0, 3.9]], [[6.0, 8.0]], [box])
    assert vis[0, 0]
    assert not vis[1, 0]  # a slightly steeper line cuts the corner off


def test_rotated_box_blocks_by_its_true_shape():
    # A thin plank at 45 degrees through (10, 5): blocks the horizontal line y = 5, not y = 7.
    plank = Obstacle(center=(10.0, 5.0), size=(4.0, 0.2), yaw=np.pi / 4)
    vis, _ = _vis([[15.0, 5.0], [15.0, 7.6]], [[5.0, 5.0], [5.0, 7.6]], [plank])
    assert not vis[0, 0]          # through the plank's middle
    assert vis[1, 1]              # y = 7.6 is above the plank's top end (10 + 1.41, 5 + 1.41 + 0.07)


def test_marker_on_a_face_is_seen_from_the_open_side_only():
    box = Obstacle(center=(10.0, 5.0), size=(4.0, 2.0))   # top face y = 6
    marker = [[10.0, 6.0]]
    pts = [[10.0, 9.0],   # in front of the face
           [6.0, 6.5],    # in front, oblique
           [10.0, 1.0],   # behind the box: through it
           [6.0, 5.5],    # beside the box, below the face plane: the line crosses the box
           [13.0, 6.0]]   # in the face plane, grazing along the face: not through the interior
    vis, _ = _vis(pts, marker, [box])
    assert vis[:, 0].tolist() == [True, True, False, False, True]


def test_points_inside_obstacles_or_outside_the_workspace_are_not_free():
    box = Obstacle(center=(10.0, 5.0), size=(4.0, 2.0))
    pts = [[10.0, 5.0], [12.0, 5.5], [12.0, 6.0], [-0.5, 5.0], [5.0, 10.5], [5.0, 9.0]]
    vis, free = _vis(pts, [[0.0, 0.0], [20.0, 10.0]], [box])
    assert free.tolist() == [False, False, False, False, False, True]  # the boundary is not free
    assert not vis[~free].any()


@pytest.mark.parametrize("d, expected", [(4.999, True), (5.0, True), (5.001, False)])
def test_max_range_is_inclusive(d, expected):
    vis, _ = _vis([[3.0 + d, 4.0]], [[3.0, 4.0]], max_range=5.0)
    assert vis[0, 0] == expected


def test_marker_inside_a_box_is_hidden_everywhere_on_both_paths():
    box = Obstacle(center=(10.0, 5.0), size=(4.0, 2.0))
    x = np.linspace(0.25, 19.75, 40)
    y = np.linspace(0.25, 9.75, 20)
    vg, _ = visible_grid(x, y, [[10.5, 5.2]], _corners(box), 100.0, WS)
    xx, yy = np.meshgrid(x, y)
    vp, _ = visible_points(np.column_stack([xx.ravel(), yy.ravel()]), [[10.5, 5.2]], _corners(box), 100.0, WS)
    assert not vg.any() and not vp.any()


def _random_layout(rng, n_boxes, n_markers):
    boxes = []
    while len(boxes) < n_boxes:
        boxes.append(Obstacle(center=(float(rng.uniform(2, 18)), float(rng.uniform(1.5, 8.5))),
                              size=(float(rng.uniform(0.3, 3.0)), float(rng.uniform(0.3, 2.0))),
                              yaw=float(rng.uniform(0, np.pi))))
    markers = []
    for i in range(n_markers):
        if i % 3 == 0:  # on a box face, at a random point of a random edge
            c = boxes[i % n_boxes].corners()
            e = int(rng.integers(4))
            t = rng.uniform(0.1, 0.9)
            markers.append(c[e] + t * (c[(e + 1) % 4] - c[e]))
        elif i % 3 == 1:  # on a wall
            markers.append([rng.uniform(0, WS[2]), rng.choice([0.0, WS[3]])])
        else:
            markers.append(rng.uniform([0, 0], WS[2:]))
    return boxes, np.array(markers, float)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_grid_path_agrees_with_points_path_on_random_layouts(seed):
    rng = np.random.default_rng(seed)
    boxes, markers = _random_layout(rng, n_boxes=6, n_markers=9)
    corners = _corners(*boxes)
    x = (np.arange(157) + 0.5) * WS[2] / 157
    y = (np.arange(83) + 0.5) * WS[3] / 83
    vg, fg = visible_grid(x, y, markers, corners, 12.0, WS)
    xx, yy = np.meshgrid(x, y)
    vp, fp = visible_points(np.column_stack([xx.ravel(), yy.ravel()]), markers, corners, 12.0, WS)
    assert np.array_equal(fg.ravel(), fp)
    assert np.array_equal(vg.reshape(len(markers), -1), vp)
    # The layouts are not trivial: some cells are shadowed, some out of range, most see something.
    in_range = np.hypot(xx.ravel()[None] - markers[:, :1], yy.ravel()[None] - markers[:, 1:]) <= 12.0
    shadowed = in_range & fp[None] & ~vp
    assert shadowed.mean() > 0.02 and vp.mean() > 0.3


def test_grid_path_agrees_with_points_path_on_the_warehouse():
    sc = scenarios.load("warehouse")
    x = (np.arange(300) + 0.5) * 0.1
    y = (np.arange(200) + 0.5) * 0.1
    vg, fg = scenario_visible_grid(sc, x, y)
    xx, yy = np.meshgrid(x, y)
    vp, fp = scenario_visible_points(sc, np.column_stack([xx.ravel(), yy.ravel()]))
    assert np.array_equal(fg.ravel(), fp)
    assert np.array_equal(vg.reshape(len(sc.markers), -1), vp)
    # R1 sits on the aisle face (y = 6) of rack row 1: seen from the aisle, not from below the rack.
    r1 = sc.marker_ids().index("R1")
    iy_aisle, iy_below = np.searchsorted(y, 7.0), np.searchsorted(y, 3.0)
    ix = np.searchsorted(x, 15.0)
    assert vg[r1, iy_aisle, ix] and not vg[r1, iy_below, ix]


def test_pairs_path_agrees_with_points_path_pair_by_pair():
    """Each point looking at one marker (the schedule's sight check) sees it exactly when the points path says so.

    With the line-of-sight rule's margins (flat reflectors on the racks, their bodies blocking),
    on the warehouse. Negative control: paired with the next marker instead, the answers differ
    (the pairing is what is tested, not a constant answer).
    """
    from planner.pef.sight import SightRule
    from planner.pef.visibility import visible_pairs

    sc = scenarios.load("warehouse")
    rng = np.random.default_rng(7)
    x0, y0, x1, y1 = sc.workspace.bounds
    pts = np.column_stack([rng.uniform(x0, x1, 3000), rng.uniform(y0, y1, 3000)])
    m = len(sc.markers)
    which = rng.integers(0, m, len(pts))
    args = (sc.marker_positions(), sc.obstacle_pieces(), sc.sensor.max_range, sc.workspace.bounds,
            sc.marker_normals(), sc.sensor.max_incidence, SightRule(margin=0.02))
    vis, _ = visible_points(pts, *args)
    got = visible_pairs(pts, which, *args)
    assert np.array_equal(got, vis[which, np.arange(len(pts))])
    assert 0.1 < got.mean() < 0.9  # both answers occur
    other = visible_pairs(pts, (which + 1) % m, *args)
    assert not np.array_equal(other, got)
