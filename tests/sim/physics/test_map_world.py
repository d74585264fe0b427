"""The physics world of a ROS map: no wall on the map's edge, nothing in unknown space."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import scenarios
from sim.physics.quiet import pb
from sim.physics.world import PhysicsWorld
from tests.scenarios import drawings as dr
from tests.scenarios.drawings import room_text

LASER_Z = 0.3  # [m]: below every wall's top


@pytest.fixture(scope="module")
def room(tmp_path_factory):
    folder = tmp_path_factory.mktemp("room")
    dr.write_map(folder, dr.room_map(), origin=(*dr.ROOM_ORIGIN, 0.0))
    (folder / "room.toml").write_text(room_text())
    return scenarios.load(folder / "room.toml")


def ray(world: PhysicsWorld, a, b) -> int:
    """Body id the ray from a to b (user frame [m]) hits first, -1 for none."""
    a, b = np.asarray(a, float) - world.origin, np.asarray(b, float) - world.origin
    return pb.rayTest([*a, LASER_Z], [*b, LASER_Z], physicsClientId=world.client)[0][0]


def test_no_wall_on_the_opening_nor_a_body_in_unknown_space(room):
    pose = (4.0, 2.0, 0.0)  # out of the rays' way
    with PhysicsWorld(room, pose=pose) as w:
        assert ray(w, (5.0, 0.5), (7.0, 0.5)) == -1                 # out through the opening and past the edge
        assert ray(w, (0.2, -0.4), (1.6, -0.4)) == -1               # across the unknown pocket
        assert ray(w, (0.0, 2.0), (0.0, 3.0)) in set(w.blocker_ids)  # the occupied top wall is a body
    # negative control: with walls = true the border is a wall again, across the opening too
    walled = dataclasses.replace(room, workspace=dataclasses.replace(room.workspace, walls=True))
    with PhysicsWorld(walled, pose=pose) as w:
        assert ray(w, (5.0, 0.5), (7.0, 0.5)) in set(w.blocker_ids)
