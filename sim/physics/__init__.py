"""The PyBullet side: world, robot and its URDF, laser sensor, wheel odometry.

The only package that imports pybullet."""
