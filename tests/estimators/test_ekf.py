"""EKF localiser: closed-form updates, gating, and Monte-Carlo consistency (NEES/NIS)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from estimators import consistency, measurements, motion, process_noise
from estimators.ekf import Localizer
from scenarios.errors import SimulationError
from scenarios.schema import NoiseModel, RobotSpec, SensorSpec

MARKERS = np.array([[0.0, 0.0], [20.0, 0.0], [20.0, 20.0], [0.0, 20.0]])
ROBOT = RobotSpec(turn_slip=0.0)  # the synthetic truth (motion.propagate) turns on the arc: no slip
SENSOR = SensorSpec(noise=NoiseModel.GAUSSIAN, bearing_error=math.radians(0.5))
P_PRIOR = np.array([[4e-4, 5e-5, 1e-5], [5e-5, 2e-4, -2e-5], [1e-5, -2e-5, 3e-4]])


def _localizer(x0=(8.0, 11.0, 0.4), P0=P_PRIOR, **kw) -> Localizer:
    return Localizer(ROBOT, SENSOR, MARKERS, np.array(x0), P0, **kw)


def _kalman_by_hand(x, P, H, innovation, R):
    S = H @ P @ H + R
    K = P @ H / S
    I_KH = np.eye(3) - np.outer(K, H)
    return x + K * innovation, I_KH @ P @ I_KH.T + R * np.outer(K, K), S


# ------------------------------------------------------------- closed form
def test_single_range_update_matches_hand_kalman_update():
    loc = _localizer()
    x, P = loc.x, loc.P
    marker = 2
    # Independent model evaluation through estimators.measurements.
    r = measurements.ranges(x[:2], MARKERS[marker:marker + 1])[0]
    H = np.r_[measurements.range_jacobian(x[:2], MARKERS[marker:marker + 1])[0], 0.0]
    R = measurements.range_std(measurements.range_bound(SENSOR, r), SENSOR.noise) ** 2
    z = r + 0.0015
    x_hand, P_hand, S = _kalman_by_hand(x, P, H, z - r, R)
    # Joseph form equals the textbook (I - KH) P for the optimal gain: a second, simpler check.
    K = P @ H / S
    np.testing.assert_allclose(P_hand, (np.eye(3) - np.outer(K, H)) @ P, rtol=1e-9, atol=1e-15)

    res = loc.update_range(marker, z)
    assert res.accepted
    assert res.innovation == pytest.approx(0.0015, rel=1e-9)
    assert res.innovation_var == pytest.approx(S, rel=1e-12)
    assert res.nis == pytest.approx(0.0015**2 / S, rel=1e-9)
    np.testing.assert_allclose(loc.x, x_hand, rtol=0, atol=1e-13)
    np.testing.assert_allclose(loc.P, P_hand, rtol=1e-10, atol=1e-18)


def test_bearing_update_wraps_the_residual_across_pi():
    # Marker straight behind the robot: the predicted bearing is ~ +pi, the measurement is
    # reported on the other branch (~ -pi). Unwrapped the innovation would be ~ -2 pi.
    x0 = (10.0, 20.0 - 1e-3, 0.0)
    loc = _localizer(x0=x0)
    x, P = loc.x, loc.P
    marker = 3  # (0, 20): at world angle ~pi from the robot
    predicted = measurements.bearing(x, MARKERS[marker:marker + 1])[0]
    H = measurements.bearing_jacobian(x, MARKERS[marker:marker + 1])[0]
    R = measurements.bearing_std(SENSOR.bearing_error, SENSOR.noise) ** 2
    assert predicted > 3.14
    z = -math.pi + 0.002 + (predicted - math.pi)  # true residual: +0.002 rad after wrapping
    x_hand, P_hand, S = _kalman_by_hand(x, P, H, 0.002, R)
    res = loc.update_bearing(marker, z)
    assert res.accepted
    assert res.innovation == pytest.approx(0.002, abs=1e-12)
    assert res.innovation_var == pytest.approx(S, rel=1e-12)
    np.testing.assert_allclose(loc.x, x_hand, rtol=0, atol=1e-12)
    np.testing.assert_allclose(loc.P, P_hand, rtol=1e-10, atol=1e-18)


def test_predict_matches_linearised_moments():
    for q_scale in (1.0, 0.01):
        loc = _localizer(q_scale=q_scale)
        x, P = loc.x, loc.P
        dl, dr = 0.031, 0.024
        F, _ = motion.jacobians(x, dl, dr, ROBOT.wheel_base)
        loc.predict(dl, dr)
        np.testing.assert_allclose(loc.x, motion.propagate(x, dl, dr, ROBOT.wheel_base), atol=1e-15)
        expected = F @ P @ F.T + q_scale * process_noise.process_cov(x, dl, dr, ROBOT)
        np.testing.assert_allclose(loc.P, expected, rtol=1e-12)


def test_nees_method_matches_consistency_nees():
    loc = _localizer(x0=(8.0, 11.0, math.pi - 0.01))
    truth = np.array([8.01, 10.98, -math.pi + 0.02])  # heading error wraps to -0.03 rad
    e = consistency.pose_errors(loc.x, truth)
    assert e[2] == pytest.approx(-0.03, abs=1e-12)
    assert loc.nees(truth) == pytest.approx(float(consistency.nees(e, loc.P)), rel=1e-12)


# ------------------------------------------------------------------- gating
def test_gate_rejects_a_fifty_sigma_outlier():
    loc = _localizer()
    x, P = loc.x, loc.P
    r = float(np.hypot(*(x[:2] - MARKERS[1])))
    s = _localizer().update_range(1, r).innovation_var  # S at this prior, from a twin filter
    res = loc.update_range(1, r + 50.0 * math.sqrt(s))
    assert not res.accepted
    assert res.nis == pytest.approx(2500.0, rel=1e-6)
    np.testing.assert_array_equal(loc.x, x)
    np.testing.assert_array_equal(loc.P, P)
    # A measurement inside the gate (3 sigma, NIS 9 < chi2_0.999(1) = 10.83) is applied.
    assert loc.update_range(1, r + 3.0 * math.sqrt(s)).accepted
    # Negative control: without the gate the same outlier goes in and drags the estimate.
    ungated = _localizer(x0=x, P0=P, gate_probability=None)
    assert ungated.update_range(1, r + 50.0 * math.sqrt(s)).accepted
    assert np.linalg.norm(ungated.x[:2] - x[:2]) > 1e-3


def test_two_markers_in_a_row_past_the_gate_bring_a_lost_filter_back():
    # The prediction is 30 sigma off in x; the markers are exact. One marker past the gate is an
    # outlier; a second, other marker past it too says the prediction is off: it is applied.
    truth = np.array([8.0, 11.0, 0.4])
    sd = math.sqrt(P_PRIOR[0, 0])
    loc = _localizer(x0=truth + [30.0 * sd, 0.0, 0.0])
    first = loc.update_range(0, float(np.hypot(*(truth[:2] - MARKERS[0]))))
    assert not first.accepted and first.nis > 100.0
    second = loc.update_range(1, float(np.hypot(*(truth[:2] - MARKERS[1]))))
    assert second.accepted and second.nis > 100.0
    assert abs(loc.x[0] - truth[0]) < 15.0 * sd
    # The next rejection starts a new count: a lone outlier after an applied update is gated.
    r2 = float(np.hypot(*(loc.x[:2] - MARKERS[2])))
    assert not loc.update_range(2, r2 + 50.0 * math.sqrt(loc.update_range(2, r2).innovation_var)).accepted
    # Negative control: the same marker twice is one marker disagreeing; both are gated.
    same = _localizer(x0=truth + [30.0 * sd, 0.0, 0.0])
    r0, lost = float(np.hypot(*(truth[:2] - MARKERS[0]))), same.x
    assert not same.update_range(0, r0).accepted
    assert not same.update_range(0, r0).accepted
    np.testing.assert_array_equal(same.x, lost)


def test_bad_arguments_raise_one_line_errors():
    with pytest.raises(SimulationError, match="P0"):
        _localizer(P0=np.diag([1.0, -1.0, 1.0]))
    with pytest.raises(SimulationError, match="gate_probability"):
        _localizer(gate_probability=1.0)
    with pytest.raises(SimulationError, match="q_scale"):
        _localizer(q_scale=0.0)
    with pytest.raises(SimulationError, match="marker_index"):
        _localizer().update_range(7, 3.0)
    with pytest.raises(SimulationError, match="bearing_error"):
        Localizer(ROBOT, SensorSpec(), MARKERS, [1.0, 1.0, 0.0], np.eye(3)).update_bearing(0, 0.1)


# -------------------------------------------------------------- consistency
DT = 0.05          # control step [s]
FIX_EVERY = 4      # steps between fixes: 0.2 s
DURATION = 100.0   # [s]
RUNS = 20
SPEED = 0.5        # [m/s]
P0_STD = np.array([0.05, 0.05, 0.02])  # initial error std [m, m, rad]


@dataclass
class Outcome:
    nees: np.ndarray  # (RUNS, fixes) after each fix
    nis: np.ndarray   # (all updates,)


def _simulate(seed: int, q_scale: float = 1.0, noise_factor: float = 1.0, bearings: bool = False) -> Outcome:
    """Drive RUNS robots with exactly the filter's noise model and run the filter on each.

    The sensor noise is the declared one times ``noise_factor``; the filter keeps the declared.
    """
    n_steps = int(round(DURATION / DT))
    t = np.arange(n_steps) * DT
    yaw_rate = 0.1 + 0.15 * np.sin(2 * np.pi * t / 15.0)  # a wobbling ~5 m loop around (10, 10)
    half_base = 0.5 * ROBOT.wheel_base
    # Encoder readings (the commands, exactly); the true travel adds the model's wheel noise.
    enc_l = (SPEED - yaw_rate * half_base) * DT
    enc_r = (SPEED + yaw_rate * half_base) * DT
    var_l, var_r = process_noise.wheel_variances(enc_l, enc_r, ROBOT)
    gens = [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(RUNS)]
    rng_truth = np.random.default_rng(np.random.SeedSequence(seed).spawn(RUNS + 1)[-1])

    truth = np.tile([10.0, 5.0, 0.0], (RUNS, 1))
    wheel_noise = rng_truth.standard_normal((n_steps, RUNS, 2))
    poses = np.empty((n_steps + 1, RUNS, 3))
    poses[0] = truth
    for k in range(n_steps):
        poses[k + 1] = motion.propagate(poses[k], enc_l[k] + np.sqrt(var_l[k]) * wheel_noise[k, :, 0],
                                        enc_r[k] + np.sqrt(var_r[k]) * wheel_noise[k, :, 1], ROBOT.wheel_base)

    # Measurements at every fix (after step k = FIX_EVERY-1, 2*FIX_EVERY-1, ...): two markers,
    # cycling through all four.
    fix_steps = np.arange(FIX_EVERY, n_steps + 1, FIX_EVERY)
    fix_markers = np.column_stack([fix_steps // FIX_EVERY % 4, (fix_steps // FIX_EVERY + 1) % 4])
    fix_poses = poses[fix_steps]                                  # (F, RUNS, 3)
    seen = MARKERS[fix_markers]                                   # (F, 2, 2)
    delta = seen[:, None, :, :] - fix_poses[:, :, None, :2]       # (F, RUNS, 2, 2)
    true_ranges = np.hypot(delta[..., 0], delta[..., 1])          # (F, RUNS, 2)
    true_bearings = np.arctan2(delta[..., 1], delta[..., 0]) - fix_poses[:, :, None, 2]
    range_std = measurements.range_std(SENSOR.range_bound(true_ranges), NoiseModel.GAUSSIAN) * noise_factor
    bearing_std = measurements.bearing_std(SENSOR.bearing_error, NoiseModel.GAUSSIAN) * noise_factor

    P0 = np.diag(P0_STD**2)
    nees_all, nis_all = [], []
    for run, rng in enumerate(gens):
        x0 = poses[0, run] + P0_STD * rng.standard_normal(3)
        z_range = true_ranges[:, run] + range_std[:, run] * rng.standard_normal((len(fix_steps), 2))
        z_bearing = true_bearings[:, run] + bearing_std * rng.standard_normal((len(fix_steps), 2))
        loc = Localizer(ROBOT, SENSOR, MARKERS, x0, P0, q_scale=q_scale)
        run_nees = []
        for k in range(n_steps):
            loc.predict(enc_l[k], enc_r[k])
            if (k + 1) % FIX_EVERY:
                continue
            fix = (k + 1) // FIX_EVERY - 1
            for j in range(2):
                marker = int(fix_markers[fix, j])
                nis_all.append(loc.update_range(marker, z_range[fix, j]).nis)
                if bearings:
                    nis_all.append(loc.update_bearing(marker, z_bearing[fix, j]).nis)
            run_nees.append(loc.nees(poses[k + 1, run]))
        nees_all.append(run_nees)
    return Outcome(np.array(nees_all), np.array(nis_all))


# Two checks (NEES and NIS) per configuration, family false-alarm probability 1 %:
# Bonferroni gives alpha = 0.5 % per check. The NEES interval counts only the RUNS independent
# runs (consistency.nees_test: conservative for the time average); the NIS interval counts
# every update (innovations of a consistent filter are white). Under the model NEES ~ chi2(3)
# and NIS ~ chi2(1) exactly up to linearisation, which is negligible here (errors ~1 mm and
# ~1 mrad against ranges ~10 m and steps of 2.5 cm).
FAMILY_ALPHA = 0.01
ALPHA = FAMILY_ALPHA / 2


@pytest.fixture(scope="module", params=[False, True], ids=["ranges", "ranges+bearings"])
def bearings(request):
    return request.param


def test_filter_is_consistent(bearings):
    out = _simulate(seed=20240601, bearings=bearings)
    nees = consistency.nees_test(out.nees, 3, ALPHA)
    nis = consistency.nis_test(out.nis, 1, ALPHA)
    assert nees.passed, f"average NEES {nees.statistic:.3f} outside {nees.interval}"
    assert nis.passed, f"average NIS {nis.statistic:.4f} outside {nis.interval} (n={nis.n})"


def test_negative_control_process_noise_too_small_fails(bearings):
    out = _simulate(seed=20240602, q_scale=0.01, bearings=bearings)
    nees = consistency.nees_test(out.nees, 3, ALPHA)
    assert nees.verdict is consistency.Verdict.ABOVE, f"average NEES {nees.statistic:.3f} {nees.interval}"


def test_negative_control_sensor_noisier_than_declared_fails(bearings):
    out = _simulate(seed=20240603, noise_factor=3.0, bearings=bearings)
    nees = consistency.nees_test(out.nees, 3, ALPHA)
    nis = consistency.nis_test(out.nis, 1, ALPHA)
    assert nees.verdict is consistency.Verdict.ABOVE, f"average NEES {nees.statistic:.3f} {nees.interval}"
    assert nis.verdict is consistency.Verdict.ABOVE, f"average NIS {nis.statistic:.3f} {nis.interval}"


def test_initial_heading_is_wrapped():
    loc = _localizer(x0=(1.0, 1.0, 7.0))
    assert loc.x[2] == pytest.approx(7.0 - 2 * math.pi, abs=1e-15)
