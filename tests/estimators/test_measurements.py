"""Tests of the measurement models.

Jacobians against finite differences, noise draws against their stated distributions, and
the paper's eq. 14 Jacobian against H^-1.
"""

import math

import numpy as np
import pytest
from scipy import stats

from estimators.lsq import solve_position
from estimators.measurements import (
    bearing,
    bearing_jacobian,
    bearing_std,
    draw_bearing_errors,
    draw_range_errors,
    range_bound,
    range_jacobian,
    range_std,
    ranges,
    world_bearing,
    world_bearing_jacobian,
    wrap_angle,
)
from scenarios.schema import NoiseModel, SensorSpec

H_FD = 1e-6  # finite-difference step [m] / [rad]: central-difference error O(h^2) ~ 1e-12


def _central_diff(f, x, h=H_FD):
    x = np.asarray(x, dtype=float)
    cols = []
    for j in range(x.size):
        e = np.zeros_like(x)
        e[j] = h
        cols.append((f(x + e) - f(x - e)) / (2 * h))
    return np.column_stack(cols)


def _random_setup(rng, k):
    markers = rng.uniform([0, 0], [30, 20], size=(k, 2))
    pose = np.array([*rng.uniform([0, 0], [30, 20]), rng.uniform(-np.pi, np.pi)])
    return markers, pose


def test_wrap_angle_range_and_equivalence():
    a = np.linspace(-20, 20, 4001)
    w = wrap_angle(a)
    assert np.all(w > -np.pi) and np.all(w <= np.pi)
    # Same angle: differs by a multiple of 2 pi.
    k = (a - w) / (2 * np.pi)
    np.testing.assert_allclose(k, np.round(k), atol=1e-9)
    assert wrap_angle(np.pi) == pytest.approx(np.pi)
    assert wrap_angle(-np.pi) == pytest.approx(np.pi)
    assert wrap_angle(3 * np.pi / 2) == pytest.approx(-np.pi / 2)
    assert isinstance(wrap_angle(0.5), float)


def test_ranges_shapes_and_values():
    markers = np.array([[0.0, 0.0], [3.0, 4.0]])
    pts = np.zeros((5, 7, 2))
    assert ranges(pts, markers).shape == (5, 7, 2)
    np.testing.assert_allclose(ranges(np.array([0.0, 0.0]), markers), [0.0, 5.0])


@pytest.mark.parametrize("seed", range(5))
def test_range_jacobian_matches_finite_differences(seed):
    rng = np.random.default_rng(seed)
    markers, pose = _random_setup(rng, 4)
    jac = range_jacobian(pose[:2], markers)
    fd = _central_diff(lambda p: ranges(p, markers), pose[:2])
    np.testing.assert_allclose(jac, fd, atol=1e-7)
    np.testing.assert_allclose(np.linalg.norm(jac, axis=1), 1.0)   # rows are unit vectors u_i


@pytest.mark.parametrize("seed", range(5))
def test_bearing_jacobian_matches_finite_differences(seed):
    rng = np.random.default_rng(100 + seed)
    markers, pose = _random_setup(rng, 4)
    jac = bearing_jacobian(pose, markers)
    assert jac.shape == (4, 3)
    # Differences of wrapped bearings must be unwrapped before dividing.
    fd = _central_diff(lambda q: wrap_angle(bearing(q, markers) - bearing(pose, markers)), pose)
    np.testing.assert_allclose(jac, fd, atol=1e-6)
    fdw = _central_diff(lambda p: wrap_angle(world_bearing(p, markers) - world_bearing(pose[:2], markers)),
                        pose[:2])
    np.testing.assert_allclose(world_bearing_jacobian(pose[:2], markers), fdw, atol=1e-6)


def test_bearing_is_world_direction_minus_heading():
    pose = np.array([1.0, 2.0, 0.5])
    markers = np.array([[4.0, 2.0], [1.0, 5.0], [-3.0, 2.0]])
    b = bearing(pose, markers)
    np.testing.assert_allclose(b, wrap_angle(np.array([0.0, np.pi / 2, np.pi]) - 0.5))
    assert np.all(b > -np.pi) and np.all(b <= np.pi)


def test_range_bound_is_relative_plus_absolute():
    sensor = SensorSpec(relative_error=1e-3, absolute_error=0.002)
    np.testing.assert_allclose(range_bound(sensor, np.array([0.0, 10.0])), [0.002, 0.012])
    assert range_bound(sensor, 10.0) == pytest.approx(0.012)


# Normalised errors z = e / std have E[z^2] = 1. By the CLT the mean of n values of z^2 is
# normal with sd sqrt(Var(z^2) / n): Var(z^2) = 2 for gaussian z, 4/5 for z = sqrt(3) U,
# U ~ U(-1, 1) (E z^4 = 9/5). Two-sided false-alarm 1e-3 -> |mean - 1| <= 3.29 sd.
N_NOISE = 20000
Q_NOISE = stats.norm.ppf(1 - 1e-3 / 2)
VAR_Z2 = {NoiseModel.GAUSSIAN: 2.0, NoiseModel.UNIFORM: 0.8}


def _mean_z2_ok(z, model):
    return abs(np.mean(z**2) - 1.0) <= Q_NOISE * math.sqrt(VAR_Z2[model] / z.size)


