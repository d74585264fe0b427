"""Each wheel's encoder phase advance over an odometry read, predicted from the wheel command.

Why (the derivation is in ``docs/design.md`` §6): a read's count error is ``q_old - q_new``, the
difference of the residuals below the last tick edge at its two ends. For a wheel phase uniform
over a tick and a read that turns the wheel ``n + f`` ticks, known to ``sigma`` ticks, its
variance is ``sum_m 2 (1 - cos(2 pi m f) exp(-2 pi^2 m^2 sigma^2)) / (2 pi^2 m^2)`` tick^2:
``f (1 - f)`` when the travel is known, the ``1/6`` of independent residuals when it is not
(sigma >~ 0.3). Across the runs of a sweep a fix's read windows turn the wheels the same to
~0.005 ticks: the filter must know ``f``, so it must know how far each wheel turned, to a
fraction of a tick, without the count it is modelling the error of.

The prediction: the wheel turns at its commanded rate over the read's span,
``T = omega_cmd * m * step_time * ticks_per_rev / (2 pi)`` ticks for a read spanning ``m``
physics steps. Its uncertainty assumes the wheel's tracking error per step over the read is what
it was over the history before it (``WINDOW`` physics steps, :func:`sigma_per_step`): there the
counted minus the commanded turn is ``D`` ticks, which holds the count's own residual difference
and the readings' slip besides the tracking, so ``sigma = m sqrt(D^2 + 1/4 + slip part) / span``.
Measured over the read windows of random-23-016 and random-23-030: the commanded
rate predicts the travel to 0.0002-0.0015 ticks (median), well inside such a sigma. The fix
snapshot uses it over a fix's shifts, a few physics steps (:func:`estimators.fault.carried.count_cov`),
the filter for the part of the residual it does not carry as harmonics, over a read
(:mod:`estimators.motion_quantised`). The drive holds each wheel to its command's integral
(``sim.physics.robot``, a position loop), so the phase at every read boundary is the start's plus
the commanded turn since, whatever the lag: the filter carries the residual's harmonics through
the commanded sums (:func:`boundaries`) from the first read on. With no span (``STEPS``
``UNKNOWN_SPAN``: a filter used outside an episode) the read's turn is not predicted: it starts a
new segment, and ``sigma`` is infinite; so it is while the history is shorter than half a
``WINDOW``. A read of span 0 (a second read at the same physics step: the robot stopped at its
goal) turns the wheels by 0, exactly.

State (float64, shape ``(RECENT0 + BOUNDARY * BOUNDARIES,)``, :func:`new_state`): the command,
the read's span, constants, running sums [ticks], a ring of checkpoints (``ENTRY`` running sums
each) and a ring of the last read boundaries (:func:`boundaries`).
"""

from __future__ import annotations

import math

import numpy as np

from jit import compiled

CMD_LEFT, CMD_RIGHT, STEPS, TICKS_PER_RAD, STEP_TIME, NOW, COUNT_L, COUNT_R, CMD_SUM_L, CMD_SUM_R, \
    TICK, HEAD, FILLED, SLIP_VAR, SQ_L, SQ_R, PER_L, PER_R, SEGMENT, NEWEST = range(20)
HEAD0 = 20
#: entries of a past read in the ring: step, counted (l, r), commanded (l, r), sum d^2 (l, r)
ENTRY = 7
#: history the tracking error is read from [physics steps] (4 s at 240 Hz): long enough for the
#: count's residuals and the slip to be a small part of it (the count's 1/2 tick is 5e-4 tick per
#: step)
WINDOW = 960
#: the history keeps the first read past every CHECKPOINT physics steps
CHECKPOINT = 16
#: checkpoints kept
RING = WINDOW // CHECKPOINT + 8
#: read boundaries kept, the read just recorded's two ends (:mod:`estimators.motion_quantised`):
#: commanded sum left, right [ticks], step, segment (a read whose turn is not predicted starts a
#: new segment)
BOUNDARIES = 2
BOUNDARY = 4
RECENT0 = HEAD0 + ENTRY * RING
#: ``STEPS`` of a read whose span is not known (0 is a span: a read at the step of the last one)
UNKNOWN_SPAN = -1.0


