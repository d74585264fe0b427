"""The compiled scalar update is filterpy's ``ExtendedKalmanFilter.update``, number for number."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter

from estimators.update import gated_joseph_update, joseph_update, wrap_scalar


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


def _gated_reference(x, P, H, nu, var, gate):
    # the localiser's former numpy steps
    s = float(H @ P @ H) + var
    nis = nu * nu / s
    if nis > gate:
        return False, nis, s
    joseph_update(x, P, H, nu, var)
    x[2] = wrap_scalar(x[2])
    return True, nis, s


@pytest.mark.parametrize("n", [3, 4, 6])
def test_the_gated_update_is_the_gate_then_the_update(n):
    rng = np.random.default_rng(10 + n)
    outcomes = set()
    for _ in range(200):
        x, P, H, nu, var = _case(rng, n)
        x[2] = rng.uniform(-4.0, 4.0)  # a heading to wrap
        nu *= float(rng.choice([1.0, 30.0]))  # some far outside the gate
        gate = float(rng.choice([0.5, 3.84, np.inf]))
        want_x, want_P = x.copy(), P.copy()
        want = _gated_reference(want_x, want_P, H, nu, var, gate)
        got_x, got_P = x.copy(), P.copy()
        got = gated_joseph_update(got_x, got_P, H, nu, var, gate)
        assert got == pytest.approx(want, rel=1e-12)
        np.testing.assert_allclose(got_x, want_x, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(got_P, want_P, rtol=1e-10, atol=1e-18)
        outcomes.add(got[0])
        if not got[0]:  # negative control: a gated measurement leaves the state as it was
            assert np.array_equal(got_x, x) and np.array_equal(got_P, P)
    assert outcomes == {True, False}
