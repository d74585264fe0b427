"""A ROS map read as a map: unknown space is neither floor nor wall, sites sit on occupied faces.

The map (``tests.scenarios.drawings.room_map``) is written with Pillow in map_saver's shades
(0 / 254 / 205): an unknown band round a walled room whose right wall has an opening, an
unknown pocket inside it and a rack wall at 30 degrees.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import shapely

import scenarios
from planner.placement.facing import face_directions
from planner.placement.sites import candidate_sites, route_points
from tests.scenarios import drawings as dr
from tests.scenarios.drawings import room_text

RES = 0.05


@pytest.fixture(scope="module")
def room(tmp_path_factory):
    folder = tmp_path_factory.mktemp("room")
    dr.write_map(folder, dr.room_map(), origin=(*dr.ROOM_ORIGIN, 0.0))
    (folder / "room.toml").write_text(room_text())
    return scenarios.load(folder / "room.toml")


def cell_of(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Image row and column of points (N, 2) [m] (row 0 at the top)."""
    h, _ = dr.ROOM_SHAPE
    c = np.floor((p[:, 0] - dr.ROOM_ORIGIN[0]) / RES).astype(int)
    r = h - 1 - np.floor((p[:, 1] - dr.ROOM_ORIGIN[1]) / RES).astype(int)
    return r, c


def bad_sites(sc) -> np.ndarray:
    """Sites (S, 2) that are not on a face of occupied cells looking into known free space.

    A site on an occupied face has an occupied cell within 1.5 cells (the simplified face stays
    within one cell of the traced one); the cell 1.5 cells out along its facing is free.
    """
    img = dr.room_map()
    sites = candidate_sites(sc)
    facing = np.array(face_directions(sc, sites), dtype=float)
    r, c = np.nonzero(img == dr.OCCUPIED)
    h = dr.ROOM_SHAPE[0]
    occ = np.column_stack([dr.ROOM_ORIGIN[0] + (c + 0.5) * RES, dr.ROOM_ORIGIN[1] + (h - r - 0.5) * RES])
    near = np.array([np.abs(occ - p).max(axis=1).min() <= 1.5 * RES + 1e-9 for p in sites])
    front = sites + 1.5 * RES * np.column_stack([np.cos(facing), np.sin(facing)])
    fr, fc = cell_of(front)
    free_ahead = img[np.clip(fr, 0, h - 1), np.clip(fc, 0, dr.ROOM_SHAPE[1] - 1)] == dr.FREE
    return sites[~(near & free_ahead)]


def test_workspace_is_the_known_area_and_its_border_no_wall(room):
    assert room.workspace.bounds == pytest.approx(dr.ROOM_KNOWN)
    assert not room.workspace.walls
    pocket = shapely.box(*dr.ROOM_POCKET)
    assert any(u.geometry().equals_exact(pocket.normalize(), 1e-9) or u.geometry().symmetric_difference(pocket).area
               < 1e-9 for u in room.unknown)
    assert not any(ob.geometry().intersection(pocket).area > 1e-9 for ob in room.obstacles)  # not an obstacle


def test_sites_only_on_occupied_faces_facing_known_space(room):
    sites = candidate_sites(room)
    assert len(sites) > 20
    assert len(bad_sites(room)) == 0
    # none on the opening (x = 5.5, y 0..1) nor anywhere on the known area's border
    x0, y0, x1, y1 = dr.ROOM_KNOWN
    on_border = (np.abs(sites[:, 0] - x0) < 1e-6) | (np.abs(sites[:, 0] - x1) < 1e-6) \
        | (np.abs(sites[:, 1] - y0) < 1e-6) | (np.abs(sites[:, 1] - y1) < 1e-6)
    assert not on_border.any()


def test_negative_control_old_semantics_put_sites_on_the_edge_and_in_unknown(room):
    """The checks above fail for the reading this replaced: border walls, unknown cells as obstacles."""
    walled = dataclasses.replace(room, workspace=dataclasses.replace(room.workspace, walls=True))
    bad = bad_sites(walled)
    assert ((bad[:, 0] > dr.ROOM_KNOWN[2] - 1e-6) & (bad[:, 1] > 0.0) & (bad[:, 1] < 1.0)).any()  # the opening
    old = dataclasses.replace(room, obstacles=room.obstacles + room.unknown, unknown=())
    bad = bad_sites(old)
    px0, py0, px1, py1 = dr.ROOM_POCKET
    assert ((bad[:, 0] >= px0 - 1e-6) & (bad[:, 0] <= px1 + 1e-6) & (bad[:, 1] >= py0 - 1e-6)
            & (bad[:, 1] <= py1 + 1e-6)).any()  # on the pocket's faces


