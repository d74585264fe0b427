"""Physics settings of the PyBullet world (time step, solver, contact and geometry constants).

The solver runs pybullet's default 50 iterations. 20 were used for speed (a step costs ~0.75x,
see ``benchmarks/physics.py``) and tracked the reference within 1 cm, but that is not accurate
enough for a filter with a 0.1 mm laser: with 20 iterations the solver does not converge on the
wheel contacts and the small robot of ``paper-two-markers`` crabs sideways by 0.41 mm over a
3 m straight run (1.4e-4 rad), motion its encoders never see, and its filter fails NEES at 200
runs (3.218 against [2.853, 3.151]). With 50 iterations the crab is 0.075 mm (2.5e-5 rad) and
NEES 3.007; ``tests/sim/physics/test_world.py::test_built_in_robots_do_not_crab`` bounds it.
The time step stays at pybullet's 1/240 s: the turn slip of its integrator scales with it
(``RobotSpec.turn_slip``, see :mod:`estimators.motion`).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

from planner.pef.sight import REFLECTOR_RADIUS
from scenarios.body import WHEEL_WIDTH
from scenarios.errors import SimulationError


@dataclass(frozen=True)
class PhysicsConfig:
    """Settings of one :class:`~sim.physics.world.PhysicsWorld`.

    Attributes
    ----------
    time_step : float
        Physics time step [s]; pybullet's default is 1/240.
    solver_iterations : int
        Constraint-solver iterations per step (pybullet's default: 50).
    gravity : float
        Gravitational acceleration [m/s^2], pointing down -z.
    floor_friction : float
        Lateral friction coefficient of the floor (Bullet multiplies the two bodies' values).
    wheel_friction : float
        Lateral friction coefficient of the driven wheels.
    wheel_width : float
        Width of each driven wheel [m], for its inertia (the contact shape is a sphere of the
        wheel's radius: a point contact, see ``diffdrive.urdf``).
    wheel_mass_fraction : float
        Mass of each driven wheel as a fraction of the chassis mass [-].
    caster_clearance : float
        Gap between the casters and the floor when the chassis is level [m]: the robot rests
        on its two wheels (full weight on the driven wheels), the casters only stop pitching.
    post_radius : float
        Radius of the cylindrical marker posts [m]: the reflector's body of the planner's
        line-of-sight rule (:data:`planner.pef.sight.REFLECTOR_RADIUS`).
    post_height : float
        Height of the marker posts [m].
    laser_height : float
        Height of the laser above the floor [m]; must clear the robot and stay below the posts.
    wall_thickness : float
        Thickness of the border walls, which lie just outside the workspace rectangle [m].
    wall_height : float
        Height of border walls and obstacles [m].
    """

    time_step: float = 1.0 / 240.0
    solver_iterations: int = 50
    gravity: float = 9.81
    floor_friction: float = 1.0
    wheel_friction: float = 1.0
    wheel_width: float = WHEEL_WIDTH
    wheel_mass_fraction: float = 0.05
    caster_clearance: float = 0.002
    post_radius: float = REFLECTOR_RADIUS
    post_height: float = 1.0
    laser_height: float = 0.5
    wall_thickness: float = 0.2
    wall_height: float = 2.0

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if not v > 0:
                raise SimulationError(f"PhysicsConfig.{f.name}: expected a positive value, got {v!r}")
        if self.laser_height >= self.post_height:
            raise SimulationError(
                f"PhysicsConfig.laser_height: expected below post_height ({self.post_height}), "
                f"got {self.laser_height}")

    @classmethod
    def reference(cls) -> PhysicsConfig:
        """Return pybullet's own defaults (50 solver iterations at 240 Hz), which are ours."""
        return cls(solver_iterations=50)
