"""Tests of the exact fault area.

Containment (with a negative control), the outer-approximation tolerance, agreement with
the linearised parallelogram (`docs/design.md` §1, paper eqs. 10 and 12) and its breakdown at large
relative error, mirror resolution, empty sets.
"""

import math

import numpy as np
import pytest
import shapely
from scipy import stats

from estimators.fault.exact import DEFAULT_TOLERANCE_FRACTION, exact_fault_area, fault_area_of_point
from estimators.measurements import draw_bearing_errors, draw_range_errors, ranges, world_bearing
from scenarios.schema import NoiseModel

N_GEOMETRIES = 300
XI = math.radians(0.5)   # bearing error bound used where bearings are tested [rad]


def _line_distance(p, a, b):
    d = b - a
    return abs(d[0] * (p[1] - a[1]) - d[1] * (p[0] - a[0])) / math.hypot(*d)


def _geometries(seed, k, n=N_GEOMETRIES):
    """Random fixes in a 30 x 20 m floor: (markers (k,2), truth (2,), rho (k,), prior (2,)).

    Sensors range from the paper's laser to 1 % relative error. The prior is the truth plus
    5 mm gaussian error (an EKF's); fixes whose truth is within 10 cm of the line through two
    markers are skipped, since there no prior can tell the mirror regions apart.
    """
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        markers = rng.uniform([0, 0], [30, 20], size=(k, 2))
        truth = rng.uniform([0, 0], [30, 20])
        r = ranges(truth, markers)
        if np.any(r < 1.0) or np.any(r > 25.0):
            continue
        if k == 2 and _line_distance(truth, *markers) < 0.1:
            continue
        rho = rng.uniform(6.7e-5, 1e-2) * r + rng.uniform(1e-3, 5e-3)
        out.append((markers, truth, rho, truth + rng.normal(0.0, 0.005, 2), rng))
    return out


def _contained(fa, point):
    """Tell whether ``point`` is inside the polygon, or within its tolerance of it.

    The polygon is an outer approximation, so the first is expected; the second guards only
    against rounding.
    """
    if fa.is_empty:
        return False
    return fa.contains(point) or fa.polygon.distance(shapely.points(point)) <= fa.tolerance


@pytest.mark.parametrize("k", [2, 3])
def test_truth_is_contained_with_uniform_errors_and_not_at_1_5_rho(k):
    """Containment every time with |e| <= rho; negative control with errors in +-1.5 rho.

    With e_i ~ U(-1.5 rho_i, 1.5 rho_i) the truth is outside the exact set iff some
    |e_i| > rho_i: probability p = 1 - (2/3)^k (0.56 for k=2, 0.70 for k=3), whatever the
    geometry. The failure count is Binomial(n, p); we require it above the 1e-6 quantile
    (false alarm 1e-6), i.e. a "substantial fraction" of about p.
    """
    misses, fails = 0, 0
    for markers, truth, rho, prior, rng in _geometries(10 + k, k):
        r = ranges(truth, markers)
        z = r + draw_range_errors(rng, rho, NoiseModel.UNIFORM)
        misses += not _contained(exact_fault_area(markers, z, rho, prior), truth)
        z_bad = r + draw_range_errors(rng, 1.5 * rho, NoiseModel.UNIFORM)
        fails += not _contained(exact_fault_area(markers, z_bad, rho, prior), truth)
    assert misses == 0
    p_fail = 1 - (2 / 3) ** k
    assert fails >= stats.binom.ppf(1e-6, N_GEOMETRIES, p_fail), (fails, N_GEOMETRIES, p_fail)


def test_truth_is_contained_with_bearings_and_not_at_1_5_xi():
    """Ranges + world bearings (wedges with bound xi): containment every time.

    Negative control: bearing errors in +-1.5 xi and exact ranges, p_fail = 1 - (2/3)^2.
    """
    misses, fails = 0, 0
    geoms = _geometries(21, 2, n=150)
    for markers, truth, rho, prior, rng in geoms:
        r = ranges(truth, markers)
        wb = world_bearing(truth, markers)
        z = r + draw_range_errors(rng, rho, NoiseModel.UNIFORM)
        b = wb + draw_bearing_errors(rng, XI, 2, NoiseModel.UNIFORM)
        fa = exact_fault_area(markers, z, rho, prior, bearings=b, bearing_error=XI)
        misses += not _contained(fa, truth)
        b_bad = wb + draw_bearing_errors(rng, 1.5 * XI, 2, NoiseModel.UNIFORM)
        fa = exact_fault_area(markers, r, rho, prior, bearings=b_bad, bearing_error=XI)
        fails += not _contained(fa, truth)
    assert misses == 0
    assert fails >= stats.binom.ppf(1e-6, len(geoms), 1 - (2 / 3) ** 2), fails


