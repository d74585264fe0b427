"""Physics settings of the PyBullet world (time step, solver, contact and geometry constants).

The defaults are chosen for speed: 20 solver iterations instead of pybullet's 50 (a step
costs ~0.75x; see ``benchmarks/physics.py``). The test
``tests/sim/physics/test_world.py::test_fast_config_tracks_reference`` shows that a fixed ~20 s
wheel-command sequence drives within 1 cm of :meth:`PhysicsConfig.reference` (pybullet's
defaults at 240 Hz); measured 3.5 mm (step commands) and 1.8 mm (ramped at 5 rad/s^2).
10 iterations drift 1.04 cm with step commands and a 60 Hz time step 1.8 cm, so neither is used.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

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
        Radius of the cylindrical marker posts [m].
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
    solver_iterations: int = 20
    gravity: float = 9.81
    floor_friction: float = 1.0
    wheel_friction: float = 1.0
    wheel_width: float = 0.03
    wheel_mass_fraction: float = 0.05
    caster_clearance: float = 0.002
    post_radius: float = 0.02
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
        """Return pybullet's own defaults (50 solver iterations at 240 Hz): the accuracy baseline."""
        return cls(solver_iterations=50)
