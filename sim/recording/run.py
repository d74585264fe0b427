"""A recording of one run, whoever drove it: a lone robot's episode or a fleet's (:func:`sim.episode.run.run`)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from scenarios.schema import Scenario
from sim.recording import write_episode_rrd
from sim.recording.fleet import write_fleet_rrd


def write_run_rrd(path: str | os.PathLike[str], scenario: Scenario, result: Any, pef_map: Any = None) -> Path:
    """Write a recording of a run's :class:`~sim.episode.fleet.FleetResult`; returns the path.

    Named robots are recorded side by side (:func:`sim.recording.fleet.write_fleet_rrd`); a lone
    robot's episode as :func:`sim.recording.write_episode_rrd` records it.
    """
    if result.names:
        return write_fleet_rrd(path, scenario, result, pef_map=pef_map)
    return write_episode_rrd(path, scenario, result.robots[0].result, pef_map=pef_map)
