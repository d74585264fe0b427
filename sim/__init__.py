"""Does it hold: the PyBullet world (``sim.physics``) and the harness that runs and judges scenarios.

Only ``sim.physics`` imports pybullet, and only the ``sim.recording`` package imports rerun.
"""
