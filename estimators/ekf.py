"""Extended Kalman filter localiser: wheel odometry predicts, marker ranges/bearings correct.

State: the planar pose ``x = (x [m], y [m], theta [rad])`` with covariance ``P`` (3, 3).

Optionally (``estimate_wheel_bias=True``) the state is augmented with the relative
wheel-radius error ``e`` (right wheel radius ``r (1 + e)``, left ``r (1 - e)``; the encoders
are converted with the nominal ``r``): ``(x, y, theta, e)``. A systematic error adds up
coherently between fixes, which per-step white noise (``include_systematic``) cannot represent;
as a state it is tracked and its effect on the pose carried in the cross-covariance. Its prior
is zero-mean with std ``max(|RobotSpec.wheel_radius_error|, BIAS_STD_FLOOR)`` (the declared
magnitude, sign unknown), uncorrelated with the pose; it is a random constant, optionally with
a random walk (``bias_walk_std``). Measurements do not see ``e`` (a zero column in ``H``); it is
learnt through its correlation with the pose. ``x``/``P``/``nees`` stay on the pose;
``full_x``/``full_P`` give the whole state.

What we use of filterpy (``filterpy.kalman.ExtendedKalmanFilter``, 2.0.0):
- it holds ``x`` (kept 1-D, shape (3,) or (4,)) and ``P``;
- its ``update(z, HJacobian, Hx, R, residual=...)`` defines the correction: gain, state update
  and the Joseph-form covariance update. For one scalar measurement that is
  :func:`estimators.update.joseph_update`, the same arithmetic compiled and in place (held to
  filterpy's result by a test): filterpy's general matrix code cost an episode a fifth of its
  non-physics time. Its ``z``, ``y``, ``K``, ``S`` and posterior copies are not maintained.
We do NOT use its ``predict``: it assumes a linear ``F x + B u``. Prediction sets ``x`` and
``P`` directly from our motion model (:func:`estimators.motion.propagate_moments`, or
:func:`~estimators.motion.propagate_moments_biased` for the augmented state), and the
filter's ``x_prior``/``P_prior`` are not maintained.

Gating: before ``update`` we compute the innovation ``nu`` and its variance
``S = H P H^T + R`` ourselves (we need them to gate, and they are three lines for a scalar
measurement) and skip the update when ``nu^2 / S`` exceeds the chi2(1) quantile at
``gate_probability``. ``HJacobian``/``Hx`` handed to filterpy then return the values already
computed at the same state, so nothing is evaluated twice. The gate stands aside for an update
when it rejected the one just before, of another marker. A consistent filter's own error
reaches 3-4 sigma now and then, and where the ranges are precise beside the heading that
prediction (k = 2, no bearings, 1.6 mm ranges on random-23-039) puts every marker past a gate
at 0.999: the filter then rejected every fix for 2.3 s while its heading error carried it 14 cm
off (one run in 200, NIS 1.027 against [0.978, 1.022] from its 18 rejected updates). Two markers
that disagree with the prediction in a row say that the prediction is off; a marker that
disagrees alone is what the gate is for.

Measurements are processed one at a time at their own time: the caller predicts up to a
measurement's time stamp, then updates (a fix of k markers taken one after another while
the robot moves is k predict/update pairs).

Noise: ``R`` is the declared sensor's model (:mod:`estimators.measurements`): range bound
``rho = Re * r + rho0`` at the predicted range, bearing bound ``xi``; variance ``rho^2 / 3`` for
``uniform`` noise and ``(rho / 3)^2`` for ``gaussian``. Process noise is
``q_scale * G diag(var_l, var_r) G^T`` (:mod:`estimators.motion`).

Encoder quantisation (``encoder_residual_state=True``, what an episode uses): the state is
further augmented with each wheel's quantisation residual [m], as the phasors of its first
harmonics and a remainder, a block per wheel at the end of ``full_x``
(:mod:`estimators.motion_quantised`). A count error is bounded and telescopes over a
window (the reported travel is ``true + q_{k-1} - q_k``); the white ``tick^2 / 12`` per step of
the plain model grows without bound and made the filter pessimistic: over the 0.4 s between
fixes the white model's pose NEES is 1.53 against 3 (``tests/sim/test_odometry_noise_model.py``),
and 200 warehouse episodes gave NIS 0.962. The residual at a read's end is the sawtooth of the
wheel's phase, which the drive holds to the commanded turn: the harmonics are turned by the
wheel command (:meth:`Localizer.set_command`) over each read's span (``steps``, with
``step_time``). The
residuals at the start can be given (``residual0``, variance 0) when the encoders were zeroed at
known angles; an episode's are unknown. ``q_scale`` scales the residual variance too. The history of commanded
against counted turn (:mod:`estimators.encoder_phase`) is the fix snapshot's too.

Also checked against the simulation and not modelled, because it is negligible: ``R`` at the
predicted instead of the true range (``Re * |error|`` ~ 1e-7 m against ``rho`` ~ 2 mm); the laser
sits at the axle midpoint, the point the pose describes, and each measurement is taken at the
physics step the odometry was read and predicted to (``sim.episode.drive``): no lever arm, no time
offset. The odometry side (physics slip, wheel-radius prior, slip model, standstill) is in
:mod:`estimators.motion`.
"""

