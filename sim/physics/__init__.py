"""The PyBullet side: world, robot and its URDF, laser sensor, wheel odometry.

The only package that imports pybullet (through :mod:`sim.physics.quiet`, which silences its
banner). Importing this package imports pybullet.
"""

from sim.physics.config import PhysicsConfig
from sim.physics.laser import LaserSensor, Measurement
from sim.physics.odometry import WheelOdometry, WheelTravel, encoder_ticks, integrate_arc
from sim.physics.robot import DiffDriveRobot
from sim.physics.world import PhysicsWorld

__all__ = [
    "DiffDriveRobot", "LaserSensor", "Measurement", "PhysicsConfig", "PhysicsWorld", "WheelOdometry",
    "WheelTravel", "encoder_ticks", "integrate_arc",
]