@pytest.mark.parametrize("use_bearings", [False, True])
def test_polygon_is_an_outer_approximation_within_tolerance(use_bearings):
    """Check the polygon lies between the exact set and the exact set with rho + tol.

    Every sampled exact point is inside the polygon; every polygon vertex violates the
    exact range constraints by at most the tolerance.
    """
    rng = np.random.default_rng(5)
    for markers, truth, rho, prior, _ in _geometries(31, 2, n=20):
        z = ranges(truth, markers) + draw_range_errors(rng, rho, NoiseModel.UNIFORM)
        b = world_bearing(truth, markers) if use_bearings else None
        fa = exact_fault_area(markers, z, rho, prior, bearings=b, bearing_error=XI if use_bearings else 0.0)
        tol = fa.tolerance
        assert tol == pytest.approx(DEFAULT_TOLERANCE_FRACTION * rho.min())
        # Samples from a box around the polygon, kept where the exact constraints hold.
        x0, y0, x1, y1 = fa.polygon.bounds
        pts = rng.uniform([x0 - 0.2 * (x1 - x0), y0 - 0.2 * (y1 - y0)],
                          [x1 + 0.2 * (x1 - x0), y1 + 0.2 * (y1 - y0)], size=(4000, 2))
        ok = np.all(np.abs(ranges(pts, markers) - z) <= rho, axis=1)
        if use_bearings:
            direction = np.arctan2(markers[:, 1] - pts[:, 1:2], markers[:, 0] - pts[:, :1])
            dev = np.angle(np.exp(1j * (direction - b)))
            ok &= np.all(np.abs(dev) <= XI, axis=1)
        assert ok.sum() > 100
        assert np.all(shapely.intersects_xy(fa.polygon, pts[ok, 0], pts[ok, 1]))
        # Vertices: distance to each annulus within tol.
        v = shapely.get_coordinates(fa.polygon)
        excess = np.abs(ranges(v, markers) - z) - rho
        assert np.all(excess <= tol * (1 + 1e-6))
        # And the polygon is not much bigger than the exact set: sampled outside-fraction.
        inside_poly = shapely.intersects_xy(fa.polygon, pts[:, 0], pts[:, 1])
        assert np.sum(inside_poly & ~ok) <= 0.01 * np.sum(inside_poly)


# --- exact vs linearised (`docs/design.md` §1, paper eqs. 10 and 12) --------------------------------
#
# Tolerance from the curvature. Away from the marker line the map p -> (a, b) = (|p - M1|,
# |p - M2|) is a diffeomorphism with Jacobian determinant sin(alpha(a, b)), and the noise-free
# fault area is the preimage of the rectangle [a0 +- rho1] x [b0 +- rho2]. Hence, exactly,
#     A_exact = integral over the rectangle of g(a, b) da db,   g = 1 / sin(alpha).
# The rectangle is centred on (a0, b0): the first-order terms of g integrate to zero, so
#     A_exact / A_lin - 1 = (rho1^2 g_aa + rho2^2 g_bb) / (6 g) + O(eps^4),
# second order in eps = max(rho_i / r_i), not first. With beta_i the triangle's angle at M_i,
# alpha_a = -cot(beta1) / a, beta1_a = -cot(alpha) / a (law of cosines and sines) give
#     a^2 g_aa / g = cot^2 b1 (1 + 2 cot^2 alpha) - cot alpha cot b1 + cot^2 alpha / sin^2 b1
# (likewise for b), each term bounded by 4 / (sin^2 alpha sin^2 b1). So
#     |A_exact / A_lin - 1| <= (4/3) eps^2 / (sin^2 alpha sin^2 beta_min)        (*)
# The long diagonal is p(+D) - p(-D) = 2 J D + O(D^3) (even terms cancel): its relative
# error is second order too, and we hold it to the same bound (*). We allow 2x (*) for the
# O(eps^4) terms, plus the polygonisation (the polygon lies inside the exact set of bounds
# rho_i + tol): area relative +<= tol (1/rho1 + 1/rho2) <= 2 tol / rho_min (doubled), and
# each end of the diagonal moves <= 2 tol / sin(alpha) (two strip edges shifted by tol).
# For Re <= 1 % with alpha in [30, 150] deg and beta_i in [20, 160] deg, (*) x 2 is <= 0.9 %.


def _triangle(markers, p):
    d = p - markers
    r = np.hypot(d[:, 0], d[:, 1])
    u = d / r[:, None]
    sin_a = abs(u[0, 0] * u[1, 1] - u[0, 1] * u[1, 0])
    cos_a = abs(u[0] @ u[1])
    e = (markers[1] - markers[0]) / np.linalg.norm(markers[1] - markers[0])
    sin_b = np.array([abs(-u[0, 0] * e[1] + u[0, 1] * e[0]), abs(u[1, 0] * e[1] - u[1, 1] * e[0])])
    return r, sin_a, cos_a, sin_b