def new_state(encoder_ticks: int, wheel_radius: float, step_time: float | None, slip_std: float = 0.0) -> np.ndarray:
    """Return a phase state for wheels of ``encoder_ticks`` per revolution.

    Parameters
    ----------
    encoder_ticks : int
        Ticks per wheel revolution.
    wheel_radius : float
        Nominal wheel radius [m] (the odometry converts counts with it).
    step_time : float or None
        Physics step [s]; None: spans are never known and every sigma is infinite.
    slip_std : float
        The floor's random slip per unit of a read's travel [-] (``RobotSpec.odometry_noise``):
        it is in the counted travel the tracking error is read from.
    """
    s = np.zeros(RECENT0 + BOUNDARY * BOUNDARIES)   # every boundary at the start, segment 0
    s[SLIP_VAR] = slip_std * slip_std
    s[TICKS_PER_RAD] = encoder_ticks / (2.0 * math.pi)
    s[STEP_TIME] = 0.0 if step_time is None else float(step_time)
    s[TICK] = 2.0 * math.pi * wheel_radius / encoder_ticks
    s[FILLED] = 1.0   # the start: step 0, nothing counted or commanded
    s[STEPS] = UNKNOWN_SPAN
    return s


@compiled.njit(cache=True)
def sigma_per_step(state):
    """Return the std of each wheel's turn per physics step about the commanded rate [ticks] (inf: unknown).

    Over the history since the newest checkpoint at least ``WINDOW`` steps old (else the oldest
    kept; unknown while it spans less than half a window), ``span`` steps: the counted minus the
    commanded turn ``D`` is the tracking error plus the count's residual difference (std at
    most 1/2 tick) plus the slip in the readings (``slip^2 sum d^2``). The tracking error's rate
    is taken as ``D / span`` give or take those: ``sqrt(D^2 + 1/4 + slip^2 sum d^2) / span``.
    """
    now, head, filled = state[NOW], int(state[HEAD]), int(state[FILLED])
    j = head
    for _ in range(filled - 1):
        if state[HEAD0 + ENTRY * j] <= now - WINDOW:
            break
        j = (j - 1) % RING
    o = HEAD0 + ENTRY * j
    span = now - state[o]
    if span < 0.5 * WINDOW:
        return math.inf, math.inf
    dev_l = (state[COUNT_L] - state[o + 1]) - (state[CMD_SUM_L] - state[o + 3])
    dev_r = (state[COUNT_R] - state[o + 2]) - (state[CMD_SUM_R] - state[o + 4])
    slip_l = state[SLIP_VAR] * (state[SQ_L] - state[o + 5])
    slip_r = state[SLIP_VAR] * (state[SQ_R] - state[o + 6])
    return (math.sqrt(dev_l * dev_l + 0.25 + slip_l) / span,
            math.sqrt(dev_r * dev_r + 0.25 + slip_r) / span)


def count_error_var(turn, sigma) -> np.ndarray:
    """Variance of a window's count error for a phase uniform over a tick [tick^2].

    ``sum_m 2 (1 - cos(2 pi m f) exp(-2 pi^2 m^2 sigma^2)) / (2 pi^2 m^2)`` for a window that
    turns the wheel ``turn`` ticks (fractional part ``f``), known to ``sigma`` ticks (module
    docstring): ``f (1 - f)`` for sigma 0, 1/6 (two independent residuals) for sigma infinite.

    Parameters
    ----------
    turn, sigma : array_like
        Predicted turn [ticks] and its standard deviation [ticks] (inf allowed), broadcast.

    Returns
    -------
    numpy.ndarray
        Variance [tick^2], in ``[0, 1/4]``.
    """
    turn, sigma = np.broadcast_arrays(np.asarray(turn, dtype=float), np.asarray(sigma, dtype=float))
    f = turn - np.floor(turn)
    exact = f * (1.0 - f)
    m = np.arange(1, _SERIES_TERMS + 1)
    with np.errstate(over="ignore", invalid="ignore"):
        damp = np.exp(-2.0 * (np.pi * m * sigma[..., None]) ** 2)
    series = np.sum((1.0 - np.cos(2.0 * np.pi * m * f[..., None]) * damp) / (np.pi * m) ** 2, axis=-1)
    # the tail past the last term: its cosines average out, leaving sum 1 / (pi m)^2 (4e-4 tick^2)
    tail = 1.0 / 6.0 - np.sum(1.0 / (np.pi * m) ** 2)
    out = np.where(sigma > 0.0, series + tail, exact)
    return np.where(np.isinf(sigma), 1.0 / 6.0, out)


