"""One scalar measurement update of the localiser: its result, the gate, angle wrapping.

:func:`joseph_update` is filterpy's ``ExtendedKalmanFilter.update`` for one scalar measurement
(gain, state update, Joseph-form covariance), compiled and in place: filterpy's general
matrix code (a scipy ``inv`` of a 1 x 1 matrix, a ``deepcopy`` of ``z``, the posterior copies)
cost ~50 us a call alone and ~250 us inside an episode, where pybullet's stepping has evicted
its caches; this costs ~2 us. ``tests/estimators/test_joseph_update.py`` holds it to filterpy's
result.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

from jit import compiled


@dataclass(frozen=True, slots=True)
class UpdateResult:
    """Outcome of one measurement update.

    Attributes
    ----------
    accepted : bool
        False when the gate rejected the measurement (the state was left unchanged).
    nis : float
        ``innovation**2 / innovation_var``, computed before the update, gated or not.
    innovation : float
        Measured minus predicted (range [m] or wrapped bearing [rad]).
    innovation_var : float
        ``H P H^T + R`` before the update [m^2 or rad^2].
    """

    accepted: bool
    nis: float
    innovation: float
    innovation_var: float


def wrap_scalar(a: float) -> float:
    """Wrap one angle [rad] to (-pi, pi]."""
    # The formula of measurements.wrap_angle ((-pi, pi]) on a float: ~0.1 µs instead of ~4 µs
    # of array handling, which would dominate predict().
    return math.pi - (math.pi - a) % (2.0 * math.pi)


@functools.lru_cache(maxsize=16)
def gate_threshold(probability: float) -> float:
    """Return the chi2(1) quantile at ``probability``: the NIS above which an update is gated."""
    # scipy's ppf costs ~0.1 ms, as much as ~100 control steps; every episode asks the same
    return float(stats.chi2.ppf(probability, 1))


@compiled.njit(cache=True)
def joseph_update(x: np.ndarray, P: np.ndarray, H: np.ndarray, innovation: float, var: float) -> None:
    """Correct ``x`` and ``P`` in place with one scalar measurement (filterpy's EKF update).

    Parameters
    ----------
    x : ndarray, shape (n,)
        State, updated in place.
    P : ndarray, shape (n, n)
        Covariance, updated in place: ``(I - K H) P (I - K H)^T + K var K^T``.
    H : ndarray, shape (n,)
        Measurement Jacobian at ``x``.
    innovation : float
        Measured minus predicted (a bearing's already wrapped).
    var : float
        Measurement noise variance ``R``.
    """
    # The Joseph form (I - K H) P (I - K H)^T + var K K^T expanded for a scalar measurement:
    # P - K h^T - h K^T + (H P H^T + var) K K^T with h = P H^T, in O(n^2) and without numba's
    # BLAS-backed `@` (~9 s to compile).
    n = x.shape[0]
    h = np.empty(n)
    for i in range(n):
        v = 0.0
        for j in range(n):
            v += P[i, j] * H[j]
        h[i] = v
    s = var
    for i in range(n):
        s += H[i] * h[i]
    K = h / s
    for i in range(n):
        x[i] += K[i] * innovation
    for i in range(n):
        for j in range(i, n):
            # one triangle written into both keeps P exactly symmetric
            v = P[i, j] - K[i] * h[j] - h[i] * K[j] + s * K[i] * K[j]
            P[i, j] = v
            P[j, i] = v


@compiled.njit(cache=True)
def gated_joseph_update(x: np.ndarray, P: np.ndarray, H: np.ndarray, innovation: float, var: float,
                        gate: float) -> tuple[bool, float, float]:
    """Gate one scalar measurement and, if it passes, :func:`joseph_update` it and wrap the heading.

    One compiled call for the localiser's update: its numpy steps (``H P H^T``, the NIS, the
    heading's wrap) cost ~90 us between physics steps, where the interpreter runs from cold
    caches. The same operations as those steps.

    Parameters
    ----------
    x, P, H, innovation, var
        As :func:`joseph_update`; ``x[2]`` is the heading [rad].
    gate : float
        Largest NIS accepted (``inf``: no gate).

    Returns
    -------
    accepted : bool
    nis : float
        ``innovation**2 / s``, before the update.
    s : float
        ``H P H^T + var`` before the update.
    """
    s = var
    for j in range(x.shape[0]):
        v = 0.0
        for i in range(x.shape[0]):
            v += H[i] * P[i, j]
        s += v * H[j]
    nis = innovation * innovation / s
    if nis > gate:
        return False, nis, s
    joseph_update(x, P, H, innovation, var)
    x[2] = math.pi - (math.pi - x[2]) % (2.0 * math.pi)  # wrap_scalar
    return True, nis, s


# numba keys a cache on its own file only: flush the kernels above when a file they inline changed
compiled.keep_fresh(__name__)