def _linearised(rho, sin_a, cos_a):
    """`docs/design.md` §1: parallelogram area and long diagonal of two strips."""
    area = 4 * rho[0] * rho[1] / sin_a
    diag = 2 / sin_a * math.sqrt(rho[0] ** 2 + rho[1] ** 2 + 2 * rho[0] * rho[1] * cos_a)
    return area, diag


def _well_conditioned(seed, n):
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        markers = rng.uniform([0, 0], [30, 20], size=(2, 2))
        p = rng.uniform([0, 0], [30, 20])
        r, sin_a, cos_a, sin_b = _triangle(markers, p)
        if (sin_a >= 0.5 and sin_b.min() >= math.sin(math.radians(20))
                and np.all(r > 1.0) and np.all(r < 25.0)):
            out.append((markers, p))
    return out


RHO0 = 1e-4           # small absolute error [m]
POLY_FRACTION = 1e-5  # polygonisation tolerance used here, as a fraction of rho_min


def _errors(markers, p, re):
    r, sin_a, cos_a, sin_b = _triangle(markers, p)
    rho = re * r + RHO0
    fa = fault_area_of_point(markers, p, rho, tolerance=POLY_FRACTION * rho.min())
    area, diag = _linearised(rho, sin_a, cos_a)
    eps = float(np.max(rho / r))
    curv = 2 * (4 / 3) * eps**2 / (sin_a**2 * sin_b.min() ** 2)
    tol_area = curv + 4 * POLY_FRACTION
    tol_diam = curv + 4 * POLY_FRACTION * rho.min() / (sin_a * diag)
    return abs(fa.area / area - 1), abs(fa.diameter / diag - 1), tol_area, tol_diam


@pytest.mark.parametrize("re", [6.7e-5, 1e-3, 5e-3, 1e-2])
def test_exact_matches_parallelogram_for_small_relative_error(re):
    for markers, p in _well_conditioned(41, 60):
        err_a, err_d, tol_a, tol_d = _errors(markers, p, re)
        assert err_a <= tol_a, (markers, p, err_a, tol_a)
        assert err_d <= tol_d, (markers, p, err_d, tol_d)
        assert tol_a < 0.01


def test_parallelogram_breaks_down_toward_10_percent():
    """Check the parallelogram model fails at Re = 10 %.

    The exact area leaves the tolerance that holds for Re <= 1 % in every geometry of the
    set (the error grows ~ Re^2), and the diameter in most of them.
    """
    out_a, out_d, geoms = 0, 0, _well_conditioned(41, 60)
    for markers, p in geoms:
        _, _, tol_a, tol_d = _errors(markers, p, 1e-2)
        err_a, err_d, _, _ = _errors(markers, p, 0.1)
        out_a += err_a > tol_a
        out_d += err_d > tol_d
    assert out_a == len(geoms)
    assert out_d >= 0.5 * len(geoms)


def test_exact_area_matches_second_order_curvature_prediction():
    """Check the polygon captures the curvature, not just the linearisation.

    Its area matches A_lin (1 + (rho1^2 g_aa + rho2^2 g_bb) / (6 g)) (derivation above) to
    within 5 % of the correction, with a polygonisation tolerance far below it. A linear
    (parallelogram) area would miss the correction by 100 %.
    """
    re = 3e-3
    for markers, p in _well_conditioned(43, 25):
        r, sin_a, cos_a, sin_b = _triangle(markers, p)
        rho = re * r
        fa = fault_area_of_point(markers, p, rho, tolerance=1e-9 * rho.min())
        area, _ = _linearised(rho, sin_a, cos_a)
        cot_a = (cos_a if (p - markers[0]) @ (p - markers[1]) > 0 else -cos_a) / sin_a
        m_vec = markers[1] - markers[0]
        cos_b = np.array([(p - markers[0]) @ m_vec, (p - markers[1]) @ -m_vec]) / (r * np.linalg.norm(m_vec))
        cot_b = cos_b / sin_b
        bracket = cot_b**2 * (1 + 2 * cot_a**2) - cot_a * cot_b + cot_a**2 / sin_b**2
        predicted = float(np.sum(rho**2 * bracket / r**2) / 6)
        measured = fa.area / area - 1
        assert abs(measured - predicted) <= 0.05 * abs(predicted) + 4e-9, (measured, predicted)


# --- selection, empties, consistency ----------------------------------------------------


