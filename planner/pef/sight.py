"""What the plan counts on as a line of sight: one definition for the planner and the simulated laser.

The simulated laser (:mod:`sim.physics.laser`) casts a ray from the robot centre to a marker's
measured point ``M`` (its position, at the laser height) and sees the marker when the first body
the ray meets is the marker's own body: a vertical post of radius :data:`REFLECTOR_RADIUS`
standing at ``M``. A physics ray test meets a body up to :data:`CONTACT_REACH` before its
surface (Bullet's convex collision margin; ``tests/sim/physics/test_sight_physics.py`` measures
it on every shape the world builds), so a ray that passes within that distance of an obstacle
may stop on it. The planner, in 2-D, judges the same segment. A line of sight is *usable* from a
point ``p`` when, for every position ``p'`` within ``margin`` of ``p`` (the robot off its planned
pose):

1. the segment ``p'``-``M`` does not enter any obstacle (the margin-free test of
   :mod:`planner.pef.visibility`, faces shrunk by a micrometre so that a segment ending on a
   face is not blocked);
2. it clears every obstacle that is not the marker's *mount* by ``CONTACT_REACH``: the segment
   ``p'``-``M`` does not enter the piece grown by the reach. The points ``p`` for which that
   fails for *some* ``p'`` within ``margin`` are the piece's shadow seen from ``M`` (the points
   whose segment to ``M`` enters it) widened by ``margin``: every half-plane of the shadow moved
   out by ``margin`` (a mitred superset of the exact set), the same half-planes for arbitrary
   points and for grid rows (:func:`planner.pef.visibility.shadow_table`). The mount of a
   marker is every obstacle piece its body touches: grown by ``REFLECTOR_RADIUS +
   CONTACT_REACH``, it takes in ``M`` (a reflector on a wall, on a rack face or on a pillar).
   The segment necessarily comes close to it at ``M`` itself, and 3 takes its place. A piece
   farther away is a blocker like any other, however near: a pillar 5 cm in front of a wall
   hides the reflector behind it from a wide cone, and a robot within the margin of that
   cone's edge may lose it (random-23-032's R9, 2026-12-06: a mount then reached out by the
   margin, and the plan counted on rays the laser stopped on the pillar);
3. on its mount, the ray meets the marker's own body before coming within ``CONTACT_REACH`` of
   the mount face. The ray enters the post at distance ``REFLECTOR_RADIUS`` before ``M``, where
   it is ``REFLECTOR_RADIUS sin(theta')`` from the face (``theta'`` the angle between the ray and
   the face seen from ``p'``). With ``h = n.(p - M)`` the distance of ``p`` from the face's line
   (``n`` its outward unit normal) and ``r = |p - M|``: ``sin(theta') >= (h - margin) / (r +
   margin)``, so the condition holds for every ``p'`` when ``h >= margin (1 + b) + b r``, ``b =
   CONTACT_REACH / REFLECTOR_RADIUS``: a wedge in front of the face, the flat reflector's
   incidence wedge (``d.n >= |d| cos(max_incidence)``) generalised by an offset
   (:func:`planner.pef.visibility.facing_ok`);
4. the range and a flat reflector's incidence limit hold at every ``p'`` too: ``r <= max_range
   - margin``, and the incidence wedge by the same argument as 3 with ``b = cos(max_incidence)``.

A line of sight that grazes an obstacle within the tracking bound is therefore not one the plan
counts on, and where the plan counts on one the physics ray sees the marker (a test compares
them along the planned paths of every built-in, marker by marker).

The margin of a map (a point with no path through it) is :func:`estimate_floor`: the smallest
pose bound the plan can certify at a fix after the dock. A scheduled measurement is held to its own
pose bound ``Δ_i`` (:func:`planner.schedule.promise.pose_bound`: the tracking bound on the path,
the estimate's certified error, the start lag, the speed; :mod:`planner.schedule.sightcheck`), and
``Δ_i`` is at least the certified estimate error, which is at least the promise of the fix before,
which is at least ``2 min(rho) >= 2 absolute_error`` (every strip of the promise's polygon holds
the disc of radius ``min(rho)``, :mod:`planner.schedule.promise`, "Polygon tolerance"). A line of
sight the map does not count on is therefore one no scheduled fix after the dock could count on:
the map's visibility is a superset of what the schedule keeps, never a guess of it. The dock's
fix (at standstill, ``Δ_0`` may be smaller) is judged by the map, which is only stricter there.

The margin does not depend on ``eps_max``: a looser requirement sees the same markers from the
same points (when the margin was ``eps_max`` plus a measured tracking allowance, 0.12 m, a looser
requirement hid markers, removed admissible routes and made ``place`` add reflectors).
"""

from __future__ import annotations

from dataclasses import dataclass

#: Radius of a reflector's body: the simulated post a laser ray must meet [m].
REFLECTOR_RADIUS = 0.02

#: How far before a body's surface a physics ray test may stop on it [m]. Bullet's convex
#: collision margin: 2.0 mm measured on an extruded convex mesh (the polygon pieces), 1.0 mm on
#: a capsule (the posts), 0.9 mm on a cylinder, 0.7 mm on a box, by bisection over random
#: directions (``tests/sim/physics/test_sight_physics.py`` holds the world's shapes to it).
CONTACT_REACH = 0.002



@dataclass(frozen=True)
class SightRule:
    """The margins of a usable line of sight (module docstring).

    Attributes
    ----------
    margin : float
        How far the robot may be from the pose the plan judges [m] (>= 0).
    radius : float
        Radius of the reflector's body [m] (> 0).
    reach : float
        How far before a surface the physics ray may stop on it [m] (>= 0).
    """

    margin: float
    radius: float = REFLECTOR_RADIUS
    reach: float = CONTACT_REACH

    @property
    def grow(self) -> float:
        """A piece that, grown by this much [m], takes in a marker is the marker's mount: its body touches it."""
        return self.radius + self.reach

    @property
    def slope(self) -> float:
        """``b = reach / radius``: the sine of the shallowest usable angle to a mount face far away."""
        return self.reach / self.radius

    @property
    def offset(self) -> float:
        """``margin (1 + b)``: the closest usable distance from a mount face's line at the marker [m]."""
        return self.wedge_offset(self.slope)

    def wedge_offset(self, slope: float) -> float:
        """Return the offset [m] that makes the wedge ``d.n >= |d| slope`` hold within ``margin`` of a point."""
        return self.margin * (1.0 + slope)

    def usable_range(self, max_range: float) -> float:
        """Return the range up to which a marker is counted on [m]: ``max_range`` at every point within the margin."""
        return max(float(max_range) - self.margin, 0.0)


def estimate_floor(sensor) -> float:
    """Return the smallest estimate error the plan can certify after the dock's fix [m] (module docstring).

    Parameters
    ----------
    sensor : scenarios.schema.Sensor
        The declared sensor: its range noise bound is ``relative_error r + absolute_error``.

    Returns
    -------
    float
        ``2 absolute_error``: no fix's promise is smaller, so no later fix's pose bound is.
    """
    return 2.0 * float(sensor.absolute_error)


def sight_rule(sensor) -> SightRule:
    """Return the rule of a map's line of sight for a plan with this declared sensor (module docstring).

    It does not depend on ``eps_max``; a scheduled fix is held to its own, larger, pose bound.
    """
    return SightRule(margin=estimate_floor(sensor))
