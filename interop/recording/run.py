"""The recording of one run, a lone robot's or a fleet's: what a sweep's ``rrd_every`` writes."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from interop.recording import write_episode_rrd
from interop.recording.fleet import write_fleet_rrd
from scenarios.schema import Scenario


def write_run_rrd(path: str | os.PathLike[str], scenario: Scenario, result: Any, pef_map: Any = None) -> Path:
    """Write the recording of one run of ``scenario`` to ``path``.

    Named robots (a fleet's) are recorded side by side (:func:`interop.recording.fleet.write_fleet_rrd`);
    a lone robot's episode as :func:`interop.recording.write_episode_rrd` records it.

    Parameters
    ----------
    path : str or path-like
        The ``.rrd`` file to write.
    scenario : Scenario
        The scenario the run drove.
    result : EpisodeResult or FleetResult
        The run's result (:func:`sim.episode.run.run`): both give their ``robots`` and ``names``.
    pef_map : PefGrid, optional
        The PEF map to draw under the run.

    Returns
    -------
    Path
        ``path``.
    """
    if result.names:
        return write_fleet_rrd(path, scenario, result, pef_map=pef_map)
    return write_episode_rrd(path, scenario, result.robots[0].result, pef_map=pef_map)
