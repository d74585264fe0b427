"""The compiled scalar update is filterpy's ``ExtendedKalmanFilter.update``, number for number."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter

from estimators.update import joseph_update


def _filterpy(x, P, H, innovation, var):
    kf = ExtendedKalmanFilter(dim_x=x.size, dim_z=1)
    kf.x, kf.P = x.copy(), P.copy()
    # Hx returns 0 and z is the innovation: filterpy's residual z - Hx is then the innovation
    kf.update(np.array([innovation]), lambda _x: H[None, :], lambda _x: np.zeros(1), R=np.array([[var]]))
    return kf.x, kf.P


def _case(rng, n):
    A = rng.normal(size=(n, n))
    P = A @ A.T * 1e-4 + 1e-6 * np.eye(n)
    return rng.normal(size=n), P, rng.normal(size=n), float(rng.normal(0, 0.01)), float(rng.uniform(1e-6, 1e-4))


@pytest.mark.parametrize("n", [3, 4, 5])
def test_joseph_update_equals_filterpy(n):
    rng = np.random.default_rng(n)
    for _ in range(50):
        x, P, H, nu, var = _case(rng, n)
        want_x, want_P = _filterpy(x, P, H, nu, var)
        got_x, got_P = x.copy(), P.copy()
        joseph_update(got_x, got_P, H, nu, var)
        np.testing.assert_allclose(got_x, want_x, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(got_P, want_P, rtol=1e-10, atol=1e-18)


def test_a_different_noise_variance_is_told_apart():
    # negative control: the comparison above sees an R off by 10 %
    x, P, H, nu, var = _case(np.random.default_rng(7), 5)
    want_x, want_P = _filterpy(x, P, H, nu, var)
    got_x, got_P = x.copy(), P.copy()
    joseph_update(got_x, got_P, H, nu, 1.1 * var)
    assert not np.allclose(got_P, want_P, rtol=1e-10, atol=1e-18)
