"""A fleet robot's zone gate: what it asks of zone control each control tick, and how fast that lets it go.

One rule, used by the simulation (:class:`sim.episode.fleet.ZoneGate`, every control tick of a
physical robot) and by the planner's sampled blocking prediction (:mod:`planner.fleet.sampled`,
which drives the same rule kinematically), so that a robot waits in the model where and when it
waits in the simulation. At each tick, a robot at arc length ``s`` of its whole path commanded to
``v``:

* releases the zones it has left ``RELEASE_SLACK`` behind it;
* asks for the floor up to its braking distance ``v^2 / (2 BRAKE a)`` plus ``LOOKAHEAD`` ahead;
* is capped to the speed from which it stops ``STOP_MARGIN`` short of its reservation's end, and
  stands there (holding its stop's cells alone, :meth:`planner.fleet.zones.ZoneControl.stand`)
  once that cap falls below ``WAIT_SPEED``. Reserved to its final dock, it is not capped: the path
  follower's own goal stop rules.
"""

from __future__ import annotations

import math

STOP_MARGIN = 0.05
"""A robot aims to stop this far before the end of its reservation [m] (the follower's overshoot)."""
RELEASE_SLACK = 0.1
"""A robot releases the zones of its path up to this far behind its estimate [m]: its true
position may trail the estimate's projection by the tracking error."""
LOOKAHEAD = 0.5
"""A robot asks for the floor this far beyond its braking distance [m], so that it rarely
slows for a reservation it would have got."""
BRAKE = 0.8
"""Share of the follower's deceleration limit a zone stop uses (the follower brakes for its goal
with the same share)."""
GOAL_TOLERANCE = 0.05
"""The path follower's goal tolerance [m] (``sim.episode.follower.PurePursuit.goal_tolerance``): a
robot is done with a task within it of the task's end, and stands there."""
CREEP_SPEED = 0.02
"""The path follower's least commanded speed short of its goal [m/s] (``sim.episode.follower``: it
creeps rather than stall within a rounding of its goal tolerance)."""
WAIT_SPEED = 0.02
"""A robot whose zone speed cap is below this [m/s] stands at the end of its reservation: it
waits there, within ``STOP_MARGIN`` + 0.5 mm of its stop (a cap this low leaves ``0.02^2 / (2 BRAKE
a)`` of room, a = 0.5 m/s^2), and holds the stop's cells alone (``margin`` of the zones covers the gap)."""


def zone_cap(zones, i: int, s: float, v: float, accel: float) -> float:
    """Release behind robot ``i``, request ahead of it, and return its speed cap (module docstring).

    Parameters
    ----------
    zones : planner.fleet.zones.ZoneControl
        The fleet's zone control (robot ``i``'s reservation is updated in place).
    i : int
        The robot.
    s : float
        Its arc length along its whole path [m].
    v : float
        Its commanded speed before the cap [m/s].
    accel : float
        Its path follower's acceleration limit [m/s^2].

    Returns
    -------
    float
        The cap [m/s]: ``inf`` when reserved to its final dock; 0.0 when it must stand at its
        stop (it then holds that stop's cells alone).
    """
    zones.release(i, s - RELEASE_SLACK)
    zones.request(i, s + v * v / (2.0 * BRAKE * accel) + LOOKAHEAD)
    end = zones.reserved_to(i)
    if end >= zones.length(i):
        # compared as arc lengths, not as room left: the room and the way left, summed in another
        # order, differed in the last bit, and a robot 5 cm short of its goal was held there for good
        return math.inf
    cap = math.sqrt(2.0 * BRAKE * accel * max(end - STOP_MARGIN - s, 0.0))
    if cap < WAIT_SPEED:
        # the samples just before a stop need not be safe, and a waiting robot that held them
        # could block the robot it waits for (zones.stand)
        zones.stand(i)
        return 0.0
    return cap
