"""Each wheel's encoder phase advance over an odometry read, predicted from the wheel command.

Why (the derivation is in ``docs/design.md`` §6): a read's count error is ``q_old - q_new``, the
difference of the residuals below the last tick edge at its two ends. For a wheel phase uniform
over a tick and a read that turns the wheel ``n + f`` ticks, known to ``sigma`` ticks, its
variance is ``sum_m 2 (1 - cos(2 pi m f) exp(-2 pi^2 m^2 sigma^2)) / (2 pi^2 m^2)`` tick^2:
``f (1 - f)`` when the travel is known, the ``1/6`` of independent residuals when it is not
(sigma >~ 0.3). Across the runs of a sweep a fix's read windows turn the wheels the same to
~0.005 ticks: the filter must know ``f``, so it must know how far each wheel turned, to a
fraction of a tick, without the count it is modelling the error of.

The prediction: the wheel turns at its commanded rate plus the velocity loop's steady offset
over the read's span of ``m`` physics steps, ``T = (omega_cmd a + D / span) m`` ticks, with
``a = step_time ticks_per_rev / (2 pi)`` and ``D`` the counted minus the commanded turn over the
history (``WINDOW`` physics steps, :func:`tracking`), taken where it stands out of its noise
(else 0, with ``|D|`` in the spread). Bullet's wheels, measured (issue 23),
turn 3e-4 to 9e-4 rad/s short of their command under load, steadily; their rate wanders about
that by 5e-5 to 1e-4 of the command, correlated over 40-150 steps; after a command change the
first step keeps ~0.1 of the change. The read's ``sigma`` holds what that prediction does not
know:

- the offset's own error (the count residuals at the history's ends, the readings' slip, the
  turn the loop lost to the history's command change), times ``m`` (:func:`tracking`);
- the loop's lag after this read's command change ``dw``: ``lambda`` in ``[0, 1]`` of one step
  of it, uniform, mean square ``(a dw)^2 / 3``;
- the rate's wander, a random walk: ``rate_diffusion (omega_cmd a)^2 m``
  (``sim.physics.robot.RATE_DIFFUSION`` for the simulated motors).

The last two are summed per wheel (``LOOSE_L``/``LOOSE_R``) for the snapshot's windows
(:func:`estimators.fault.carried.count_cov`). With the commanded rate alone and the history's
``|D|`` as a spread instead (the model before this one), random-23-029 was overconfident (NEES
3.85: each read's phase fell 0.006 tick behind, coherently) and random-23-030 too (3.22). With no
span (``STEPS`` 0: a filter used outside an episode) or too short a history, ``sigma`` is
infinite: the residuals are independent from read to read.

State (float64, shape ``(HEAD0 + ENTRY * RING,)``, :func:`new_state`): the command and the one
before, the read's span, constants, running sums [ticks, tick^2] and a ring of checkpoints
(``ENTRY`` entries each).
"""

from __future__ import annotations

import math

import numpy as np

from jit import compiled

CMD_LEFT, CMD_RIGHT, STEPS, TICKS_PER_RAD, STEP_TIME, NOW, COUNT_L, COUNT_R, CMD_SUM_L, CMD_SUM_R, \
    TICK, HEAD, FILLED, SLIP_VAR, SQ_L, SQ_R, PREV_LEFT, PREV_RIGHT, LOOSE_L, LOOSE_R, DIFFUSION = range(21)
HEAD0 = 21
#: entries of a past read in the ring: step, counted (l, r), commanded (l, r), sum d^2 (l, r),
#: the read's commanded rate (l, r)
ENTRY = 9
#: history the tracking error is read from [physics steps] (4 s at 240 Hz): long enough for the
#: count's residuals and the slip to be a small part of it (the count's 1/2 tick is 5e-4 tick per
#: step; a fix's reads then keep even the 8th harmonic's phase: rho_8 > 0.99)
WINDOW = 960
#: the history keeps the first read past every CHECKPOINT physics steps
CHECKPOINT = 16
#: checkpoints kept
RING = WINDOW // CHECKPOINT + 8


