"""Tests of the compiled ranges-only Gauss-Newton and the closed-form fix covariance.

The compiled iteration (``lsq._gauss_newton_ranges``) against the numpy one
(``lsq._gauss_newton``, still used with bearings) on random noisy fixes; the singular
fallback; the snapshot covariance against ``numpy.linalg.inv``.
"""

import numpy as np

from estimators import lsq, snapshot
from estimators.measurements import ranges


def _fixes(seed, n):
    """Noisy ranges-only fixes (k = 2..4) with priors 1 cm to 1 m off: (markers, z, std, prior)."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        k = int(rng.integers(2, 5))
        markers = rng.uniform([0, 0], [30, 20], size=(k, 2))
        truth = rng.uniform([0, 0], [30, 20])
        r = ranges(truth, markers)
        if np.any(r < 1.0):
            continue
        std = rng.uniform(0.001, 0.02, k)
        z = r + rng.normal(0.0, std)
        out.append((markers, z, std, truth + rng.normal(0.0, rng.choice([0.01, 0.1, 1.0]), 2)))
    return out


def _info_cond(markers, std, p):
    d = p - markers
    jw = d / np.hypot(d[:, 0], d[:, 1])[:, None] / std[:, None]
    return np.linalg.cond(jw.T @ jw)


def test_compiled_gauss_newton_follows_the_numpy_iteration():
    """Same iterations (+-1), positions within 1e-9 m on well-conditioned fixes (cond < 1e6).

    Both run the same arithmetic but sum in different orders (BLAS vs scalar loops), so they
    agree to rounding amplified by the conditioning: ~1e-16 * 1e6 * 10 m = 1e-9 m.
    Negative control: the check tells apart a fit with one weight changed by 10 %.
    """
    compared, control_caught = 0, 0
    for markers, z, std, prior in _fixes(1, 400):
        ref = lsq._gauss_newton(markers, z, 1.0 / std, prior.copy(), None, 20, 1e-10)
        if not ref.converged or ref.iterations >= 20 or _info_cond(markers, std, ref.position) >= 1e6:
            continue
        compared += 1
        sol = lsq.solve_position(markers, z, std, prior)
        # termination compares a ~1e-10 m step (or a cost change) with a threshold: rounding
        # can move it by one iteration
        assert abs(sol.iterations - ref.iterations) <= 1 and sol.converged
        np.testing.assert_allclose(sol.position, ref.position, rtol=0, atol=1e-9)
        np.testing.assert_allclose(sol.residuals, ref.residuals, rtol=0, atol=1e-9)
        np.testing.assert_allclose(sol.jacobian, ref.jacobian, rtol=0, atol=1e-9)
        other = std.copy()
        other[0] *= 1.1
        moved = lsq.solve_position(markers, z, other, prior).position
        control_caught += np.abs(moved - ref.position).max() > 1e-9
    assert compared >= 300
    # with k = 2 the circles usually cross: any weights fit them exactly (no change), so the
    # control is only expected to catch the over-determined k >= 3 fixes (about 2/3 of them)
    assert control_caught >= 0.5 * compared, (control_caught, compared)


def test_singular_step_falls_back_to_numpy():
    """On the marker line the normal matrix is singular: the numpy least-squares step answers."""
    markers = np.array([[0.0, 0.0], [5.0, 0.0]])
    z, std, prior = np.array([2.0, 3.0]), np.array([0.002, 0.002]), np.array([1.0, 0.0])
    assert not lsq._gauss_newton_ranges(markers, z, 1.0 / std, prior, 20, 1e-10)[-1]
    sol = lsq.solve_position(markers, z, std, prior)
    ref = lsq._gauss_newton(markers, z, 1.0 / std, prior.copy(), None, 20, 1e-10)
    np.testing.assert_array_equal(sol.position, ref.position)
    assert sol.iterations == ref.iterations


def test_closed_form_covariance_is_the_inverse_information():
    for markers, z, std, prior in _fixes(2, 100):
        sol = lsq.solve_position(markers, z, std, prior)
        jw = sol.jacobian / std[:, None]
        info = jw.T @ jw
        cov = snapshot._covariance(sol.jacobian, std)
        np.testing.assert_allclose(cov, np.linalg.inv(info), rtol=1e-9)
        np.testing.assert_allclose(cov @ info, np.eye(2), atol=1e-9)
    on_line = np.array([[1.0, 0.0], [1.0, 0.0]])        # both unit rows parallel: rank 1
    assert np.all(np.isinf(snapshot._covariance(on_line, np.array([0.01, 0.02]))))
