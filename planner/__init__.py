"""Where to go and where to put markers.

PEF models and maps, visibility, routes, grid planning, the measurement schedule and marker
placement. Depends on ``scenarios`` and ``estimators``; never imports pybullet or rerun.
"""
