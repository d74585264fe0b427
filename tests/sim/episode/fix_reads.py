"""The physics steps a fix measures at and the odometry reads an episode makes over it."""

from __future__ import annotations

import math

from sim.episode.driver import CONTROL_STEPS


def fix_reads(first_step: int, k: int, measurement_time: float, dt: float) -> tuple[list[int], list[int]]:
    """Return a fix's measurement steps and the steps the odometry is read at from the first one.

    Measurement j falls due ``j * measurement_time`` after the first and is taken at the first
    physics step at or after that (``sim.episode.drive``); the odometry is read at every control
    tick (each ``CONTROL_STEPS`` physics steps) and at each measurement's step, once per step (a
    measurement on a tick uses the tick's read).

    Parameters
    ----------
    first_step : int
        Physics step of the first measurement.
    k : int
        Measurements in the fix.
    measurement_time : float
        Time between them [s].
    dt : float
        Physics time step [s].

    Returns
    -------
    due : list of int
        The measurements' steps.
    reads : list of int
        The read steps from ``due[0]`` to ``due[-1]``, increasing.
    """
    due = [first_step + math.ceil(j * measurement_time / dt - 1e-9) for j in range(k)]
    ticks = set(range(0, due[-1] + 1, CONTROL_STEPS))
    return due, sorted(s for s in ticks | set(due) if s >= due[0])