def new_state(encoder_ticks: int, wheel_radius: float, step_time: float | None, slip_std: float = 0.0,
              rate_diffusion: float = 0.0) -> np.ndarray:
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
    rate_diffusion : float
        The velocity loop's rate wander about its steady offset, as the growth per physics step of
        the variance of the turn relative to the commanded turn [-]: a read's turn about the
        history's rate has variance ``rate_diffusion (commanded turn per step)^2`` per step.
    """
    s = np.zeros(HEAD0 + ENTRY * RING)
    s[SLIP_VAR] = slip_std * slip_std
    s[DIFFUSION] = rate_diffusion
    s[TICKS_PER_RAD] = encoder_ticks / (2.0 * math.pi)
    s[STEP_TIME] = 0.0 if step_time is None else float(step_time)
    s[TICK] = 2.0 * math.pi * wheel_radius / encoder_ticks
    s[FILLED] = 1.0   # the start: step 0, nothing counted or commanded
    return s


@compiled.njit(cache=True)
def tracking(state):
    """Each wheel's turn per physics step about the commanded rate, and its std [ticks] (std inf: unknown).

    Over the history since the newest checkpoint at least ``WINDOW`` steps old (else the oldest
    kept; unknown while it spans less than half a window), ``span`` steps, the counted minus the
    commanded turn ``D`` is the wheel's steady tracking error (a rate: the velocity loop's offset
    under load, 1.6e-3 tick per step on random-23-029's wheels, the same to 1 % at every step)
    plus three errors taken as its uncertainty:

    - the count's residual difference at the history's ends (std at most 1/2 tick);
    - the slip in the readings (``slip^2 sum d^2``);
    - the turn the velocity loop lost to the history's command change ``dW`` (the rate at its
      end minus the rate at its start, as turn per step: ``a = ticks_per_rad * step_time``):
      after a change the wheel lags the integral of its command by a part ``lambda`` in
      ``[0, 1]`` of one step of the change (0.10 in Bullet's solver, measured on
      random-23-030), uniform: mean square ``(a dW)^2 / 3``.

    Returns
    -------
    rate_left, rate_right, std_left, std_right : float
        ``D / span`` and ``sqrt((a dW)^2 / 3 + 1/4 + slip^2 sum d^2) / span`` [ticks per step]
        where ``|D|`` exceeds twice that noise; else 0 and ``sqrt(D^2 + noise) / span``.
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
        return 0.0, 0.0, math.inf, math.inf
    dev_l = (state[COUNT_L] - state[o + 1]) - (state[CMD_SUM_L] - state[o + 3])
    dev_r = (state[COUNT_R] - state[o + 2]) - (state[CMD_SUM_R] - state[o + 4])
    slip_l = state[SLIP_VAR] * (state[SQ_L] - state[o + 5])
    slip_r = state[SLIP_VAR] * (state[SQ_R] - state[o + 6])
    a = state[TICKS_PER_RAD] * state[STEP_TIME]
    lost_l = a * (state[PREV_LEFT] - state[o + 7])
    lost_r = a * (state[PREV_RIGHT] - state[o + 8])
    noise_l = lost_l * lost_l / 3.0 + 0.25 + slip_l
    noise_r = lost_r * lost_r / 3.0 + 0.25 + slip_r
    # A rate error persists from read to read: the phase error it leaves grows with the number
    # of reads, which the phasors' per-read forgetting cannot follow. So the offset is taken
    # only where it stands out of its own noise, at two standard deviations (random-23-029: 1.5
    # ticks over the history against 0.5); where the readings' slip swamps it (random-23-016:
    # 1.3 ticks of slip against an offset of 0.1), correcting by D / span would turn the slip
    # into a persistent error of that size (NEES 3.47 over 24 runs, 2.97 with the gate), and
    # |D| counts as the spread instead, as before the offset was taken.
    take_l = dev_l * dev_l > 4.0 * noise_l
    take_r = dev_r * dev_r > 4.0 * noise_r
    rest_l = 0.0 if take_l else dev_l
    rest_r = 0.0 if take_r else dev_r
    return (dev_l / span if take_l else 0.0, dev_r / span if take_r else 0.0,
            math.sqrt(rest_l * rest_l + noise_l) / span,
            math.sqrt(rest_r * rest_r + noise_r) / span)


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
        over the read [rad/s] and ``STEPS`` its span [physics steps]; updated.
    d_left, d_right : float
        The read's wheel travel from the encoders [m].

    Returns
    -------
    turn_left, turn_right, sigma_left, sigma_right : float
        Predicted turn [ticks] and its standard deviation [ticks] (inf: unknown).
    """
    m = state[STEPS]
    a = state[TICKS_PER_RAD] * state[STEP_TIME]
    if not (m > 0.0 and a > 0.0):
        state[PREV_LEFT], state[PREV_RIGHT] = state[CMD_LEFT], state[CMD_RIGHT]
        return 0.0, 0.0, math.inf, math.inf
    rate_l, rate_r, per_l, per_r = tracking(state)
    cmd_l, cmd_r = state[CMD_LEFT] * a, state[CMD_RIGHT] * a   # commanded turn per step [ticks]
    # what the history does not predict: the velocity loop's lag after this read's command change
    # (tracking(): lambda in [0, 1], mean square a third of one step of the change) and the
    # rate's wander over the read
    step_l = cmd_l - state[PREV_LEFT] * a
    step_r = cmd_r - state[PREV_RIGHT] * a
    state[PREV_LEFT], state[PREV_RIGHT] = state[CMD_LEFT], state[CMD_RIGHT]
    loose_l = step_l * step_l / 3.0 + state[DIFFUSION] * cmd_l * cmd_l * m
    loose_r = step_r * step_r / 3.0 + state[DIFFUSION] * cmd_r * cmd_r * m
    state[LOOSE_L] += loose_l
    state[LOOSE_R] += loose_r
    turn_l, turn_r = (cmd_l + rate_l) * m, (cmd_r + rate_r) * m
    sig_l = math.sqrt((m * per_l) ** 2 + loose_l)
    sig_r = math.sqrt((m * per_r) ** 2 + loose_r)
    now, head, filled = state[NOW], int(state[HEAD]), int(state[FILLED])
    state[NOW] = now + m
    cl, cr = d_left / state[TICK], d_right / state[TICK]
    state[COUNT_L] += cl
    state[COUNT_R] += cr
    state[SQ_L] += cl * cl
    state[SQ_R] += cr * cr
    state[CMD_SUM_L] += cmd_l * m
    state[CMD_SUM_R] += cmd_r * m
    if math.floor(state[NOW] / CHECKPOINT) > math.floor(now / CHECKPOINT):   # a checkpoint passed
        head = (head + 1) % RING
        o = HEAD0 + ENTRY * head
        state[o], state[o + 1], state[o + 2] = state[NOW], state[COUNT_L], state[COUNT_R]
        state[o + 3], state[o + 4] = state[CMD_SUM_L], state[CMD_SUM_R]
        state[o + 5], state[o + 6] = state[SQ_L], state[SQ_R]
        state[o + 7], state[o + 8] = state[CMD_LEFT], state[CMD_RIGHT]
        state[HEAD] = head
        state[FILLED] = min(filled + 1, RING)
    state[STEPS] = 0.0   # a span is set for each read
    return turn_l, turn_r, sig_l, sig_r


# numba keys a cache on its own file only: flush the kernels above when a file they inline changed
compiled.keep_fresh(__name__)