#: terms of count_error_var's series
_SERIES_TERMS = 256


@compiled.njit(cache=True)
def phase_advance(state, d_left, d_right):
    """Predict each wheel's turn over this read [ticks] and its uncertainty; record the read.

    Parameters
    ----------
    state : ndarray
        :func:`new_state`'s array, with ``CMD_LEFT``/``CMD_RIGHT`` the wheel rates commanded
        over the read [rad/s] and ``STEPS`` its span [physics steps] (``UNKNOWN_SPAN``: not
        known); updated.
    d_left, d_right : float
        The read's wheel travel from the encoders [m].

    Returns
    -------
    turn_left, turn_right, sigma_left, sigma_right : float
        Predicted turn [ticks] and its standard deviation [ticks] (inf: unknown).
    """
    m = state[STEPS]
    if not (m >= 0.0 and state[STEP_TIME] > 0.0):
        state[PER_L] = state[PER_R] = math.inf
        _push_boundary(state, state[SEGMENT] + 1.0)
        return 0.0, 0.0, math.inf, math.inf
    k = state[TICKS_PER_RAD] * state[STEP_TIME] * m
    turn_l, turn_r = state[CMD_LEFT] * k, state[CMD_RIGHT] * k
    per_l, per_r = sigma_per_step(state)
    sig_l, sig_r = (m * per_l, m * per_r) if m > 0.0 else (0.0, 0.0)
    now, head, filled = state[NOW], int(state[HEAD]), int(state[FILLED])
    state[NOW] = now + m
    cl, cr = d_left / state[TICK], d_right / state[TICK]
    state[COUNT_L] += cl
    state[COUNT_R] += cr
    state[SQ_L] += cl * cl
    state[SQ_R] += cr * cr
    state[CMD_SUM_L] += turn_l
    state[CMD_SUM_R] += turn_r
    if math.floor(state[NOW] / CHECKPOINT) > math.floor(now / CHECKPOINT):   # a checkpoint passed
        head = (head + 1) % RING
        o = HEAD0 + ENTRY * head
        state[o], state[o + 1], state[o + 2] = state[NOW], state[COUNT_L], state[COUNT_R]
        state[o + 3], state[o + 4] = state[CMD_SUM_L], state[CMD_SUM_R]
        state[o + 5], state[o + 6] = state[SQ_L], state[SQ_R]
        state[HEAD] = head
        state[FILLED] = min(filled + 1, RING)
    state[STEPS] = UNKNOWN_SPAN   # a span is set for each read
    state[PER_L], state[PER_R] = per_l, per_r
    _push_boundary(state, state[SEGMENT])
    return turn_l, turn_r, sig_l, sig_r


@compiled.njit(cache=True)
def _push_boundary(state, segment):
    """Record the read boundary just passed: the commanded sums, the step, its ``segment``."""
    newest = (int(state[NEWEST]) + 1) % BOUNDARIES
    o = RECENT0 + BOUNDARY * newest
    state[o], state[o + 1], state[o + 2], state[o + 3] = state[CMD_SUM_L], state[CMD_SUM_R], state[NOW], segment
    state[NEWEST] = newest
    state[SEGMENT] = segment


@compiled.njit(cache=True)
def boundaries(state, wheel, turns, steps, segments):
    """Fill the last ``BOUNDARIES`` read boundaries, newest first.

    Parameters
    ----------
    state : ndarray
        :func:`new_state`'s array.
    wheel : int
        0 left, 1 right.
    turns, steps, segments : ndarray, shape (BOUNDARIES,)
        Filled: the wheel's commanded turn since the start [ticks], the physics step and the
        segment at each boundary (boundaries of different segments are not related by a
        predicted turn).

    Returns
    -------
    float
        The wheel's tracking sigma per physics step [ticks] (:func:`sigma_per_step`, inf: unknown).
    """
    newest = int(state[NEWEST])
    for k in range(BOUNDARIES):
        o = RECENT0 + BOUNDARY * ((newest - k) % BOUNDARIES)
        turns[k] = state[o + wheel]
        steps[k] = state[o + 2]
        segments[k] = state[o + 3]
    return state[PER_L + wheel]


# numba keys a cache on its own file only: flush the kernels above when a file they inline changed
compiled.keep_fresh(__name__)
