"""A sweep run with a deliberately wrong model, and the mark it leaves in its directory.

``pefsim validate --q-scale Q`` multiplies the filter's process noise by ``Q`` to show that the
consistency checks fail on a filter that is wrong; ``pefsim validate --alone`` plans a fleet's
measurement schedules as if each robot drove alone (no traffic prediction) to show that the plan
check fails when the others are ignored (negative controls, nothing else). The sweep directory
then holds :data:`NEGATIVE_CONTROL_JSON`, so that validating it later (``--from``) says what it was.
"""

from __future__ import annotations

import json
import math
from functools import partial
from pathlib import Path

from scenarios.errors import OutputError, ScenarioError, SimulationError
from sim.montecarlo.engine import EpisodeApi, default_api
from sim.montecarlo.results import write_atomic

NEGATIVE_CONTROL_JSON = "negative-control.json"
"""Written into a sweep directory run as a negative control (``{"q_scale": 0.01, "alone": false}``)."""


def check_q_scale(q_scale: float) -> float:
    """Return ``q_scale`` as a float; raises :class:`SimulationError` unless it is positive and finite."""
    if not (isinstance(q_scale, (int, float)) and q_scale > 0 and math.isfinite(q_scale)):
        raise SimulationError(f"q_scale: expected a positive number, got {q_scale}")
    return float(q_scale)


def check_alone(scenario, alone: bool) -> bool:
    """Return ``alone`` as a bool; raise :class:`ScenarioError` if it is set for a scenario without ``[[robots]]``."""
    if alone and not scenario.robots:
        raise ScenarioError(f"{scenario.source}: alone: {scenario.name} is not a fleet scenario (no [[robots]])")
    return bool(alone)


def scaled_api(q_scale: float, alone: bool = False) -> EpisodeApi:
    """Return the real episode API with the filter's process noise times ``q_scale``.

    Parameters
    ----------
    q_scale : float
        Process-noise factor (> 0); 1 is the filter as declared (every robot's).
    alone : bool
        A fleet's schedules planned as if each robot drove alone (``default_api(traffic=False)``).

    Returns
    -------
    EpisodeApi
        :func:`~sim.montecarlo.engine.default_api` whose ``run_episode`` passes ``q_scale``.
    """
    api = default_api(traffic=not alone)
    q_scale = check_q_scale(q_scale)
    if q_scale == 1.0:
        return api
    return EpisodeApi(api.prepare, partial(api.run_episode, q_scale=q_scale), api.make_world, api.preload)


def mark(directory: str | Path, q_scale: float, alone: bool = False) -> None:
    """Record in sweep ``directory`` its filter's process noise factor and whether the fleet was planned alone."""
    write_atomic(Path(directory) / NEGATIVE_CONTROL_JSON,
                 (json.dumps({"q_scale": float(q_scale), "alone": bool(alone)}) + "\n").encode("utf-8"))


def read_mark(directory: str | Path) -> tuple[float, bool]:
    """Return ``(q_scale, alone)`` of sweep ``directory``: ``(1.0, False)`` without a mark.

    Raises
    ------
    OutputError
        The mark is unreadable.
    """
    control = Path(directory) / NEGATIVE_CONTROL_JSON
    if not control.exists():
        return 1.0, False
    try:
        doc = json.loads(control.read_text(encoding="utf-8"))
        alone = doc.get("alone", False)
        if not isinstance(alone, bool):
            raise TypeError(alone)
        return float(doc["q_scale"]), alone
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        raise OutputError(f"{control}: unreadable; expected {{\"q_scale\": <number>, \"alone\": <bool>}}") from None