from __future__ import annotations

import math

import numpy as np

from estimators import encoder_phase, motion, motion_quantised, process_noise
from estimators.measurements import bound_std
from estimators.predict import TURN_SLIP, predict_step
from estimators.update import UpdateResult, gate_threshold, gated_joseph_update, wrap_scalar
from jit import compiled
from scenarios.errors import SimulationError
from scenarios.schema import RobotSpec, SensorSpec

BIAS_STD_FLOOR = 1e-4
"""Smallest prior std of the estimated wheel-radius error [-]: a declared 0 still lets the
filter learn a small error instead of freezing ``e`` at exactly 0."""


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
    x0 : array_like, shape (3,) or (4,)
        Initial pose estimate (x [m], y [m], theta [rad]); with ``estimate_wheel_bias`` it may
        also carry the wheel error (4,), else that starts at 0.
    P0 : array_like, shape (3, 3) or (4, 4)
        Initial covariance (shaped like ``x0``), symmetric positive definite; a (3, 3) pose
        covariance is extended by the wheel-error prior variance
        ``max(|robot.wheel_radius_error|, BIAS_STD_FLOOR)**2``, uncorrelated.
    gate_probability : float or None
        A measurement whose NIS exceeds the chi2(1) quantile at this probability is not
        applied, unless the gate rejected the update just before it, of another marker:
        two markers in a row that disagree with the prediction say that the prediction is off,
        and a filter that went on rejecting would never find its way back (module docstring).
        ``None`` disables gating.
    q_scale : float
        Multiplies the process noise (1 = the declared model; tests use 0.01 to mis-tune). Read
        once, like ``bias_walk_std``, into :attr:`predict_params`.
    include_systematic : bool
        Add the declared wheel-radius error bound to the process noise
        (:func:`estimators.process_noise.wheel_variances`).
    estimate_wheel_bias : bool
        Augment the state with the relative wheel-radius error ``e`` (module docstring).
    bias_walk_std : float
        Random-walk std of ``e`` per square root of metre travelled (mean of both wheels)
        [1/sqrt(m)]; 0 (default) makes ``e`` a random constant. Only with
        ``estimate_wheel_bias``.
    encoder_residual_state : bool
        Model encoder quantisation: the state gains each wheel's centred quantisation residual
        as ``motion_quantised.BLOCK`` states [m] (its harmonics' phasors and the remainder, a
        block per wheel, left then right, at the end of :attr:`full_x`) and the white
        ``tick^2 / 12`` term leaves the process noise (module docstring,
        :mod:`estimators.motion_quantised`). Off by default (the white approximation).
    residual0 : array_like, shape (2,), optional
        The residuals at the start, centred [m], when they are known (the encoders were zeroed
        at a known angle): used with variance 0. By default zero-mean with ``tick^2 / 12``.
    step_time : float, optional
        The physics step [s] that reads' spans count (:meth:`predict`'s ``steps``); without it
        no read's turn is predicted and each read's residual is new.
    """

    def __init__(self, robot: RobotSpec, sensor: SensorSpec, markers, x0, P0,
                 gate_probability: float | None = 0.999, q_scale: float = 1.0,
                 include_systematic: bool = False, estimate_wheel_bias: bool = False,
                 bias_walk_std: float = 0.0, encoder_residual_state: bool = False, residual0=None,
                 step_time: float | None = None):
        # filterpy imports all its subpackages (~1 s): only pay for it when a filter is built.
        from filterpy.kalman import ExtendedKalmanFilter

        markers_arr = np.array(markers, dtype=float)
        if markers_arr.ndim != 2 or markers_arr.shape[1] != 2 or not np.all(np.isfinite(markers_arr)):
            raise SimulationError(f"Localizer: markers: expected a finite (M, 2) array, got shape "
                                  f"{markers_arr.shape}")
        # A (3,) pose prior, or with the wheel error estimated optionally a full (4,) prior (e.g.
        # the error learnt in an earlier run).
        dim = 4 if estimate_wheel_bias and np.shape(x0) == (4,) else 3
        x0_arr = _check_matrix("x0", x0, (dim,))
        P0_arr = _check_matrix("P0", P0, (dim, dim))
        if not np.allclose(P0_arr, P0_arr.T) or np.any(np.linalg.eigvalsh(0.5 * (P0_arr + P0_arr.T)) <= 0):
            raise SimulationError(f"Localizer: P0: expected a symmetric positive definite matrix, "
                                  f"got {P0_arr.tolist()}")
        if not (q_scale > 0 and math.isfinite(q_scale)):
            raise SimulationError(f"Localizer: q_scale: expected a positive number, got {q_scale}")
        if not (bias_walk_std >= 0 and math.isfinite(bias_walk_std)):
            raise SimulationError(f"Localizer: bias_walk_std: expected a number >= 0, got {bias_walk_std}")
        if gate_probability is None:
            self._gate = math.inf
        elif 0.0 < gate_probability < 1.0:
            self._gate = gate_threshold(float(gate_probability))
        else:
            raise SimulationError(f"Localizer: gate_probability: expected a probability in (0, 1) or None, "
                                  f"got {gate_probability}")
        # the marker whose update the gate rejected last, while no update has been applied since
        self._rejected = -1

        self.robot = robot
        self.sensor = sensor
        self.markers = markers_arr
        self.q_scale = float(q_scale)
        self.include_systematic = bool(include_systematic)
        # The noise std is linear in its bound: one factor per model, computed once.
        self._std_per_bound = bound_std(1.0, sensor.noise)
        self._bearing_var = (sensor.bearing_error * self._std_per_bound) ** 2
        self._variance_terms = process_noise.variance_terms(robot, include_systematic)
        self.encoder_residual_state = bool(encoder_residual_state)
        quant_var = 0.0
        if self.encoder_residual_state:
            # The residuals carry the quantisation: it leaves the white per-step term.
            quant_var = self._variance_terms[1] - motion.VARIANCE_FLOOR
            self._variance_terms = (self._variance_terms[0], motion.VARIANCE_FLOOR)
        self.estimate_wheel_bias = bool(estimate_wheel_bias)
        self.bias_walk_std = float(bias_walk_std)
        P0_sym = 0.5 * (P0_arr + P0_arr.T)
        if self.estimate_wheel_bias and dim == 3:
            # Declared magnitude, unknown sign: zero mean, one sigma, independent of the pose.
            bias_std = max(abs(robot.wheel_radius_error), BIAS_STD_FLOOR)
            x0_arr = np.r_[x0_arr, 0.0]
            P0_sym = np.block([[P0_sym, np.zeros((3, 1))], [np.zeros((1, 3)), np.array([[bias_std**2]])]])
            dim = 4
        if self.encoder_residual_state:
            # each wheel's block: its residual's harmonics and the remainder
            # (estimators.motion_quantised)
            k = motion_quantised.BLOCK
            if residual0 is None:   # counted from an unknown point in a tick
                x0_arr = np.r_[x0_arr, np.zeros(2 * k)]
                # q_scale scales the residual's variance, as it scales the remainder's per read
                blocks = self.q_scale * quant_var * np.diag(np.tile(motion_quantised.block_prior(), 2))
            else:
                q0 = _check_matrix("residual0", residual0, (2,))
                tick = 2.0 * math.pi * robot.wheel_radius / robot.encoder_ticks
                x0_arr = np.r_[x0_arr, motion_quantised.residual_block(q0[0], tick),
                               motion_quantised.residual_block(q0[1], tick)]
                blocks = np.zeros((2 * k, 2 * k))
            P0_sym = np.block([[P0_sym, np.zeros((dim, 2 * k))], [np.zeros((2 * k, dim)), blocks]])
            dim += 2 * k
        elif residual0 is not None:
            raise SimulationError("Localizer: residual0: given without encoder_residual_state")
        self._kf = ExtendedKalmanFilter(dim_x=dim, dim_z=1)
        self._kf.x = np.ascontiguousarray(x0_arr)
        self._kf.x[2] = wrap_scalar(self._kf.x[2])
        self._kf.P = np.ascontiguousarray(P0_sym)
        rel_var, base_var = self._variance_terms
        self.predict_params = np.array([robot.wheel_base, rel_var, base_var, self.q_scale,
                                        self.bias_walk_std**2, float(self.estimate_wheel_bias), quant_var,
                                        robot.turn_slip])
        #: the encoder phase predictor's state (:mod:`estimators.encoder_phase`)
        self.phase = encoder_phase.new_state(robot.encoder_ticks, robot.wheel_radius, step_time,
                                             robot.odometry_noise)
        # Measurement Jacobian at the current state, filled before each update; the wheel-error
        # and residual columns (if any) stay 0.
        self._H = np.zeros((1, dim))

    # ------------------------------------------------------------------ state
    @property
    def x(self) -> np.ndarray:
        """Pose estimate (x [m], y [m], theta [rad]), shape (3,), a copy; theta in (-pi, pi]."""
        return self._kf.x[:3].copy()

    @property
    def P(self) -> np.ndarray:
        """Pose covariance, shape (3, 3) [m^2, m rad, rad^2], a copy."""
        return self._kf.P[:3, :3].copy()

    @property
    def heading_var(self) -> float:
        """Variance of the heading estimate [rad^2] (``P[2, 2]`` without copying ``P``)."""
        return float(self._kf.P[2, 2])

    @property
    def full_x(self) -> np.ndarray:
        """Whole state, a copy: (3,) pose, (4,) with the wheel error ``e``; then the encoder residual blocks."""
        return self._kf.x.copy()

    @property
    def full_P(self) -> np.ndarray:
        """Covariance of the whole state, a copy: shape (n, n) for the n entries of :attr:`full_x`."""
        return self._kf.P.copy()

    @property
    def bias(self) -> float:
        """Estimated relative wheel-radius error ``e`` [-]; 0 when it is not estimated."""
        return float(self._kf.x[3]) if self.estimate_wheel_bias else 0.0

    @property
    def bias_var(self) -> float:
        """Variance of the estimated wheel-radius error [-]; 0 when it is not estimated."""
        return float(self._kf.P[3, 3]) if self.estimate_wheel_bias else 0.0

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
            ``e^T P^-1 e`` with ``e = x - true_pose``, heading difference wrapped; on the pose
            only (3 dof) also when the wheel error is estimated.
        """
        e = self._kf.x[:3] - np.asarray(true_pose, dtype=float)
        e[2] = wrap_scalar(e[2])
        return float(e @ np.linalg.solve(self._kf.P[:3, :3], e))

    # ---------------------------------------------------------------- predict
    def predict(self, d_left: float, d_right: float, turn_slip: float | None = None,
                steps: int | None = None) -> None:
        """Propagate the estimate by one odometry increment.

        Parameters
        ----------
        d_left, d_right : float
            Wheel travel measured by the encoders over the step (nominal radius) [m].
        turn_slip : float, optional
            The increment's turn slip [-] (:func:`estimators.motion._arc_terms`); by default the
            declared ``robot.turn_slip``. A simulated platform's depends on the read's span
            (:func:`sim.physics.turn_lag.read_turn_slip`).
        steps : int, optional
            Physics steps the increment spans (:meth:`set_read_steps`); by default unknown.
        """
        self.set_turn_slip(turn_slip)
        self.set_read_steps(steps)
        predict_step(self._kf.x, self._kf.P, float(d_left), float(d_right), self.predict_params, self.phase)

    def set_read_steps(self, steps: int | None = None) -> None:
        """Set the physics steps the next predict's read spans (None: unknown).

        With ``step_time`` it times the wheels' commanded turn over the read, whose fractional
        part sets the residuals' correlation across it (:mod:`estimators.motion_quantised`);
        :attr:`phase` holds it, where a compiled caller's predict reads it too.
        """
        self.phase[encoder_phase.STEPS] = encoder_phase.UNKNOWN_SPAN if steps is None else float(steps)

    def set_command(self, rate_left: float, rate_right: float) -> None:
        """Record the wheel rates commanded from now on [rad/s] (left, right; forward positive)."""
        self.phase[encoder_phase.CMD_LEFT] = float(rate_left)
        self.phase[encoder_phase.CMD_RIGHT] = float(rate_right)

    def set_turn_slip(self, turn_slip: float | None = None) -> None:
        """Set the turn slip the next predict uses [-] (None: the declared ``robot.turn_slip``).

        :attr:`predict_params` holds it, where a compiled caller's predict reads it too
        (``sim.episode.control_tick``).
        """
        self.predict_params[TURN_SLIP] = self.robot.turn_slip if turn_slip is None else float(turn_slip)

    def state_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """Return the filter's live state and covariance arrays (not copies), for :func:`predict_step`.

        Updates work in place, so the arrays stay valid across predicts and updates.
        """
        return self._kf.x, self._kf.P

    # ----------------------------------------------------------------- update
    def _marker(self, marker_index: int) -> tuple[float, float]:
        if not 0 <= marker_index < self.markers.shape[0]:
            raise SimulationError(f"Localizer: marker_index: expected 0..{self.markers.shape[0] - 1}, "
                                  f"got {marker_index}")
        return self.markers[marker_index, 0], self.markers[marker_index, 1]

    def _gated_update(self, marker_index: int, innovation: float, var: float) -> UpdateResult:
        relock = self._rejected >= 0 and self._rejected != marker_index
        accepted, nis, s = gated_joseph_update(self._kf.x, self._kf.P, self._H[0], float(innovation), float(var),
                                               math.inf if relock else self._gate)
        self._rejected = -1 if accepted else marker_index
        return UpdateResult(accepted, nis, innovation, s)

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
        return self._gated_update(marker_index, z - r, std * std)

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
        predicted = wrap_scalar(math.atan2(dy, dx) - x[2])
        z = float(measured_bearing)
        return self._gated_update(marker_index, wrap_scalar(z - predicted), self._bearing_var)


# numba keys a cache on its own file only: flush the kernels above when a file they inline changed
compiled.keep_fresh(__name__)
