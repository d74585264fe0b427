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

The margin is ``eps_max + TRACKING_ALLOWANCE``: the plan keeps the robot's *estimate* within
``eps_max`` of the truth, and the follower keeps the estimate within the tracking error of the
planned path. The tracking term is not derived here: :data:`TRACKING_ALLOWANCE` is the largest
distance measured between a fix's true position and its planned pose (see its note). It only
narrows the subsets the schedule tries: each scheduled measurement is then held to its own derived
pose bound (:mod:`planner.schedule.sightcheck`), so where the allowance is too small the schedule
searches again; it never makes a plan count on a line of sight the robot may lose.
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

#: The follower's tracking error allowed for [m]: the largest distance between a fix's true
#: position and the planned path in episodes of ``hall`` (both tasks), ``warehouse`` (both) and
#: ``paper-docks``, seeds 1-3, was 0.119 m (p99 0.10-0.11 m), rounded up to the centimetre.
#: Measured, not derived: the schedule holds each fix to its derived bound (module docstring).
TRACKING_ALLOWANCE = 0.12


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


def sight_rule(eps_max: float) -> SightRule:
    """Return the rule for a plan that keeps the position estimate within ``eps_max`` [m] of the truth."""
    return SightRule(margin=float(eps_max) + TRACKING_ALLOWANCE)
