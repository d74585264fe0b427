"""The simulation: the PyBullet world, one episode in it, Monte-Carlo sweeps of episodes.

``sim.physics``, ``sim.episode`` and ``sim.montecarlo``. Only ``sim.physics`` imports pybullet.
"""
