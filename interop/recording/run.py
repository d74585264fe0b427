"""The recording of one Monte-Carlo run, a lone robot's or a fleet's: what a sweep's ``rrd_every`` writes."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from interop.recording import write_episode_rrd
from interop.recording.fleet import write_fleet_rrd
from scenarios.schema import Scenario


def write_run_rrd(path: str | os.PathLike[str], scenario: Scenario, result: Any, pef_map: Any = None) -> Path:
    """Write the recording of one run of ``scenario`` to ``path``.

    Parameters
    ----------
    path : str or path-like
        The ``.rrd`` file to write.
    scenario : Scenario
        The scenario the run drove.
    result : EpisodeResult or FleetResult
        The run's result: a fleet scenario's (``[[robots]]``) is a fleet result.
    pef_map : PefGrid, optional
        The PEF map to draw under the run.

    Returns
    -------
    Path
        ``path``.
    """
    if scenario.is_fleet:
        return write_fleet_rrd(path, scenario, result, pef_map=pef_map)
    return write_episode_rrd(path, scenario, result, pef_map=pef_map)
