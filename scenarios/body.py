"""The simulated robot's body: its dimensions from a RobotSpec, and how far it reaches.

One derivation serves both the URDF the simulation builds (:mod:`sim.physics.robot` fills its
template from :func:`robot_geometry`) and the loader's check that the declared ``robot.radius``
contains that body (:func:`body_reach`): the planner keeps a disc of ``radius`` clear of every
obstacle, so a body reaching beyond it touches obstacles the plan says it passes.

The body seen from above (every part is within the height of the obstacles, 2 m walls):

- the chassis, a box ``chassis_length`` x ``chassis_width`` centred on the axle midpoint;
- two driven wheels at ``y = +-wheel_base / 2``: a cylinder ``WHEEL_WIDTH`` wide of the wheel's
  radius (its inertia), whose *contact shape* is a sphere of that radius (``diffdrive.urdf``),
  reaching ``wheel_base / 2 + radius`` sideways;
- two caster spheres on the centre line, at ``+-caster_x``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from scenarios.errors import SimulationError
from scenarios.schema import RobotSpec

WHEEL_WIDTH = 0.03
"""Width of each driven wheel [m] (``sim.physics.config.PhysicsConfig.wheel_width``'s default)."""
WHEEL_GAP = 0.01
"""Clearance between the chassis side and a wheel [m]."""


@dataclass(frozen=True)
class RobotGeometry:
    """Dimensions of the simulated robot, derived from a RobotSpec and the wheel width [m]."""

    left_radius: float
    right_radius: float
    axle_height: float
    chassis_length: float
    chassis_width: float
    chassis_height: float
    com_x: float
    """Chassis centre of mass ahead of the axle; puts a share of the weight on the front caster."""
    com_z: float
    """Height of the chassis' centre of mass relative to the axle (negative: below it)."""
    caster_radius: float
    caster_x: float
    top_height: float
    """Height of the highest point of the robot above the floor."""


FRONT_LOAD = 0.1
"""Share of the chassis weight the front caster carries [-]."""


def robot_geometry(spec: RobotSpec, wheel_width: float = WHEEL_WIDTH) -> RobotGeometry:
    """Derive the robot's dimensions from its spec.

    Parameters
    ----------
    spec : RobotSpec
        The actual (simulated) robot.
    wheel_width : float
        Width of each driven wheel [m].

    Returns
    -------
    RobotGeometry

    Raises
    ------
    SimulationError
        A wheel error of half the radius or more, or a wheel base too narrow for a chassis.
    """
    r, e, b, w = spec.wheel_radius, spec.wheel_radius_error, spec.wheel_base, wheel_width
    if not 0.0 <= abs(e) < 0.5:
        raise SimulationError(f"robot.wheel_radius_error: expected |e| < 0.5, got {e}")
    chassis_width = b - w - 2.0 * WHEEL_GAP
    if chassis_width <= 0.0:
        raise SimulationError(
            f"robot.wheel_base: expected more than wheel width + gaps ({w + 2 * WHEEL_GAP} m), got {b}")
    caster_radius = 0.5 * r
    # The chassis fits inside the footprint circle where it can (corners within spec.radius),
    # but is long enough to hold both casters and no longer than 1.5 wheel bases.
    half_outer = 0.5 * b + 0.5 * w
    fit = 2.0 * math.sqrt(max(spec.radius ** 2 - half_outer ** 2, 0.0))
    chassis_length = min(max(fit, 4.0 * caster_radius + 0.02), 1.5 * b)
    chassis_height = r
    return RobotGeometry(
        left_radius=r * (1.0 - e), right_radius=r * (1.0 + e), axle_height=r,
        chassis_length=chassis_length, chassis_width=chassis_width, chassis_height=chassis_height,
        com_x=FRONT_LOAD * (0.5 * chassis_length - caster_radius), com_z=-0.5 * r,
        caster_radius=caster_radius, caster_x=0.5 * chassis_length - caster_radius,
        top_height=max(r + 0.5 * chassis_height, 2.0 * r * (1.0 + abs(e))),
    )


@dataclass(frozen=True)
class Reach:
    """How far the body reaches from the axle midpoint, and which part reaches farthest.

    Attributes
    ----------
    distance : float
        Largest distance of a point of the body from the axle midpoint, seen from above [m].
    part : str
        The part that reaches it, with the formula (for messages).
    """

    distance: float
    part: str


def body_reach(spec: RobotSpec, wheel_width: float = WHEEL_WIDTH) -> Reach:
    """Return how far the simulated body reaches from its centre, seen from above.

    Parameters
    ----------
    spec : RobotSpec
        The actual (simulated) robot.
    wheel_width : float
        Width of each driven wheel [m].

    Returns
    -------
    Reach
        The largest of: the chassis' half diagonal; a wheel's contact sphere
        (``wheel_base / 2 + wheel radius``) and its cylinder (``hypot(wheel_base / 2 + width / 2,
        wheel radius)``); a caster sphere (``caster_x + caster radius``).
    """
    g = robot_geometry(spec, wheel_width)
    half = 0.5 * spec.wheel_base
    r_w = max(g.left_radius, g.right_radius)
    parts = [
        (math.hypot(0.5 * g.chassis_length, 0.5 * g.chassis_width),
         "chassis corners reach {d:.4g} m from its centre"),
        (half + r_w, "wheels reach {d:.4g} m from its centre (wheel_base/2 + wheel radius: "
                     "their contact spheres)"),
        (math.hypot(half + 0.5 * wheel_width, r_w),
         "wheels reach {d:.4g} m from its centre (wheel_base/2 + wheel width/2, wheel radius ahead)"),
        (g.caster_x + g.caster_radius, "casters reach {d:.4g} m from its centre"),
    ]
    d, text = max(parts, key=lambda p: p[0])
    return Reach(d, text.format(d=d))
