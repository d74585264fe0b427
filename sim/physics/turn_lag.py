"""The turn slip of an odometry read, from the number of physics steps it spans.

Bullet's integrator moves the body along its velocity at each step's start heading, so over a
read spanning ``m`` physics steps of equal turn the chord lags the arc's mid-heading by
``1 / (2 m)`` of the read's turn (:mod:`estimators.motion`, turn slip). A scenario declares
``RobotSpec.turn_slip`` for the control period's reads (``reference_steps`` = 4 physics steps:
0.125 of the integrator plus ~0.005 of the solver's compliance); a fix's measurements read the
encoders between control ticks, splitting a period into reads of 1-3 steps, whose lag is
``1 / 2``-``1 / 6`` of their turn from the integrator alone. With the declared constant for
those reads the filter's NEES over the 3 s after a 0.7 rad/s corner was 17.6-19.7 on
random-23-029 (slip 0.01 %, fine encoders), 3.7-3.9 with the per-read lag.
"""

from __future__ import annotations

INTEGRATOR_LAG = 0.5
"""The integrator's chord lag per read as a fraction of one physics step's turn [-]."""


def read_turn_slip(declared: float, steps: int, reference_steps: int) -> float:
    """Turn slip of a read spanning ``steps`` physics steps [-].

    Parameters
    ----------
    declared : float
        ``RobotSpec.turn_slip``: the turn slip of a read spanning ``reference_steps`` [-].
    steps : int
        Physics steps since the previous read; < 1 (no motion read) gives ``declared``.
    reference_steps : int
        Physics steps of the reads ``declared`` was measured on (the control period) [-].

    Returns
    -------
    float
        ``declared + INTEGRATOR_LAG (1 / steps - 1 / reference_steps)``: the solver's part of
        ``declared`` kept, the integrator's taken for this read's span.
    """
    if steps < 1:
        return declared
    return declared + INTEGRATOR_LAG * (1.0 / steps - 1.0 / reference_steps)
