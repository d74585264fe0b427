"""Every PEF model reports the same quantity, a diameter of the error region (the paper's d).

The models agree where their assumptions overlap, each checked through the planner's
:class:`planner.pef.map.PEF` (the numba kernels) against an independent numpy computation:

(a) ``gdop``: for gaussian range errors ``sigma = rho / 3`` the linearised least-squares error
    falls inside the p-level ellipse with probability p, and tau is that ellipse's major axis
    (twice the semi-major), not its semi-major;
(b) ``parallelogram`` and ``strips`` with k = 2 are the same polygon (1e-9 relative);
(c) ``exact`` and ``parallelogram`` differ only by the linearisation, of order rho / r.

Every comparison has a negative control that must fail: the old gdop radius (tau / 2), the
parallelogram's short diagonal, the half diagonal. Seeds are fixed; statistical thresholds come
from a stated false-alarm probability, tolerances from a derivation in the test's docstring.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

import scenarios
from estimators.fault.exact import DEFAULT_TOLERANCE_FRACTION, fault_area_of_point
from estimators.fault.linearized import chi2_2dof_ppf, parallelogram, unit_rows
from planner.pef.map import PEF

#: Two-sided false-alarm probability of each statistical test function (Bonferroni-split over
#: its geometries and statistics).
ALPHA = 1e-3


def scenario(markers, model, k=None, rel=1e-3, ab=0.002, level=0.95, size=(20.0, 12.0)):
    """Open-floor scenario with the given markers, ranges only, k markers per fix (default: all)."""
    return scenarios.from_dict({
        "name": "agree", "workspace": {"size": list(size)},
        "markers": [{"id": f"M{i}", "position": [float(x), float(y)]} for i, (x, y) in enumerate(markers)],
        "sensor": {"relative_error": rel, "absolute_error": ab, "max_range": 100.0,
                   "markers_per_fix": len(markers) if k is None else k},
        "planning": {"eps_max": 0.05, "pef_model": model, "resolution": 0.5, "gdop_level": level},
    }, "test")


def in_interval(k: int, n: int, p: float, alpha: float) -> bool:
    """Whether p lies in the two-sided Clopper-Pearson interval of k successes in n at level 1 - alpha."""
    ci = stats.binomtest(k, n).proportion_ci(confidence_level=1.0 - alpha, method="exact")
    return ci.low <= p <= ci.high


def ellipse_semi_major_sampled(p_cov: np.ndarray, c: float, n: int) -> float:
    """Largest |x| over n boundary points ``x = sqrt(c) L (cos t, sin t)`` of ``x^T P^-1 x = c``.

    Independent of an eigen-decomposition: ``L`` is the Cholesky factor of P.
    """
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    x = math.sqrt(c) * np.linalg.cholesky(p_cov) @ np.vstack([np.cos(t), np.sin(t)])
    return float(np.hypot(*x).max())


# Robot at (8, 5); marker sets seen at 90 deg, at 40 deg (long, thin ellipse), and three markers.
POSITION = np.array([8.0, 5.0])
GEOMETRIES = {
    "right angle": [(0.0, 5.0), (8.0, 12.0)],
    "40 deg": [(0.0, 5.0), (8.0 - 9.0 * math.cos(math.radians(40)), 5.0 + 9.0 * math.sin(math.radians(40)))],
    "three markers": [(0.0, 0.0), (19.0, 2.0), (10.0, 11.0)],
}


@pytest.mark.parametrize("level", [0.5, 0.95])
def test_gdop_tau_is_the_major_axis_of_an_ellipse_that_covers_p(level):
    """(a) Coverage of the gdop ellipse, and tau as its major axis.

    Linearised LS error ``delta = (H^T W H)^-1 H^T W e`` with ``e ~ N(0, (rho / 3)^2)``, N = 20000
    draws per geometry; P, H, W built here in numpy, tau from the PEF kernel.

    1. Coverage: the count with ``delta^T P^-1 delta <= chi2.ppf(p, 2)`` is binomial(N, p); p
       must lie in its Clopper-Pearson interval. Negative control: errors 10 % larger than the
       model's sigma (coverage ~0.92 instead of 0.95, ~20 standard errors off) must be rejected.
    2. Diameter identity: the ellipse's semi-major from n = 4096 boundary points is within
       ``[cos(pi / n), 1]`` of the true one (the nearest sample is within pi / n of the maximum
       in the parameter, and ``|x(t)|^2 >= c lambda_1 cos^2(t - t*)``), so
       ``2 semi_sampled / tau`` must lie in ``[cos(pi / n), 1]`` up to 1e-12 rounding. Negative
       control: the old radius (tau / 2) gives 2, outside.
    3. Along the major axis: ``|delta . v| <= tau / 2`` holds with probability
       ``chi2.cdf(chi2.ppf(p, 2), 1)``; Clopper-Pearson again. Negative control: the old
       radius, ``|delta . v| <= tau / 4``, has probability ``chi2.cdf(c / 4, 1)`` (0.78 instead of
       0.99 at p = 0.95) and must be rejected.

    False alarms: 2 statistics x 3 geometries share ALPHA (Bonferroni).
    """
    alpha = ALPHA / (2 * len(GEOMETRIES))
    c = chi2_2dof_ppf(level)
    n_draws, n_boundary = 20000, 4096
    rng = np.random.default_rng(20250611)
    for name, markers in GEOMETRIES.items():
        sc = scenario(markers, "gdop", level=level)
        mk = sc.marker_positions()
        tau = float(PEF(sc).tau_subset(POSITION[None], np.arange(len(mk)))[0])
        u, r = unit_rows(mk, POSITION)
        sigma = sc.sensor.range_bound(r) / 3.0
        w = sigma ** -2.0
        info = (u * w[:, None]).T @ u
        p_cov = np.linalg.inv(info)
        gain = p_cov @ (u * w[:, None]).T          # (2, k): delta = gain @ e

        def coverage_ok(scale, p_cov_inv=info, gain=gain, sigma=sigma):
            e = scale * sigma * rng.standard_normal((n_draws, sigma.size))
            d = e @ gain.T
            inside = np.einsum("ni,ij,nj->n", d, p_cov_inv, d) <= c
            return in_interval(int(inside.sum()), n_draws, level, alpha)

        assert coverage_ok(1.0), name
        assert not coverage_ok(1.1), name  # negative control: wrong sigma

        semi = ellipse_semi_major_sampled(p_cov, c, n_boundary)
        lo, hi = math.cos(math.pi / n_boundary) * (1 - 1e-12), 1 + 1e-12
        assert lo <= 2.0 * semi / tau <= hi, name
        assert not lo <= 2.0 * semi / (tau / 2.0) <= hi, name  # negative control: the old radius

        v = np.linalg.eigh(p_cov)[1][:, -1]  # major-axis direction
        delta = (sigma * rng.standard_normal((n_draws, sigma.size))) @ gain.T
        along = np.abs(delta @ v)
        p_axis = stats.chi2.cdf(c, 1)
        assert in_interval(int(np.sum(along <= tau / 2.0)), n_draws, p_axis, alpha), name
        assert not in_interval(int(np.sum(along <= tau / 4.0)), n_draws, p_axis, alpha), name  # old radius


def test_parallelogram_and_strips_agree_for_two_markers():
    """(b) For k = 2 the strip polygon is the parallelogram: the same tau to 1e-9 relative.

    Both through the PEF kernels, per marker pair at 200 random points (so the float32 ranking
    of candidates plays no part), and the whole map where both chose the same pair. Negative
    control: the short diagonal ``(2 / sin a) sqrt(rho1^2 + rho2^2 - 2 rho1 rho2 |cos a|)``,
    computed here in numpy, is a diameter of the same parallelogram only at 90 deg, and must
    differ from the strips by more than 1e-9 somewhere.
    """
    rng = np.random.default_rng(5)
    markers = [(0.0, 0.0), (20.0, 0.0), (20.0, 12.0), (3.0, 12.0), (11.0, 6.5)]
    par = PEF(scenario(markers, "parallelogram", k=2))
    strips = PEF(scenario(markers, "strips", k=2))
    pts = rng.uniform((0.5, 0.5), (19.5, 11.5), (200, 2))
    short_off = 0.0
    for pair in par.subsets:
        tp, ts = par.tau_subset(pts, pair), strips.tau_subset(pts, pair)
        ok = np.isfinite(tp)
        assert np.array_equal(ok, np.isfinite(ts))
        np.testing.assert_allclose(tp[ok], ts[ok], rtol=1e-9)
        mk = par.markers[pair]
        for p, t in zip(pts[ok], ts[ok], strict=True):  # t: the strips' tau at p, from the call above
            u, r = unit_rows(mk, p)
            rho = par.sensor.range_bound(r)
            sn, cs = abs(u[0, 0] * u[1, 1] - u[0, 1] * u[1, 0]), abs(u[0] @ u[1])
            short = 2.0 / sn * math.sqrt(rho[0] ** 2 + rho[1] ** 2 - 2.0 * rho[0] * rho[1] * cs)
            short_off = max(short_off, abs(short / t - 1.0))
    assert short_off > 1e-9  # negative control
    mp, ms = par.grid(0.5), strips.grid(0.5)
    same = np.all(mp.best == ms.best, axis=-1) & np.isfinite(mp.tau)
    assert same.mean() > 0.99
    np.testing.assert_allclose(mp.tau[same], ms.tau[same], rtol=1e-9)


def linearisation_bounds(d: float, rho: np.ndarray, r: np.ndarray, poly_tol: float) -> tuple[float, float]:
    """Bounds on ``d_exact / d_parallelogram`` for ranges only, two markers.

    With ``p = R + delta``: ``|p - M_i| = r_i + u_i . delta + q_i``, ``0 <= q_i <=
    |delta|^2 / (2 (r_i - |delta|))`` (exact, from the square root). On the ball ``|delta| <= D``
    the annulus therefore lies between the strips of half-widths ``rho_i -+ eta_i``,
    ``eta_i = D^2 / (2 (r_i - D))``, and the parallelogram diagonal is homogeneous of degree 1
    and increasing in each rho, so ``d(rho_i + x_i) <= d(rho) (1 + max_i x_i / rho_i)``. The exact
    polygon contains the fault area and lies in that of ``rho + poly_tol``
    (:mod:`estimators.fault.exact`). Hence, with ``e = max_i eta_i / rho_i`` and D = 0.55 d
    (asserted to contain the enlarged parallelogram, half-diagonal
    ``d / 2 (1 + e + poly_tol / rho_min)``, so the component of R cannot leave the ball):
    ``1 - e <= d_exact / d <= 1 + e + poly_tol / rho_min``; ``e`` is ``O(d / r) = O(rho / (r sin^2 a))``.
    """
    big_d = 0.55 * d
    e = float(np.max(big_d ** 2 / (2.0 * (r - big_d)) / rho))
    hi = 1.0 + e + poly_tol / rho.min()
    assert d / 2.0 * hi < big_d, "noise too large for the first-order bound"
    return 1.0 - e, hi


def test_exact_and_parallelogram_agree_at_small_noise():
    """(c) ``exact`` vs ``parallelogram`` within the linearisation bound (:func:`linearisation_bounds`).

    Through the PEF on ``paper-two-markers`` (Re = 6.7e-5: the polygon tolerance 1e-3 dominates)
    and, with a fine polygon (1e-7 rho_min) so that the linearisation term dominates, on random
    geometries with Re from 1e-5 to 1e-3, ranges 2-20 m and sin a >= 0.3. Negative control at
    every point: the half diagonal (the radius convention gdop used to follow) falls outside the
    same bounds.

    The bound is first order and one-sided safe, not sharp: the sagitta terms ``q_i`` are even in
    delta, so they move opposite vertices alike and translate the region; the diameter changes
    only at second order in rho / r, and the observed deviations stay far below the bound.
    """
    sc = scenarios.load("paper-two-markers")
    exact, par = PEF(sc, model="exact"), PEF(sc, model="parallelogram")
    # points from which the sight rule sees both markers
    pts = np.array([[1.0, 1.5], [2.5, 2.5], [4.0, 3.0], [1.2, 4.0], [2.5, 0.8], [3.8, 4.2]])
    te, tp = exact.tau_subset(pts, [0, 1]), par.tau_subset(pts, [0, 1])
    for p, e, d in zip(pts, te, tp, strict=True):
        r = np.hypot(*(p - exact.markers).T)
        rho = sc.sensor.range_bound(r)
        lo, hi = linearisation_bounds(d, rho, r, DEFAULT_TOLERANCE_FRACTION * rho.min())
        assert lo <= e / d <= hi, p
        assert not lo <= e / (d / 2.0) <= hi  # negative control: the half diagonal

    rng = np.random.default_rng(17)
    for _ in range(40):
        while True:
            pos = rng.uniform(-1.0, 1.0, 2)
            ang = rng.uniform(0.0, 2.0 * np.pi, 2)
            mk = pos + np.column_stack([np.cos(ang), np.sin(ang)]) * rng.uniform(2.0, 20.0, (2, 1))
            u, r = unit_rows(mk, pos)
            if abs(u[0, 0] * u[1, 1] - u[0, 1] * u[1, 0]) >= 0.3:
                break
        rho = 10 ** rng.uniform(-5.0, -3.0) * r
        poly_tol = 1e-7 * rho.min()
        d = float(parallelogram(u[0], u[1], rho[0], rho[1])[1])
        e = fault_area_of_point(mk, pos, rho, tolerance=poly_tol).diameter
        lo, hi = linearisation_bounds(d, rho, r, poly_tol)
        assert lo <= e / d <= hi
        assert not lo <= e / (d / 2.0) <= hi  # negative control: the half diagonal
