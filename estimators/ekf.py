"""Extended Kalman filter localiser: wheel odometry predicts, marker ranges/bearings correct.

State: the planar pose ``x = (x [m], y [m], theta [rad])`` with covariance ``P`` (3, 3).

What we use of filterpy (``filterpy.kalman.ExtendedKalmanFilter``, 2.0.0):
- it holds ``x`` (kept 1-D, shape (3,)) and ``P``;
- ``update(z, HJacobian, Hx, R, residual=...)`` does the correction: gain, state update and
  the Joseph-form covariance update. For bearings ``residual`` wraps the innovation angle.
We do NOT use its ``predict``: it assumes a linear ``F x + B u``. Prediction sets ``x`` and
``P`` directly from our motion model (:func:`estimators.motion.propagate_moments`), and the
filter's ``x_prior``/``P_prior`` are not maintained.

Gating: before ``update`` we compute the innovation ``nu`` and its variance
``S = H P H^T + R`` ourselves (we need them to gate, and they are three lines for a scalar
measurement) and skip the update when ``nu^2 / S`` exceeds the chi2(1) quantile at
``gate_probability``. ``HJacobian``/``Hx`` handed to filterpy then return the values already
computed at the same state, so nothing is evaluated twice.

Measurements are processed one at a time at their own time: the caller predicts up to a
measurement's time stamp, then updates (a fix of k markers taken one after another while
the robot moves is k predict/update pairs).

Noise: ``R`` is the declared sensor's model (:mod:`estimators.measurements`): range bound
``rho = Re * r + rho0`` at the predicted range, bearing bound ``xi``; variance ``rho^2 / 3`` for
``uniform`` noise and ``(rho / 3)^2`` for ``gaussian``. Process noise is
``q_scale * G diag(var_l, var_r) G^T`` (:mod:`estimators.motion`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

from estimators import motion
from estimators.measurements import bound_std, wrap_angle
from scenarios.errors import SimulationError
from scenarios.schema import RobotSpec, SensorSpec


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


def _wrapped_residual(a, b):
    return wrap_angle(a - b)


def _wrap_scalar(a: float) -> float:
    # The formula of measurements.wrap_angle ((-pi, pi]) on a float: ~0.1 µs instead of ~4 µs
    # of array handling, which would dominate predict().
    return math.pi - (math.pi - a) % (2.0 * math.pi)


def _check_matrix(name: str, value, shape: tuple[int, ...]) -> np.ndarray:
    arr = np.array(value, dtype=float)
    if arr.shape != shape or not np.all(np.isfinite(arr)):
        raise SimulationError(f"Localizer: {name}: expected a finite array of shape {shape}, got {value!r}")
    return arr


class Localizer:
    """EKF pose estimator for a differential-drive robot with a marker range/bearing sensor.

    Parameters
    ----------
    robot : RobotSpec
        The declared robot (wheel base, odometry noise, encoder ticks).
    sensor : SensorSpec
        The declared sensor (range error bound, bearing bound, noise model).
    markers : array_like, shape (M, 2)
        Marker positions [m].
    x0 : array_like, shape (3,)
        Initial pose estimate (x [m], y [m], theta [rad]).
    P0 : array_like, shape (3, 3)
        Initial covariance, symmetric positive definite.
    gate_probability : float or None
        A measurement whose NIS exceeds the chi2(1) quantile at this probability is not
        applied; ``None`` disables gating.
    q_scale : float
        Multiplies the process noise (1 = the declared model; tests use 0.01 to mis-tune).
    include_systematic : bool
        Add the declared wheel-radius error bound to the process noise
        (:func:`estimators.motion.wheel_variances`).
    """

    def __init__(self, robot: RobotSpec, sensor: SensorSpec, markers, x0, P0,
                 gate_probability: float | None = 0.999, q_scale: float = 1.0,
                 include_systematic: bool = False):
        # filterpy imports all its subpackages (~1 s): only pay for it when a filter is built.
        from filterpy.kalman import ExtendedKalmanFilter

        markers_arr = np.array(markers, dtype=float)
        if markers_arr.ndim != 2 or markers_arr.shape[1] != 2 or not np.all(np.isfinite(markers_arr)):
            raise SimulationError(f"Localizer: markers: expected a finite (M, 2) array, got shape "
                                  f"{markers_arr.shape}")
        x0_arr = _check_matrix("x0", x0, (3,))
        P0_arr = _check_matrix("P0", P0, (3, 3))
        if not np.allclose(P0_arr, P0_arr.T) or np.any(np.linalg.eigvalsh(0.5 * (P0_arr + P0_arr.T)) <= 0):
            raise SimulationError(f"Localizer: P0: expected a symmetric positive definite matrix, "
                                  f"got {P0_arr.tolist()}")
        if not (q_scale > 0 and math.isfinite(q_scale)):
            raise SimulationError(f"Localizer: q_scale: expected a positive number, got {q_scale}")
        if gate_probability is None:
            self._gate = math.inf
        elif 0.0 < gate_probability < 1.0:
            self._gate = float(stats.chi2.ppf(gate_probability, 1))
        else:
            raise SimulationError(f"Localizer: gate_probability: expected a probability in (0, 1) or None, "
                                  f"got {gate_probability}")

        self.robot = robot
        self.sensor = sensor
        self.markers = markers_arr
        self.q_scale = float(q_scale)
        self.include_systematic = bool(include_systematic)
        # The noise std is linear in its bound: one factor per model, computed once.
        self._std_per_bound = bound_std(1.0, sensor.noise)
        self._bearing_var = (sensor.bearing_error * self._std_per_bound) ** 2
        self._variance_terms = motion.variance_terms(robot, include_systematic)
        self._kf = ExtendedKalmanFilter(dim_x=3, dim_z=1)
        self._kf.x = np.ascontiguousarray(x0_arr)
        self._kf.x[2] = _wrap_scalar(self._kf.x[2])
        self._kf.P = np.ascontiguousarray(0.5 * (P0_arr + P0_arr.T))
        # Measurement model at the current state, filled before each filterpy update.
        self._H = np.zeros((1, 3))
        self._hx = np.zeros(1)

    # ------------------------------------------------------------------ state
    @property
    def x(self) -> np.ndarray:
        """Pose estimate (x [m], y [m], theta [rad]), shape (3,), a copy; theta in (-pi, pi]."""
        return self._kf.x.copy()

    @property
    def P(self) -> np.ndarray:
        """Pose covariance, shape (3, 3) [m^2, m rad, rad^2], a copy."""
        return self._kf.P.copy()

    @property
    def gate_threshold(self) -> float:
        """NIS above which a measurement is rejected (inf when gating is off)."""
        return self._gate

    def nees(self, true_pose) -> float:
        """Normalised estimation error squared against a true pose.

        Parameters
        ----------
        true_pose : array_like, shape (3,)
            True pose (x [m], y [m], theta [rad]).

        Returns
        -------
        float
            ``e^T P^-1 e`` with ``e = x - true_pose``, heading difference wrapped.
        """
        e = self._kf.x - np.asarray(true_pose, dtype=float)
        e[2] = _wrap_scalar(e[2])
        return float(e @ np.linalg.solve(self._kf.P, e))

    # ---------------------------------------------------------------- predict
    def predict(self, d_left: float, d_right: float) -> None:
        """Propagate the estimate by one odometry increment.

        Parameters
        ----------
        d_left, d_right : float
            Wheel travel measured by the encoders over the step [m].
        """
        d_left, d_right = float(d_left), float(d_right)
        rel_var, base_var = self._variance_terms
        kf = self._kf
        motion.propagate_moments(kf.x, kf.P, d_left, d_right, self.robot.wheel_base,
                                 self.q_scale * (rel_var * d_left * d_left + base_var),
                                 self.q_scale * (rel_var * d_right * d_right + base_var))
        kf.x[2] = _wrap_scalar(kf.x[2])

    # ----------------------------------------------------------------- update
    def _marker(self, marker_index: int) -> tuple[float, float]:
        if not 0 <= marker_index < self.markers.shape[0]:
            raise SimulationError(f"Localizer: marker_index: expected 0..{self.markers.shape[0] - 1}, "
                                  f"got {marker_index}")
        return self.markers[marker_index, 0], self.markers[marker_index, 1]

    def _cached_H(self, _x):
        return self._H

    def _cached_hx(self, _x):
        return self._hx

    def _gated_update(self, z: float, predicted: float, innovation: float, var: float,
                      residual) -> UpdateResult:
        H = self._H[0]
        P = self._kf.P
        s = float(H @ P @ H) + var
        nis = innovation * innovation / s
        if nis > self._gate:
            return UpdateResult(False, nis, innovation, s)
        self._hx[0] = predicted
        self._kf.update(z, self._cached_H, self._cached_hx, R=var, residual=residual)
        self._kf.x[2] = _wrap_scalar(self._kf.x[2])
        return UpdateResult(True, nis, innovation, s)

    def update_range(self, marker_index: int, measured_range: float) -> UpdateResult:
        """Correct the estimate with one range measurement.

        Parameters
        ----------
        marker_index : int
            Row of ``markers`` that was measured.
        measured_range : float
            Measured range [m].

        Returns
        -------
        UpdateResult
            Innovation, its variance and NIS; ``accepted`` is False when the gate rejected it.
        """
        mx, my = self._marker(marker_index)
        x = self._kf.x
        dx, dy = x[0] - mx, x[1] - my
        r = math.hypot(dx, dy)
        if r < 1e-9:
            raise SimulationError(f"Localizer: update_range: estimate sits on marker {marker_index}")
        self._H[0, 0] = dx / r
        self._H[0, 1] = dy / r
        self._H[0, 2] = 0.0
        std = self.sensor.range_bound(r) * self._std_per_bound
        z = float(measured_range)
        return self._gated_update(z, r, z - r, std * std, np.subtract)

    def update_bearing(self, marker_index: int, measured_bearing: float) -> UpdateResult:
        """Correct the estimate with one bearing measurement (marker direction in the robot frame).

        Parameters
        ----------
        marker_index : int
            Row of ``markers`` that was measured.
        measured_bearing : float
            ``atan2(M - R) - theta`` as measured [rad], any branch.

        Returns
        -------
        UpdateResult
            Innovation (wrapped to (-pi, pi]), its variance and NIS.
        """
        if self._bearing_var <= 0.0:
            raise SimulationError("Localizer: update_bearing: the declared sensor has bearing_error = 0")
        mx, my = self._marker(marker_index)
        x = self._kf.x
        dx, dy = mx - x[0], my - x[1]
        r2 = dx * dx + dy * dy
        if r2 < 1e-18:
            raise SimulationError(f"Localizer: update_bearing: estimate sits on marker {marker_index}")
        self._H[0, 0] = dy / r2
        self._H[0, 1] = -dx / r2
        self._H[0, 2] = -1.0
        predicted = _wrap_scalar(math.atan2(dy, dx) - x[2])
        z = float(measured_bearing)
        return self._gated_update(z, predicted, _wrap_scalar(z - predicted), self._bearing_var,
                                  _wrapped_residual)
