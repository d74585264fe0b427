"""drift_bound against an independent odometry simulation (systematic, random, quantised)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy import stats

from planner.schedule.drift import drift_bound, encoder_step
from scenarios.schema import RobotSpec


def simulate(b: float, right: np.ndarray, left: np.ndarray, est_right: np.ndarray,
             est_left: np.ndarray) -> np.ndarray:
    """Integrate true and odometry poses from wheel travels per increment, shape (trials, steps).

    Returns the final position error |true - odometry| per trial [m]. Midpoint rule.
    """
    def integrate(r, lft):
        ds, dth = (r + lft) / 2, (r - lft) / b
        th = np.cumsum(dth, axis=1) - dth / 2
        return np.sum(ds * np.cos(th), axis=1), np.sum(ds * np.sin(th), axis=1)

    xt, yt = integrate(right, left)
    xe, ye = integrate(est_right, est_left)
    return np.hypot(xt - xe, yt - ye)


def test_systematic_wheel_error_is_bounded_and_tight():
    # UMBmark error only: right wheel 1 + e, left 1 - e; the odometry believes a straight line.
    robot = RobotSpec(wheel_radius_error=0.002, odometry_noise=0.0, encoder_ticks=10**9)
    d, steps = 20.0, 20000
    nominal = np.full((1, steps), d / steps)
    err = simulate(robot.wheel_base, nominal * (1 + robot.wheel_radius_error),
                   nominal * (1 - robot.wheel_radius_error), nominal, nominal)[0]
    bound = drift_bound(robot, d)
    assert err <= bound
    # the lateral e d^2 / b term dominates here: the bound is within 5 % of the real drift
    assert err >= 0.95 * bound
    # negative control: a model without the heading-induced lateral term is violated
    assert err > robot.wheel_radius_error * d * 10


def test_turn_with_scale_error_is_bounded():
    # both wheels 1 + e (scale error): a turn in place of phi leaves a heading error e phi
    robot = RobotSpec(wheel_radius_error=0.003, odometry_noise=0.0, encoder_ticks=10**9)
    b, e, phi, d = robot.wheel_base, robot.wheel_radius_error, math.pi / 2, 6.0
    arc = b * phi / 2
    turn_steps, run_steps = 500, 6000
    est_r = np.concatenate([np.full(turn_steps, arc / turn_steps), np.full(run_steps, d / run_steps)])
    est_l = np.concatenate([np.full(turn_steps, -arc / turn_steps), np.full(run_steps, d / run_steps)])
    err = simulate(b, est_r[None] * (1 + e), est_l[None] * (1 + e), est_r[None], est_l[None])[0]
    assert err <= drift_bound(robot, d, phi)
    # negative control: a scale-error model ignoring the turn (along-track e d only) is violated
    assert err > 1.5 * e * d


def test_quantisation_is_bounded():
    robot = RobotSpec(wheel_radius_error=0.0, odometry_noise=0.0, encoder_ticks=64)
    q = encoder_step(robot)
    rng = np.random.default_rng(5)
    d, steps, trials = 2.0, 400, 200
    # true wheel travels vary a little per step; the odometry sees floor(cumulative / q) * q
    right = np.full((trials, steps), d / steps) * (1 + 0.05 * rng.standard_normal((trials, steps)))
    left = np.full((trials, steps), d / steps) * (1 + 0.05 * rng.standard_normal((trials, steps)))

    def seen(x):
        c = np.floor(np.cumsum(x, axis=1) / q) * q
        return np.diff(np.concatenate([np.zeros((trials, 1)), c], axis=1), axis=1)

    err = simulate(robot.wheel_base, right, left, seen(right), seen(left))
    dist = np.sum((right + left) / 2, axis=1)
    assert np.all(err <= drift_bound(robot, dist))


def test_random_noise_bound_by_false_alarm_rate():
    """Independent per-increment noise, e = 0: exceedances of the k-sigma bound are rare.

    The error is |(a, l)| <= |a| + |l| for the (near-gaussian) along-track a and lateral l
    parts, and the bound is k std(a) + k std(l), so P(exceed) <= 2 P(|N(0,1)| > 3) = 0.0054
    per trial. With n trials the count is at most Binomial(n, 0.0054); the threshold is its
    1e-3 upper quantile (false-alarm probability <= 1e-3).
    """
    robot = RobotSpec(wheel_radius_error=0.0, odometry_noise=0.01, encoder_ticks=10**9)
    delta, d, trials = 0.02, 0.6, 4000
    steps = int(round(d / delta))
    rng = np.random.default_rng(11)
    nominal = np.full((trials, steps), delta)
    right = nominal * (1 + robot.odometry_noise * rng.standard_normal((trials, steps)))
    left = nominal * (1 + robot.odometry_noise * rng.standard_normal((trials, steps)))
    err = simulate(robot.wheel_base, right, left, nominal, nominal)
    p_max = 2 * stats.norm.sf(3.0)
    limit = stats.binom.isf(1e-3, trials, p_max)
    assert np.sum(err > drift_bound(robot, d, increment=delta)) <= limit
    # negative control: the same test rejects a model that assumes 100x shorter increments
    assert np.sum(err > drift_bound(robot, d, increment=delta / 100)) > limit
    # fully correlated (increment=None) is a looser bound still
    assert drift_bound(robot, d, increment=None) > drift_bound(robot, d, increment=delta)


def test_vectorised_monotone_and_zero_at_rest():
    robot = RobotSpec()
    d = np.linspace(0.0, 3.0, 31)
    phi = np.linspace(0.0, 2.0, 31)
    out = drift_bound(robot, d[:, None], phi[None, :])
    assert out.shape == (31, 31)
    assert out[0, 0] == 0.0
    assert np.all(np.diff(out, axis=0) > 0) and np.all(np.diff(out, axis=1) >= 0)
    assert out[7, 3] == pytest.approx(drift_bound(robot, d[7], phi[3]))
    heavier = dataclasses.replace(robot, wheel_radius_error=0.01)
    assert drift_bound(heavier, 1.0) > drift_bound(robot, 1.0)
    assert drift_bound(robot, 1.0, heading_error=0.01) == pytest.approx(drift_bound(robot, 1.0) + 0.01)


def _numpy_bound(robot, d, phi, k_sigma=3.0, heading_error=0.0, increment=0.02):
    """Compute the bound as plain numpy expressions (the module doc's formula, numpy's order of operations)."""
    d, phi = np.asarray(d, float), np.abs(np.asarray(phi, float))
    b, e, sigma, q = robot.wheel_base, abs(robot.wheel_radius_error), robot.odometry_noise, encoder_step(robot)
    arc = 0.5 * b * phi
    systematic = e * (d + arc) + e * d * d / b + e * phi * d
    delta_d = d if increment is None else np.minimum(increment, d)
    delta_t = arc if increment is None else np.minimum(increment, arc)
    random_std = sigma * (np.sqrt(0.5 * delta_d * d) + math.sqrt(2.0 / 3.0) * np.sqrt(delta_d) * d ** 1.5 / b
                          + np.sqrt(0.5 * delta_t * arc) + np.sqrt(delta_t * 2.0 * arc) * d / b)
    quantisation = np.where((d > 0.0) | (phi > 0.0), q, 0.0) + 2.0 * q * d / b
    return systematic + k_sigma * random_std + quantisation + heading_error * d


@pytest.mark.parametrize("kw", [{}, {"increment": None}, {"increment": 0.005, "k_sigma": 2.0, "heading_error": 3e-3}])
def test_compiled_bound_is_the_numpy_formula_bit_for_bit(kw):
    robot = dataclasses.replace(RobotSpec(), wheel_radius_error=-0.003)
    rng = np.random.default_rng(21)
    d = np.concatenate([[0.0, 0.0, 1e-9, 0.005, 0.02], rng.uniform(0, 50, 5000), rng.exponential(0.01, 500)])
    phi = np.concatenate([[0.0, 0.4, 0.0, 0.0, 1e-3], rng.uniform(-6, 6, 5000), np.zeros(500)])
    ref = _numpy_bound(robot, d, phi, **kw)
    assert np.array_equal(drift_bound(robot, d, phi, **kw), ref)
    grid = drift_bound(robot, d[:60].reshape(6, 10), phi[:10], **kw)             # broadcast (6, 10)
    assert grid.shape == (6, 10) and np.array_equal(grid, _numpy_bound(robot, d[:60].reshape(6, 10), phi[:10], **kw))
    one = drift_bound(robot, 3.0, 0.2, **kw)
    assert isinstance(one, float) and one == float(_numpy_bound(robot, 3.0, 0.2, **kw))
    # negative control: a different increment is a different bound, so the comparison can tell
    assert not np.array_equal(drift_bound(robot, d, phi, **(kw | {"increment": 0.03})), ref)
