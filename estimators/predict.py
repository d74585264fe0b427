"""The Localizer's predict step as one compiled kernel over its state arrays.

Kept apart from :mod:`estimators.ekf` (which re-exports it) so that a control loop can call it
from compiled code (``sim.episode.control_tick``). Which motion model runs is chosen by
``params``: with ``QUANT_VAR > 0`` the encoder residuals are states
(:func:`estimators.motion_quantised.propagate_moments_quantised`), else the pose alone or the
pose with the wheel-radius error (:mod:`estimators.motion`).
"""

from __future__ import annotations

import math

from estimators import motion
from estimators.encoder_phase import phase_advance
from estimators.motion_quantised import propagate_moments_quantised
from jit import compiled

# Localizer.predict_params (float64, shape (8,)): what a predict step needs besides x and P.
WHEEL_BASE, REL_VAR, BASE_VAR, Q_SCALE, WALK_VAR, BIASED, QUANT_VAR, TURN_SLIP = range(8)


@compiled.njit(cache=True)
def predict_step(x, P, d_left, d_right, params, phase):
    """Run the Localizer's predict on its state arrays, in place (see :meth:`Localizer.predict`).

    Compiled so that a control loop can call it from compiled code (``sim.episode.control_tick``).

    Parameters
    ----------
    x, P : ndarray, shape (n,), (n, n), n in (3, 4, 5, 6)
        The filter's state and covariance (:meth:`Localizer.state_arrays`).
    d_left, d_right : float
        Wheel travel measured by the encoders over the step (nominal radius) [m].
    params : ndarray, shape (8,)
        :attr:`Localizer.predict_params`.
    phase : ndarray
        :attr:`Localizer.phase` (:mod:`estimators.encoder_phase`): the wheel command and the
        read's span; used and updated with the encoder residual states.
    """
    wheel_base, rel_var, base_var, q = params[WHEEL_BASE], params[REL_VAR], params[BASE_VAR], params[Q_SCALE]
    var_left = q * (rel_var * d_left * d_left + base_var)
    var_right = q * (rel_var * d_right * d_right + base_var)
    walk_var = params[WALK_VAR] * 0.5 * (abs(d_left) + abs(d_right))
    slip = params[TURN_SLIP]
    if params[QUANT_VAR] > 0.0:
        # the read's commanded turn carries the residuals' harmonics (estimators.motion_quantised);
        # the history is the fix snapshot's too
        phase_advance(phase, d_left, d_right)
        propagate_moments_quantised(x, P, d_left, d_right, wheel_base, var_left, var_right,
                                    q * params[QUANT_VAR], walk_var, slip, phase)
    elif params[BIASED] > 0.0:
        motion.propagate_moments_biased(x, P, d_left, d_right, wheel_base, var_left, var_right, walk_var, slip)
    else:
        motion.propagate_moments(x, P, d_left, d_right, wheel_base, var_left, var_right, slip)
    x[2] = math.pi - (math.pi - x[2]) % (2.0 * math.pi)  # estimators.update.wrap_scalar


# numba keys a cache on its own file only: flush the kernels above when a file they inline changed
compiled.keep_fresh(__name__)