@pytest.mark.parametrize("y", [3.0, 0.5])
def test_side_ambiguity_resolved_toward_prior(y):
    markers = np.array([[0.0, 0.0], [5.0, 0.0]])
    truth = np.array([2.0, y])
    z = ranges(truth, markers)
    rho = np.array([0.002, 0.002])
    up = exact_fault_area(markers, z, rho, prior=np.array([2.3, 0.2]))
    down = exact_fault_area(markers, z, rho, prior=np.array([1.0, -7.0]))
    assert up.contains(truth) and not down.contains(truth)
    mirror = truth * [1, -1]
    assert down.contains(mirror) and not up.contains(mirror)
    np.testing.assert_allclose(down.centroid, up.centroid * [1, -1], atol=1e-9)
    assert down.area == pytest.approx(up.area, rel=1e-9)
    assert up.centroid[1] > 0 > down.centroid[1]


def test_inconsistent_measurements_give_empty_area():
    markers = np.array([[0.0, 0.0], [5.0, 0.0]])
    fa = exact_fault_area(markers, np.array([1.0, 1.0]), np.array([0.01, 0.01]), np.array([2.5, 0.5]))
    assert fa.is_empty and fa.area == 0.0 and math.isnan(fa.diameter)
    assert np.all(np.isnan(fa.centroid)) and not fa.contains(np.array([2.5, 0.0]))
    # Three circles with a pairwise but no common intersection: also empty.
    m3 = np.array([[0.0, 0.0], [5.0, 0.0], [0.0, 5.0]])
    z = ranges(np.array([2.0, 1.0]), m3) + [0.05, 0.0, 0.0]
    assert exact_fault_area(m3, z, np.full(3, 0.002), np.array([2.0, 1.0])).is_empty


def test_fault_area_of_point_equals_exact_of_noise_free_ranges():
    for markers, truth, rho, _, _ in _geometries(51, 3, n=20):
        a = fault_area_of_point(markers, truth, rho)
        b = exact_fault_area(markers, ranges(truth, markers), rho, truth)
        assert a.contains(truth)
        assert a.area == pytest.approx(b.area, rel=1e-6)
        assert a.diameter == pytest.approx(b.diameter, rel=1e-6)


def test_more_markers_and_bearings_never_enlarge_the_area():
    """Intersecting more constraints can only shrink the set (up to the tolerance)."""
    for markers, truth, rho, _, _ in _geometries(61, 3, n=20):
        two = fault_area_of_point(markers[:2], truth, rho[:2])
        three = fault_area_of_point(markers, truth, rho)
        brg = fault_area_of_point(markers[:2], truth, rho[:2], bearing_error=XI)
        assert three.area <= two.area * (1 + 1e-3)
        assert brg.area <= two.area * (1 + 1e-3)
        assert three.diameter <= two.diameter * (1 + 1e-3)


def test_large_error_area_spanning_the_marker_line_is_one_region():
    """Check that near the marker line, with 10 % errors, the mirror regions merge.

    The single region is symmetric about the line (no side left to choose).
    """
    markers = np.array([[0.0, 0.0], [5.0, 0.0]])
    truth = np.array([2.0, 0.05])
    fa = fault_area_of_point(markers, truth, 0.1 * ranges(truth, markers))
    assert fa.contains(truth) and fa.contains(truth * [1, -1])
    assert abs(fa.centroid[1]) < 1e-6


def test_rejects_bad_shapes_and_bounds():
    markers = np.array([[0.0, 0.0], [5.0, 0.0]])
    with pytest.raises(ValueError, match="rho"):
        exact_fault_area(markers, np.array([3.0, 3.0]), np.array([0.0, 0.01]), np.zeros(2))
    with pytest.raises(ValueError, match="bearing_error"):
        exact_fault_area(markers, np.array([3.0, 3.0]), np.array([0.01, 0.01]), np.zeros(2),
                         bearings=np.zeros(2))
    with pytest.raises(ValueError, match="ranges"):
        exact_fault_area(markers, np.array([3.0]), np.array([0.01, 0.01]), np.zeros(2))


def test_single_range_gives_the_whole_annulus():
    """One range: the window grows until it holds the whole annulus (full-circle polygons).

    Exact area 4 pi r rho; the outer approximation adds at most perimeter * tol, i.e. a
    relative 2 pi (2r + 2rho) tol / (4 pi r rho) ~ tol / rho = 1e-3.
    """
    marker = np.array([[3.0, 4.0]])
    r, rho = np.array([2.5]), np.array([0.01])
    fa = exact_fault_area(marker, r, rho, np.array([3.0, 1.0]))
    exact = 4 * math.pi * r[0] * rho[0]
    assert exact <= fa.area <= exact * (1 + 1.01e-3 * (1 + rho[0] / r[0]))
    assert fa.diameter == pytest.approx(2 * (r[0] + rho[0]), abs=3 * fa.tolerance)
    np.testing.assert_allclose(fa.centroid, marker[0], atol=1e-9)
