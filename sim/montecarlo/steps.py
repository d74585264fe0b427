"""Which per-step rows a sweep keeps: ``pefsim mc --steps all|fixes|none``."""

from __future__ import annotations

from enum import Enum

from scenarios.errors import ScenarioError


class StepsMode(str, Enum):
    """Which per-step rows a sweep keeps (``pefsim mc --steps``)."""

    ALL = "all"
    FIXES = "fixes"
    NONE = "none"


def steps_mode(value: StepsMode | str) -> StepsMode:
    """Parse a ``steps`` value; raises a one-line ScenarioError for anything else."""
    try:
        return StepsMode(value)
    except ValueError:
        choices = ", ".join(m.value for m in StepsMode)
        raise ScenarioError(f"steps: expected one of {choices}, got {value!r}") from None
