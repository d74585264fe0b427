"""What a robot's body touches: contact episodes with anything but the floor.

A robot's links (chassis, wheels, casters) touch the floor all the time; anything else they
touch (a border wall, an obstacle, a marker post, another robot) is a contact. Contacts are read
from pybullet's contact manifold after the physics has stepped (``getContactPoints`` of the
robot's body: ~7 us a call against the few dozen bodies of a world, ~2 % of a control period's
four physics steps) and counted as *episodes*: a contact read after a read without one. Read
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
        self._body = world.robots[robot].body
        self._floor = world.floor_id
        self._labels = world.body_labels
        self.episodes = 0
        self.first: tuple[float, str] | None = None
        self.touching = False

    def poll(self, t: float) -> bool:
        """Read the contacts after the last physics step at time ``t`` [s]; return True when one began."""
        other = self._touched()
        now = other is not None
        began = now and not self.touching
        self.touching = now
        if began:
            self.episodes += 1
            if self.first is None:
                self.first = (float(t), self._labels.get(other, f"body {other}"))
        return began

    def _touched(self) -> int | None:
        """Return the body id of something other than the floor the robot touches now, or None."""
        floor = self._floor
        for p in pb.getContactPoints(bodyA=self._body, physicsClientId=self._cid):
            # p[2]: the other body, p[8]: the signed distance [m] (negative: penetration)
            if p[2] != floor and p[8] < CONTACT_DISTANCE:
                return int(p[2])
        return None

