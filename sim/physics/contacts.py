"""What a robot's body touches: contact episodes with anything but the floor.

A robot's links (chassis, wheels, casters) touch the floor all the time; anything else they
touch (a border wall, an obstacle, a marker post, another robot) is a contact. Contacts are read
from pybullet's contact manifold after the physics has stepped and counted as *episodes*: a
contact read after a read without one. The manifold of the robot's body (``getContactPoints``,
~7 us: it always holds the wheels' floor contacts) is read only when the broadphase finds another
body's bounding box overlapping a box around the robot (``getOverlappingObjects``, ~2.5 us): a
contact needs that overlap, so none is missed, and in open floor the cheap query is all a tick
costs (~1 % of a control period's four physics steps). Read
once a control tick, a touch shorter than a control period (1/60 s) that begins and ends between
two reads goes unseen; a robot that runs into something stays in contact far longer than that.
"""

from __future__ import annotations

from sim.physics.quiet import pb

CONTACT_DISTANCE = 1e-4
"""A manifold point closer than this counts as touching [m]: Bullet keeps points up to a few mm
apart in its manifold (a caster 1.6 mm above the floor is one), and rests bodies on each other
within ~1e-5 m; 0.1 mm is above that jitter and below any gap a real robot would keep."""


class ContactMonitor:
    """Counts the contact episodes of one robot of a :class:`~sim.physics.world.PhysicsWorld`.

    Parameters
    ----------
    world : PhysicsWorld
        The built world (reset before the first :meth:`poll`).
    robot : int
        Which of ``world.robots``.

    Attributes
    ----------
    episodes : int
        Contact episodes so far.
    first : tuple or None
        The first contact: (time [s], what it touched); None before any.
    touching : bool
        Whether the last read found a contact.
    """

    def __init__(self, world, robot: int = 0) -> None:
        self._cid = world.client
        r = world.robots[robot]
        self._body = r.body
        self._floor = world.floor_id
        self._labels = world.body_labels
        # bodies a robot always overlaps: the floor, itself, its own footprint cylinder (fleets)
        self._own = {world.floor_id, r.body, *world.body_ids[robot:robot + 1]}
        g, w = r.geometry, world.config.wheel_width
        # the farthest any link reaches from the axle midpoint, plus room for the manifold's margin
        along = max(0.5 * g.chassis_length, max(g.left_radius, g.right_radius), g.caster_x + g.caster_radius)
        across = max(0.5 * g.chassis_width, 0.5 * r.spec.wheel_base + 0.5 * w)
        self._reach = (along * along + across * across) ** 0.5 + 0.05
        self._top = g.top_height + 0.05
        self._origin = (float(world.origin[0]), float(world.origin[1]))
        self.episodes = 0
        self.first: tuple[float, str] | None = None
        self.touching = False

    def poll(self, t: float, x: float, y: float) -> bool:
        """Read the contacts after the last physics step at time ``t`` [s]; return True when one began.

        ``x``, ``y``: the robot's true position (axle midpoint) [m], which the broadphase box is put around.
        """
        other = self._touched() if self._near(x, y) else None
        now = other is not None
        began = now and not self.touching
        self.touching = now
        if began:
            self.episodes += 1
            if self.first is None:
                self.first = (float(t), self._labels.get(other, f"body {other}"))
        return began

    def _near(self, x: float, y: float) -> bool:
        """Tell whether a body other than the floor and the robot's own overlaps a box around the robot."""
        lx, ly, d = x - self._origin[0], y - self._origin[1], self._reach
        near = pb.getOverlappingObjects([lx - d, ly - d, -0.05], [lx + d, ly + d, self._top],
                                        physicsClientId=self._cid)
        own = self._own
        return near is not None and any(b not in own for b, _ in near)

    def _touched(self) -> int | None:
        """Return the body id of something other than the floor the robot touches now, or None."""
        floor = self._floor
        for p in pb.getContactPoints(bodyA=self._body, physicsClientId=self._cid):
            # p[2]: the other body, p[8]: the signed distance [m] (negative: penetration)
            if p[2] != floor and p[8] < CONTACT_DISTANCE:
                return int(p[2])
        return None

