"""A sweep run with a deliberately mis-tuned filter, and the mark it leaves in its directory.

``pefsim validate --q-scale Q`` multiplies the filter's process noise by ``Q`` to show that the
consistency checks fail on a filter that is wrong (a negative control, nothing else). The sweep
directory then holds :data:`NEGATIVE_CONTROL_JSON`, so that validating it later (``--from``)
says what it was.
"""

from __future__ import annotations

import json
import math
from functools import partial
from pathlib import Path

from scenarios.errors import SimulationError
from sim.montecarlo.engine import EpisodeApi, default_api
from sim.montecarlo.results import write_atomic

NEGATIVE_CONTROL_JSON = "negative-control.json"
"""Written into a sweep directory run with a mis-tuned filter (``{"q_scale": 0.01}``)."""


def check_q_scale(q_scale: float) -> float:
    """Return ``q_scale`` as a float; raises :class:`SimulationError` unless it is positive and finite."""
    if not (isinstance(q_scale, (int, float)) and q_scale > 0 and math.isfinite(q_scale)):
        raise SimulationError(f"q_scale: expected a positive number, got {q_scale}")
    return float(q_scale)


def scaled_api(q_scale: float) -> EpisodeApi:
    """Return the real episode API with the filter's process noise times ``q_scale``.

    Parameters
    ----------
    q_scale : float
        Process-noise factor (> 0); 1 is the filter as declared.

    Returns
    -------
    EpisodeApi
        :func:`~sim.montecarlo.engine.default_api` whose ``run_episode`` passes ``q_scale``.
    """
    from sim.episode import drive as episode

    api = default_api()
    q_scale = check_q_scale(q_scale)
    if q_scale == 1.0:
        return api
    return EpisodeApi(api.prepare, partial(episode.run_episode, q_scale=q_scale), api.make_world, api.preload)


def mark(directory: str | Path, q_scale: float) -> None:
    """Record in sweep ``directory`` that its runs used a filter with process noise times ``q_scale``."""
    write_atomic(Path(directory) / NEGATIVE_CONTROL_JSON,
                 (json.dumps({"q_scale": float(q_scale)}) + "\n").encode("utf-8"))
