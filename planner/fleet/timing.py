"""A fleet robot's declared timing spread: what each run draws, and the lag model it implies.

Real fleets do not keep time like a clock: a robot is released late, stands at a dock a while,
drives a little slower than planned. A ``[[robots]]`` table declares how much
(:class:`scenarios.schema.FleetRobot`):

* ``start_jitter`` J [s]: the robot leaves its first dock ``start_time + U`` with U uniform on
  [0, J] (mean J / 2, variance J^2 / 12);
* ``dwell`` W [s]: at each dock between two of its tasks (and at its last task's dock when it
  drives on to its parking place) it stands uniform on [0, W] before the next leg (mean W / 2,
  variance W^2 / 12 each, independent);
* ``speed_spread`` s: it drives at f times its planned speeds for the whole run, f uniform on
  [1 - s, 1]; never faster, since the measurement schedule's promises assume at most the
  planned speed. A stretch planned to take d seconds then takes d / f: a lag of d (1 / f - 1),
  with mean ``m d`` and variance ``v d^2``, ``m = E[1/f] - 1`` and ``v = Var[1/f]``,
  ``E[1/f] = ln(1 / (1 - s)) / s`` and ``E[1/f^2] = 1 / (1 - s)`` (exact for the uniform f).
  The lag of one robot at two places is fully correlated in this part (one f per run).

:func:`draw` gives a run's numbers from the run's own stream (:func:`stream`, spawned from the
episode's seed under its own key, so that the other streams draw what they drew before and the
same seed gives the same numbers whatever the workers); a robot that declares nothing draws
exactly 0, 0 and 1, which leaves its drive as it was. :func:`declared_model` adds the spread to
the simulated robots' own lag model (:data:`planner.fleet.blocking.TIMING`), which the blocking
prediction uses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from planner.fleet.blocking import TIMING, TimingModel
from scenarios.schema import FleetRobot

#: spawn key (after the episode's own) of the timing streams: 0-3 are a robot's start, laser,
#: odometry and block streams, 4 the other robots' roots (sim.episode.fleet)
TIMING_KEY = 5


@dataclass(frozen=True)
class TimingDraw:
    """One run's timing of one robot.

    Attributes
    ----------
    release_delay : float
        Added to its ``start_time`` [s].
    dwell : tuple of float
        Stand at the dock ending each of its tasks but the last [s].
    speed_factor : float
        Multiplies its planned speeds, in (0, 1].
    """

    release_delay: float
    dwell: tuple[float, ...]
    speed_factor: float


def stream(ss: np.random.SeedSequence, i: int) -> np.random.Generator:
    """Return robot i's timing stream of the episode rooted at ``ss``."""
    return np.random.default_rng(np.random.SeedSequence(ss.entropy, spawn_key=(*ss.spawn_key, TIMING_KEY, i)))


def draw(fr: FleetRobot, rng: np.random.Generator, legs: int | None = None) -> TimingDraw:
    """Draw one run's release delay, dwells and speed factor of robot ``fr`` (module docstring).

    Always draws the same count of numbers (one, one per dock, one), so that a robot's later
    draws do not depend on which spreads are declared; a spread of 0 gives exactly 0 (or 1).
    ``legs``: the legs it drives (default its tasks; one more when it drives on to its parking
    place, :mod:`planner.fleet.parking`, and then dwells at its last task's dock as at the others).
    """
    u = rng.random((len(fr.tasks) if legs is None else legs) + 1)
    return TimingDraw(release_delay=float(fr.start_jitter * u[0]),
                      dwell=tuple(float(fr.dwell * x) for x in u[1:-1]),
                      speed_factor=float(1.0 - fr.speed_spread * u[-1]))


def speed_moments(spread: float) -> tuple[float, float]:
    """Mean and variance of ``1 / f - 1`` for f uniform on [1 - spread, 1] (s/s, s^2/s^2)."""
    if spread <= 0.0:
        return 0.0, 0.0
    inv = -math.log1p(-spread) / spread
    return inv - 1.0, max(1.0 / (1.0 - spread) - inv * inv, 0.0)


def declared_model(fr: FleetRobot, docks: np.ndarray | tuple = (), base: TimingModel = TIMING) -> TimingModel:
    """Return robot ``fr``'s lag model: the simulated robots' own (``base``) plus its declared spread.

    Parameters
    ----------
    fr : FleetRobot
    docks : array_like of float
        Planned time driven [s] when it reaches each dock between two of its tasks.
    base : TimingModel
    """
    m, v = speed_moments(fr.speed_spread)
    j, w = fr.start_jitter, fr.dwell
    return replace(base, lag0=base.lag0 + j / 2.0, base_var=base.base_var + j * j / 12.0,
                   lag_rate=base.lag_rate + m, var_quad=base.var_quad + v,
                   docks=tuple(float(d) for d in np.asarray(docks, float).reshape(-1)),
                   dwell_mean=w / 2.0, dwell_var=w * w / 12.0, tie_wait=j > 0 or w > 0 or fr.speed_spread > 0)