def test_facings_of_a_slanted_wall_within_a_degree(room):
    """The rack's faces run at 30 degrees: its sites face 120 or -60 degrees within 1 degree.

    The line is fitted to the cell faces within FIT_RADIUS = 0.5 m: a 30-degree staircase of
    5 cm cells, its midpoints spread evenly along the line, tilts the principal axis by well
    under a degree (measured 0.35 at most). Sites within FIT_RADIUS + 0.1 m of the rack's ends,
    whose disc takes in the end face, are left out.
    """
    (ax, ay), (bx, by) = dr.ROOM_RACK
    a, b = np.array([ax, ay]), np.array([bx, by])
    u = (b - a) / np.hypot(*(b - a))
    sites = candidate_sites(room, spacing=0.2)
    along = (sites - a) @ u
    across = np.abs((sites - a) @ np.array([-u[1], u[0]]))
    on_rack = (across < dr.ROOM_RACK_HALF + 2 * RES) & (along > 0.6) & (along < np.hypot(*(b - a)) - 0.6)
    assert on_rack.sum() >= 4
    facing = np.degrees(np.array(face_directions(room, sites[on_rack]), dtype=float))
    err = np.minimum(np.abs((facing - 120.0 + 180.0) % 360.0 - 180.0), np.abs((facing + 60.0 + 180.0) % 360.0 - 180.0))
    assert err.max() <= 1.0, f"facings {facing} off by up to {err.max():.2f} degrees"
    # negative control: the simplified outline's own edge normals are off by more
    raw = dataclasses.replace(room, floorplan=None)
    raw_facing = np.degrees(np.array(face_directions(raw, sites[on_rack]), dtype=float))
    raw_err = np.minimum(np.abs((raw_facing - 120.0 + 180.0) % 360.0 - 180.0),
                         np.abs((raw_facing + 60.0 + 180.0) % 360.0 - 180.0))
    assert raw_err.max() > 1.0


def test_routes_keep_out_of_unknown_space(room):
    """The drivable route between the docks (planned before any marker is placed) skirts the pocket."""
    assert not room.markers
    pocket = shapely.box(*dr.ROOM_POCKET)
    pts = route_points(room)
    d = shapely.distance(pocket, shapely.points(pts))
    assert d.min() >= room.robot.radius - RES  # the body clear of the pocket (grid search, one cell)
    # negative control: without the unknown areas the straight way runs through the pocket
    blind = dataclasses.replace(room, unknown=())
    assert shapely.distance(pocket, shapely.points(route_points(blind))).min() == 0.0


def test_a_dock_in_unknown_space_is_refused(tmp_path):
    dr.write_map(tmp_path, dr.room_map(), origin=(*dr.ROOM_ORIGIN, 0.0))
    (tmp_path / "room.toml").write_text(room_text().replace("[0.0, -0.4, 0.0]", "[0.9, -0.4, 0.0]"))
    with pytest.raises(scenarios.ScenarioError, match=r"docks\[0\]\.pose: expected .* outside unknown areas"):
        scenarios.load(tmp_path / "room.toml")


def test_walls_key_overrides_and_is_checked(tmp_path):
    dr.write_map(tmp_path, dr.room_map(), origin=(*dr.ROOM_ORIGIN, 0.0))
    (tmp_path / "room.toml").write_text(room_text("walls = true"))
    assert scenarios.load(tmp_path / "room.toml").workspace.walls
    (tmp_path / "room.toml").write_text(room_text('walls = "no"'))
    with pytest.raises(scenarios.ScenarioError, match=r'workspace\.walls: expected true or false, got "no"'):
        scenarios.load(tmp_path / "room.toml")


def test_unknown_everywhere_is_one_error_line(tmp_path):
    dr.write_map(tmp_path, np.full((10, 10), dr.UNKNOWN, dtype=np.uint8))
    (tmp_path / "room.toml").write_text('name = "u"\n[floorplan]\nfile = "map.yaml"\n[sensor]\n[planning]\n'
                                        'eps_max = 0.03\n')
    with pytest.raises(scenarios.ScenarioError, match=r"image: expected some known cells"):
        scenarios.load(tmp_path / "room.toml")


def test_hand_written_scenarios_keep_their_walls():
    sc = scenarios.load("warehouse")
    assert sc.workspace.walls and sc.unknown == ()
    x0, y0, x1, y1 = sc.workspace.bounds
    sites = candidate_sites(sc)
    assert (np.abs(sites[:, 0] - x0) < 1e-9).any() and (np.abs(sites[:, 1] - y1) < 1e-9).any()
    assert math.isclose(face_directions(sc, sites[np.abs(sites[:, 0] - x0) < 1e-9][:1])[0], 0.0, abs_tol=1e-12)