@pytest.mark.parametrize("model", list(NoiseModel))
def test_range_errors_follow_their_std(model):
    rng = np.random.default_rng(7)
    rho = np.full(N_NOISE, 0.004)
    e = draw_range_errors(rng, rho, model)
    assert _mean_z2_ok(e / range_std(rho, model), model)
    if model is NoiseModel.UNIFORM:
        assert np.all(np.abs(e) <= rho)
    else:
        # P(|e| > rho) = P(|z| > 3) = 0.0027: ~54 of 20000; none would have prob e^-54.
        assert np.sum(np.abs(e) > rho) > 0
    # Negative control: the other model's std is rejected by the same statistic.
    other = NoiseModel.GAUSSIAN if model is NoiseModel.UNIFORM else NoiseModel.UNIFORM
    assert not _mean_z2_ok(e / range_std(rho, other), model)


@pytest.mark.parametrize("model", list(NoiseModel))
def test_bearing_errors_follow_their_std(model):
    rng = np.random.default_rng(8)
    xi = math.radians(0.5)
    e = draw_bearing_errors(rng, xi, N_NOISE, model)
    assert e.shape == (N_NOISE,)
    assert _mean_z2_ok(e / bearing_std(xi, model), model)
    other = NoiseModel.GAUSSIAN if model is NoiseModel.UNIFORM else NoiseModel.UNIFORM
    assert not _mean_z2_ok(e / bearing_std(xi, other), model)


def test_range_std_values():
    assert range_std(0.003, NoiseModel.GAUSSIAN) == pytest.approx(0.001)
    assert range_std(0.003, "uniform") == pytest.approx(0.003 / math.sqrt(3))


def test_solve_position_recovers_noise_free_position():
    rng = np.random.default_rng(3)
    markers, pose = _random_setup(rng, 3)
    sol = solve_position(markers, ranges(pose[:2], markers), np.full(3, 0.002), pose[:2] + [0.7, -0.4])
    assert sol.converged
    np.testing.assert_allclose(sol.position, pose[:2], atol=1e-9)
    wb = world_bearing(pose[:2], markers)
    sol = solve_position(markers, ranges(pose[:2], markers), np.r_[np.full(3, 0.002), np.full(3, 1e-3)],
                         pose[:2] + [0.3, 0.2], world_bearings=wb)
    np.testing.assert_allclose(sol.position, pose[:2], atol=1e-9)
    assert sol.jacobian.shape == (6, 2)


@pytest.mark.parametrize("xy", [(2.5, 2.0), (1.0, 3.0), (4.0, 0.5), (-2.0, 4.0), (7.0, 6.0), (2.5, 40.0)])
def test_paper_eq14_jacobian_is_inverse_of_h(xy):
    """Paper eq. 14 for M1 = (0, 0), M2 = (m, 0), m = 5, robot (x_R, y_R) with y_R > 0.

    Finding: with H the range Jacobian (rows u_1^T, u_2^T; H maps (dx, dy) -> (da, db)),
    J = [[a/m, -b/m], [a(m - x_R)/(m y_R), x_R b/(m y_R)]] equals H^-1 exactly (to rounding),
    entry by entry, with no transpose: rows of J are (dx, dy), columns are (da, db). So J maps
    range errors to position errors, (dx, dy) = J (da, db) -- docs/design.md §1's "H^-1 is exactly
    the paper's J" holds, and eq. 14's "GDOP = J" is the Jacobian of the *inverse*
    measurement function (position from ranges). We also check that direction independently
    by differentiating the paper's eq. 1 (x, y from a, b) by finite differences.
    """
    m = 5.0
    x, y = xy
    markers = np.array([[0.0, 0.0], [m, 0.0]])
    a, b = ranges(np.array(xy), markers)
    j_paper = np.array([[a / m, -b / m], [a * (m - x) / (m * y), x * b / (m * y)]])
    h = range_jacobian(np.array(xy), markers)
    np.testing.assert_allclose(np.linalg.inv(h), j_paper, rtol=1e-12, atol=1e-12)
    assert not np.allclose(np.linalg.inv(h).T, j_paper)   # the transpose is NOT J

    def eq1(ab):   # paper eq. 1, upper solution (y > 0)
        xx = (m**2 + ab[0] ** 2 - ab[1] ** 2) / (2 * m)
        return np.array([xx, math.sqrt(ab[0] ** 2 - xx**2)])

    np.testing.assert_allclose(_central_diff(eq1, np.array([a, b])), j_paper, rtol=1e-6, atol=1e-8)


def test_solve_position_reaches_the_weighted_least_squares_optimum_on_noisy_data():
    """Check Gauss-Newton stops at the optimum of inconsistent (noisy) data.

    The minimum has nonzero residuals: the solver must stop there (converged, few
    iterations) with the normal equations H^T W r = 0 satisfied relative to their terms.
    """
    rng = np.random.default_rng(11)
    for _ in range(20):
        markers, pose = _random_setup(rng, 3)
        std = np.r_[np.full(3, 0.003), np.full(3, math.radians(0.3))]
        z = ranges(pose[:2], markers) + rng.normal(0, std[:3])
        wb = world_bearing(pose[:2], markers) + rng.normal(0, std[3:])
        sol = solve_position(markers, z, std, pose[:2] + rng.normal(0, 0.05, 2), world_bearings=wb)
        assert sol.converged and sol.iterations <= 10
        w2 = 1.0 / std**2
        grad = sol.jacobian.T @ (w2 * sol.residuals)
        scale = np.abs(sol.jacobian.T) @ (w2 * np.abs(sol.residuals))
        assert np.all(np.abs(grad) <= 1e-6 * scale)
