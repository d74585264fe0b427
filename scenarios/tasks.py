"""The one check of a task index, for every layer that is given one (planning, a run, a sweep)."""

from __future__ import annotations

import numpy as np

from scenarios.errors import ScenarioError
from scenarios.schema import Scenario


def check_task(scenario: Scenario, task: object) -> int:
    """Return ``task`` as an int when it indexes ``scenario.tasks``.

    Parameters
    ----------
    scenario : Scenario
    task : int
        0-based index into ``scenario.tasks``.

    Returns
    -------
    int

    Raises
    ------
    ScenarioError
        One line naming the parameter ``task``, the valid range and the scenario's file.
    """
    n = len(scenario.tasks)
    if n == 0:
        raise ScenarioError(f"{scenario.source}: tasks: expected at least one [[tasks]] entry, got none (task {task})")
    index = isinstance(task, (int, np.integer)) and not isinstance(task, bool)
    if not (index and 0 <= task < n):
        raise ScenarioError(f"task: expected 0 .. {n - 1} ({n} tasks in {scenario.source}), "
                            f"got {task if index else repr(task)}")
    return int(task)
