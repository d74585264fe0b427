"""The PEF and its linearised kernels, cross-checked against independent computations.

The exact fault area (polygon clipping), shapely strip intersections, Monte-Carlo least
squares, plain numpy/scipy formulas; monotonicity; every built-in scenario.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
import shapely
from scipy import stats

import scenarios
from estimators.fault.exact import fault_area_of_point
from estimators.fault.linearized import (
    chi2_2dof_ppf,
    fix_strips,
    gdop,
    gdop_diameter,
    lsq_covariance,
    parallelogram,
    strip_polygon,
    unit_rows,
)
from planner.pef.map import PEF
from planner.pef.result import grid_centres
from planner.pef.visibility import scenario_sight_rule
from scenarios.errors import PlanningError
from scenarios.schema import PefModel

# Two-sided false-alarm probability of every statistical test here, and its normal quantile.
ALPHA = 1e-3
Z = stats.norm.ppf(1 - ALPHA / 2)  # 3.29


def make_scenario(markers, obstacles=(), k=2, model="strips", size=(20.0, 10.0), max_range=40.0,
                  bearing_deg=0.0, rel=1e-3, ab=0.002, gdop_level=0.95):
    """Build a scenario from marker positions and obstacle (center, size, yaw_deg) triples."""
    return scenarios.from_dict({
        "name": "test", "workspace": {"size": list(size)},
        "markers": [{"id": f"M{i}", "position": [float(p[0]), float(p[1])]} for i, p in enumerate(markers)],
        "obstacles": [{"center": list(c), "size": list(s), "yaw_deg": y} for c, s, y in obstacles],
        "sensor": {"relative_error": rel, "absolute_error": ab, "max_range": max_range,
                   "markers_per_fix": k, "bearing_error_deg": bearing_deg},
        "planning": {"eps_max": 0.05, "pef_model": model, "resolution": 0.5, "gdop_level": gdop_level},
    }, "test")


def random_geometry(rng, k, min_sin=0.2):
    """Draw a robot position and k markers around it whose directions are not nearly parallel."""
    while True:
        pos = rng.uniform(-1, 1, 2)
        ang = rng.uniform(0, 2 * np.pi, k)
        mk = pos + np.column_stack([np.cos(ang), np.sin(ang)]) * rng.uniform(1, 20, (k, 1))
        u, r = unit_rows(mk, pos)
        sines = [abs(u[i, 0] * u[j, 1] - u[i, 1] * u[j, 0]) for i, j in itertools.combinations(range(k), 2)]
        if max(sines) >= min_sin:
            return pos, mk, u, r


# --- linearised kernels ---------------------------------------------------------------------

def test_chi2_closed_form_matches_scipy():
    for p in (0.5, 0.9, 0.95, 0.99, 0.999):
        assert chi2_2dof_ppf(p) == pytest.approx(stats.chi2.ppf(p, 2), rel=1e-12)


def test_parallelogram_matches_the_exact_fault_area_below_one_percent_relative_error():
    """Linearised parallelogram vs the exact clipped fault area (estimators.fault.exact).

    Tolerance: an annulus boundary of radius r deviates from its tangent line over the
    parallelogram's half-length d/2 by the sagitta (d/2)^2 / (2r); with d <= 2 sqrt(2) rho / sin a
    that is <= rho * (rho / r) / sin^2 a, and a vertex where two such boundaries cross moves by
    that over sin a: relative to the diagonal, <= 2 Re / sin^3 a (Re = rho / r, the factor 2 for
    both strips). The exact polygon itself is an outer approximation within 1e-3 rho per arc,
    moving each corner by <= 2e-3 rho / sin a: relative <= 3e-3 / sin a. Checked for
    1e-5 <= Re <= 1e-2 and sin a >= 0.2.
    """
    rng = np.random.default_rng(3)
    for _ in range(60):
        re = 10 ** rng.uniform(-5, -2)
        pos, mk, u, r = random_geometry(rng, 2)
        s = abs(u[0, 0] * u[1, 1] - u[0, 1] * u[1, 0])
        rho = re * r
        area, diag = parallelogram(u[0], u[1], rho[0], rho[1])
        fa = fault_area_of_point(mk, pos, rho)
        tol = 2 * re / s ** 3 + 3e-3 / s
        assert fa.diameter == pytest.approx(float(diag), rel=tol)
        assert fa.area == pytest.approx(float(area), rel=tol)


def test_parallelogram_formulas_against_trigonometry():
    # Paper eqs. 10 and 12 with the angle written out.
    for alpha, r1, r2 in [(np.pi / 2, 0.01, 0.01), (0.3, 0.01, 0.03), (2.5, 0.02, 0.005)]:
        u1, u2 = np.array([1.0, 0.0]), np.array([np.cos(alpha), np.sin(alpha)])
        area, diag = parallelogram(u1, u2, r1, r2)
        assert area == pytest.approx(4 * r1 * r2 / np.sin(alpha))
        ref = 2 / np.sin(alpha) * np.sqrt(r1**2 + r2**2 + 2 * r1 * r2 * abs(np.cos(alpha)))
        assert diag == pytest.approx(ref)
    assert parallelogram([1.0, 0.0], [-1.0, 0.0], 0.01, 0.01)[1] == np.inf


def _shapely_strips(normals, half_widths, big=1e3):
    """Intersection of the strips as a shapely polygon (independent of strip_polygon)."""
    poly = shapely.box(-big, -big, big, big)
    for n, b in zip(normals, half_widths, strict=True):
        t = np.array([-n[1], n[0]])
        corners = [b * n + big * t, b * n - big * t, -b * n - big * t, -b * n + big * t]
        poly = poly.intersection(shapely.Polygon(corners))
    return poly


@pytest.mark.parametrize("k", [2, 3, 4, 6])
def test_strip_polygon_matches_shapely_intersection(k):
    rng = np.random.default_rng(k)
    for _ in range(10):
        _, _, u, r = random_geometry(rng, k)
        rho = rng.uniform(0.001, 0.01, k)
        sp = strip_polygon(u, rho)
        ref = _shapely_strips(u, rho)
        ref_v = np.asarray(ref.exterior.coords)[:-1]
        assert sp.area == pytest.approx(ref.area, rel=1e-9)
        ref_diam = max(np.hypot(*(a - b)) for a, b in itertools.combinations(ref_v, 2))
        assert sp.diameter == pytest.approx(ref_diam, rel=1e-9)
        assert len(sp.vertices) == len(shapely.Polygon(ref_v).simplify(0).exterior.coords) - 1


def test_strip_polygon_with_two_strips_is_the_parallelogram():
    rng = np.random.default_rng(11)
    for _ in range(20):
        _, _, u, _ = random_geometry(rng, 2)
        rho = rng.uniform(0.001, 0.01, 2)
        sp = strip_polygon(u, rho)
        area, diag = parallelogram(u[0], u[1], rho[0], rho[1])
        assert len(sp.vertices) == 4
        assert sp.area == pytest.approx(float(area), rel=1e-12)
        assert sp.diameter == pytest.approx(float(diag), rel=1e-12)


def test_bearing_strips_are_tangential_with_half_width_r_tan_xi():
    u = np.array([[1.0, 0.0], [0.0, 1.0]])
    n, b = fix_strips(u, [0.01, 0.02], r=[5.0, 10.0], bearing_error=0.01)
    assert n.tolist() == [[1.0, 0.0], [0.0, 1.0], [0.0, 1.0], [-1.0, 0.0]]
    assert b == pytest.approx([0.01, 0.02, 5 * np.tan(0.01), 10 * np.tan(0.01)])


def test_adding_a_strip_or_a_row_never_increases_the_error():
    rng = np.random.default_rng(5)
    for _ in range(40):
        _, _, u, _ = random_geometry(rng, 5)
        rho = rng.uniform(0.001, 0.01, 5)
        diam = [strip_polygon(u[:j], rho[:j]).diameter for j in range(2, 6)]
        rad = [gdop_diameter(u[:j], rho[:j], 0.95) for j in range(2, 6)]
        g = [gdop(u[:j]) for j in range(2, 6)]
        for seq in (diam, rad, g):
            assert all(b <= a * (1 + 1e-12) for a, b in itertools.pairwise(seq))


def _gauss_newton(markers, z, sigma, start, iterations=6):
    """Weighted nonlinear least squares for N range vectors z (N, k); returns (N, 2)."""
    x = np.repeat(start[None, :], len(z), axis=0)
    w = 1.0 / sigma**2
    for _ in range(iterations):
        diff = x[:, None, :] - markers[None]
        r = np.linalg.norm(diff, axis=-1)
        h = diff / r[..., None]
        a = np.einsum("nki,k,nkj->nij", h, w, h)
        b = np.einsum("nki,k,nk->ni", h, w, z - r)
        x = x + np.linalg.solve(a, b[..., None])[..., 0]
    return x


def test_gdop_matches_monte_carlo_least_squares():
    """E|e|^2 = sigma^2 GDOP^2 for equal, independent gaussian range errors.

    With e ~ N(0, sigma^2 (H^T H)^-1), |e|^2 has variance 2 sigma^4 (l1^2 + l2^2) (l = eigenvalues
    of (H^T H)^-1), so the mean over N samples is normal (CLT, N = 20000) with that variance / N;
    the test rejects at |z| > 3.29 (false alarm 1e-3). Negative control: a GDOP 5 % too large
    shifts E|e|^2 by 10 %, about 10 standard errors, and must be rejected by the same test.
    """
    rng = np.random.default_rng(20240611)
    markers = np.array([[0.0, 0.0], [10.0, 0.0], [3.0, 8.0]])
    pos = np.array([4.0, 3.0])
    sigma = 0.003
    u, r = unit_rows(markers, pos)
    n = 20000
    z = r[None] + sigma * rng.standard_normal((n, 3))
    est = _gauss_newton(markers, z, np.full(3, sigma), pos)
    e2 = np.sum((est - pos) ** 2, axis=1)
    lam = np.linalg.eigvalsh(np.linalg.inv(u.T @ u))
    se = np.sqrt(2 * sigma**4 * np.sum(lam**2) / n)

    def z_stat(g):
        return (e2.mean() - sigma**2 * g**2) / se

    assert abs(z_stat(gdop(u))) < Z
    assert abs(z_stat(1.05 * gdop(u))) > Z  # negative control


def test_lsq_covariance_and_gdop_diameter_match_monte_carlo():
    """Weighted LS with unequal sigma_i = rho_i / 3: P = (H^T W H)^-1 and the p-ellipse.

    (1) e^T P^-1 e ~ chi2(2): its mean over N = 20000 has sd 2 / sqrt(N); reject at |z| > 3.29.
    Negative control: P 10 % too large must be rejected (expected shift ~13 sd).
    (2) The fraction of fixes inside the p = 0.95 ellipse is binomial(N, p); reject at
    |frac - p| > 3.29 sqrt(p (1 - p) / N). (3) Every fix inside the ellipse lies within tau / 2
    of the truth (tau is the ellipse's major axis).
    """
    rng = np.random.default_rng(7)
    markers = np.array([[0.0, 0.0], [12.0, 1.0], [5.0, 9.0]])
    pos = np.array([6.0, 3.0])
    u, r = unit_rows(markers, pos)
    rho = 1e-3 * r + 0.002
    sigma = rho / 3
    n = 20000
    est = _gauss_newton(markers, r[None] + sigma * rng.standard_normal((n, 3)), sigma, pos)
    e = est - pos
    p_cov = lsq_covariance(u, sigma)

    def mean_z(cov):
        d2 = np.einsum("ni,ij,nj->n", e, np.linalg.inv(cov), e)
        return (d2.mean() - 2.0) / (2.0 / np.sqrt(n)), d2

    z0, d2 = mean_z(p_cov)
    assert abs(z0) < Z
    assert abs(mean_z(1.1 * p_cov)[0]) > Z  # negative control
    p = 0.95
    inside = d2 <= stats.chi2.ppf(p, 2)
    assert abs(inside.mean() - p) <= Z * np.sqrt(p * (1 - p) / n)
    tau = gdop_diameter(u, rho, p)
    assert np.all(np.hypot(*e[inside].T) <= tau / 2 * (1 + 1e-12))
    assert np.hypot(*e[inside].T).max() > 0.9 * tau / 2  # the semi-major axis is reached, not loose


# --- the PEF ----------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def warehouse():
    return scenarios.load("warehouse")


def _sample_cells(pm, rng, n):
    iy, ix = np.nonzero(pm.free & np.isfinite(pm.tau))
    sel = rng.choice(len(iy), size=min(n, len(iy)), replace=False)
    return iy[sel], ix[sel], np.column_stack([pm.x[ix[sel]], pm.y[iy[sel]]])


def test_gdop_pef_matches_independent_numpy(warehouse):
    pef = PEF(warehouse, model="gdop")
    pm = pef.grid(0.5)
    iy, ix, pts = _sample_cells(pm, np.random.default_rng(1), 150)
    vis = pef.visible(pts)
    mk = warehouse.marker_positions()
    c = stats.chi2.ppf(warehouse.planning.gdop_level, 2)
    for n, p in enumerate(pts):
        best = np.inf
        for sub in itertools.combinations(np.flatnonzero(vis[n]), 2):
            d = p - mk[list(sub)]
            rr = np.linalg.norm(d, axis=1)
            h = d / rr[:, None]
            w = np.diag(9.0 / (warehouse.sensor.relative_error * rr + warehouse.sensor.absolute_error) ** 2)
            info = h.T @ w @ h
            if np.linalg.cond(info) > 1e12:
                continue  # (nearly) collinear: no fix
            best = min(best, 2 * np.sqrt(c * np.linalg.eigvalsh(np.linalg.inv(info)).max()))  # major axis
        # Candidates are ranked in float32 (documented): the chosen tau is within 1e-6 of the minimum.
        assert pm.tau[iy[n], ix[n]] == pytest.approx(best, rel=1e-5)


def test_parallelogram_pef_matches_independent_trigonometry(warehouse):
    pef = PEF(warehouse, model="parallelogram")
    pm = pef.grid(0.5)
    iy, ix, pts = _sample_cells(pm, np.random.default_rng(2), 150)
    vis = pef.visible(pts)
    mk = warehouse.marker_positions()
    for n, p in enumerate(pts):
        best, best_sub = np.inf, None
        for i, j in itertools.combinations(np.flatnonzero(vis[n]), 2):
            a = np.arctan2(*(p - mk[i])[::-1]) - np.arctan2(*(p - mk[j])[::-1])
            r1, r2 = np.linalg.norm(p - mk[i]), np.linalg.norm(p - mk[j])
            rho1, rho2 = (warehouse.sensor.range_bound(r) for r in (r1, r2))
            d = 2 / abs(np.sin(a)) * np.sqrt(rho1**2 + rho2**2 + 2 * rho1 * rho2 * abs(np.cos(a)))
            if d < best:
                best, best_sub = d, (i, j)
        assert pm.tau[iy[n], ix[n]] == pytest.approx(best, rel=1e-5)
        if pm.tau[iy[n], ix[n]] != pytest.approx(best, rel=1e-12):
            continue  # a float32 near-tie may pick another pair of the same error
        assert tuple(pm.best[iy[n], ix[n]]) == best_sub


def test_strips_with_two_markers_equals_parallelogram(warehouse):
    a = PEF(warehouse, model="strips").grid(0.25)
    b = PEF(warehouse, model="parallelogram").grid(0.25)
    assert np.array_equal(np.isinf(a.tau), np.isinf(b.tau))
    f = np.isfinite(a.tau)
    np.testing.assert_allclose(a.tau[f], b.tau[f], rtol=1e-5)


def test_grid_is_the_points_path_on_cell_centres(warehouse):
    for model in ("parallelogram", "gdop", "strips"):
        pef = PEF(warehouse, model=model)
        pm = pef.grid(0.4)
        xx, yy = np.meshgrid(pm.x, pm.y)
        r = pef.at(np.column_stack([xx.ravel(), yy.ravel()]))
        assert np.array_equal(r.tau, pm.tau.ravel())
        assert np.array_equal(r.best, pm.best.reshape(-1, pef.k))


def _random_scenario(rng, n_markers, k, model):
    markers = np.column_stack([rng.uniform(0, 20, n_markers), rng.uniform(0, 10, n_markers)])
    obstacles = [((float(rng.uniform(4, 16)), float(rng.uniform(3, 7))), (float(rng.uniform(0.5, 3)), 1.0),
                  float(rng.uniform(0, 180))) for _ in range(2)]
    sc = make_scenario(markers, obstacles, k=k, model=model, max_range=15.0)
    return sc, markers, obstacles


@pytest.mark.parametrize("model, k", [("strips", 2), ("strips", 3), ("gdop", 2), ("gdop", 3)])
def test_adding_a_marker_never_increases_the_pef(model, k):
    rng = np.random.default_rng(100 + k)
    for _ in range(3):
        while True:
            try:
                sc, markers, obstacles = _random_scenario(rng, 7, k, model)
                less = make_scenario(markers[:-1], obstacles, k=k, model=model, max_range=15.0)
                break
            except scenarios.ScenarioError:  # a marker fell inside an obstacle: draw again
                continue
        full_map = PEF(sc).grid(0.5)
        full, fewer = full_map.tau, PEF(less).grid(0.5).tau
        # The added reflector's body blocks the others' lines of sight, as its post does in the
        # physics (planner.pef.sight): the claim holds where no line of sight to the other markers
        # passes within the body, its reach and the rule's margin of it.
        rule = scenario_sight_rule(sc)
        clear = _clear_of(full_map.x, full_map.y, markers[:-1], markers[-1],
                          rule.radius + rule.reach + rule.margin + 1e-6)
        assert clear.mean() > 0.5  # the claim is tested on most of the floor
        # gdop ranks candidates in float32 (documented): allow 1e-5 relative; strips is exact.
        slack = 1e-5 if model == "gdop" else 0.0
        assert np.all(full[clear] <= fewer[clear] * (1 + slack))
        assert np.any(full[clear] < fewer[clear] * (1 - 1e-3))  # the extra marker matters somewhere


def _clear_of(x, y, others, body, distance):
    """Cells (ny, nx) from which every segment to ``others`` (M, 2) passes farther than ``distance`` from ``body``."""
    px, py = np.meshgrid(x, y)
    clear = np.ones(px.shape, dtype=bool)
    for mx, my in others:
        dx, dy = mx - px, my - py
        t = np.clip(((body[0] - px) * dx + (body[1] - py) * dy) / np.maximum(dx * dx + dy * dy, 1e-300), 0.0, 1.0)
        clear &= np.hypot(px + t * dx - body[0], py + t * dy - body[1]) > distance
    return clear


def test_fewer_than_k_visible_markers_gives_inf_and_no_subset():
    # A wall-to-wall obstacle splits the floor: M0 left, M1 and M2 right.
    sc = make_scenario([(0.0, 5.0), (20.0, 2.0), (20.0, 8.0)], [((10.0, 5.0), (1.0, 10.0), 0.0)])
    pef = PEF(sc)
    r = pef.at([[5.0, 5.0], [15.0, 5.0], [10.0, 5.0]])
    assert r.tau[0] == np.inf and r.best[0].tolist() == [-1, -1]
    assert np.isfinite(r.tau[1]) and r.best[1].tolist() == [1, 2]
    assert r.tau[2] == np.inf  # inside the obstacle
    assert PEF(sc, k=3).at([[15.0, 5.0]]).tau[0] == np.inf


def test_tau_subset(warehouse):
    pef = PEF(warehouse)
    pts = np.array([[3.0, 2.0], [27.0, 18.0], [15.0, 3.0]])
    r = pef.at(pts)
    for n in range(2):
        assert pef.tau_subset(pts[n:n + 1], r.best[n])[0] == r.tau[n]
    vis = pef.visible(pts)
    hidden = np.flatnonzero(~vis[2])[:1].tolist() + np.flatnonzero(vis[2])[:1].tolist()
    assert pef.tau_subset(pts[2:], hidden)[0] == np.inf
    with pytest.raises(PlanningError, match="subset"):
        pef.tau_subset(pts, [0, 0])
    with pytest.raises(PlanningError, match="subset"):
        pef.tau_subset(pts, [0, 99])


def test_bearings_shrink_strips_and_gdop():
    markers = [(0.0, 0.0), (20.0, 0.0), (10.0, 10.0)]
    pts = np.array([[5.0, 2.0], [12.0, 6.0], [18.0, 9.0]])
    for model in ("strips", "gdop"):
        plain = PEF(make_scenario(markers, model=model)).at(pts)
        with_b = PEF(make_scenario(markers, model=model, bearing_deg=0.01)).at(pts)
        assert np.all(with_b.tau < plain.tau)
        # Independent: the strips of the chosen subset, bearings included.
        sc = make_scenario(markers, model=model, bearing_deg=0.01)
        for n, p in enumerate(pts):
            mk = sc.marker_positions()[with_b.best[n]]
            u, r = unit_rows(mk, p)
            normals, half = fix_strips(u, sc.sensor.range_bound(r), r, sc.sensor.bearing_error)
            ref = (strip_polygon(normals, half).diameter if model == "strips"
                   else gdop_diameter(normals, half, sc.planning.gdop_level))
            assert with_b.tau[n] == pytest.approx(ref, rel=1e-9)


def test_exact_model_is_the_fault_area_of_the_best_subset():
    sc = scenarios.load("paper-two-markers")
    # (1.0, 4.0), not (0.5, 4.5): from there the corner marker (0, 0) is seen at 6 degrees to the
    # west wall, inside the mount wedge of planner.pef.sight (a line of sight the plan does not count on)
    pts = np.array([[1.0, 1.5], [2.5, 2.5], [4.0, 3.0], [1.0, 4.0]])
    exact = PEF(sc, model="exact").at(pts)
    lin = PEF(sc, model="parallelogram").at(pts)
    for n, p in enumerate(pts):
        mk = sc.marker_positions()
        rho = sc.sensor.range_bound(np.linalg.norm(p - mk, axis=1))
        assert exact.tau[n] == fault_area_of_point(mk, p, rho).diameter
        assert exact.tau[n] == pytest.approx(lin.tau[n], rel=1e-2)


def test_exact_model_candidate_pruning_loses_nothing_on_the_warehouse(warehouse):
    pruned = PEF(warehouse, model="exact").grid(2.5)
    full = PEF(warehouse, model="exact", exact_margin=math.inf).grid(2.5)
    assert np.array_equal(pruned.tau, full.tau)
    assert np.isfinite(pruned.tau).sum() > 50


def test_bad_arguments_are_planning_errors(warehouse):
    with pytest.raises(PlanningError, match="model"):
        PEF(warehouse, model="bogus")
    with pytest.raises(PlanningError, match="needs k = 2, got 3"):
        PEF(warehouse, model="parallelogram", k=3)
    with pytest.raises(PlanningError, match="resolution"):
        PEF(warehouse).grid(0.0)
    with pytest.raises(PlanningError, match="cells"):
        PEF(warehouse).grid(1e-4)
    with pytest.raises(PlanningError, match="points"):
        PEF(warehouse).at(np.zeros((3, 3)))


def test_grid_centres_divide_the_workspace_evenly():
    x, y = grid_centres((30.0, 20.0), 0.7)
    assert x.size == 43 and y.size == 29
    assert x[0] == pytest.approx(30.0 / 43 / 2) and x[-1] == pytest.approx(30.0 - 30.0 / 43 / 2)


@pytest.mark.parametrize("name", scenarios.builtin_names())
def test_every_builtin_scenario_maps(name):
    sc = scenarios.load(name)
    pef = PEF(sc)
    assert pef.model is sc.planning.pef_model and pef.k == sc.sensor.markers_per_fix
    pm = pef.grid(max(sc.workspace.size) / 60)
    assert pm.tau.shape == pm.free.shape == (pm.y.size, pm.x.size)
    assert pm.best.shape == pm.tau.shape + (pef.k,)
    assert np.isfinite(pm.tau).any()
    assert np.all(np.isinf(pm.tau[~pm.free]))
    xx, yy = np.meshgrid(pm.x, pm.y)
    for ob in sc.obstacles:  # cells inside every obstacle are not free
        pts = zip(xx.ravel(), yy.ravel(), strict=True)
        inside = np.array([ob.contains(p) for p in pts]).reshape(xx.shape)
        assert not pm.free[inside].any() and np.all(np.isinf(pm.tau[inside]))
    fin = np.isfinite(pm.tau_plain)  # best is the plain best subset (tau is tau_r with redundancy)
    assert np.all(pm.best[fin] >= 0) and np.all(pm.best[~fin] == -1)
    assert np.all(pm.tau >= pm.tau_plain)
    assert np.all(pm.tau[fin] > 0)
    assert pm.model is PefModel(sc.planning.pef_model)


@pytest.mark.parametrize("redundancy", [0, 1])
def test_points_asked_twice_get_the_values_of_points_asked_once(warehouse, redundancy):
    """PEF.at evaluates a repeated point once and hands each copy that point's values.

    The same points without repeats, in another order, give each point the same tau, best,
    tau_plain and fallback bit for bit (every point's value is its own). Negative control: the
    answers of the shuffled points read in the asked order do not match (the points differ in
    tau, so a wrong row would show).
    """
    sc = warehouse
    pef = PEF(sc, redundancy=redundancy)
    rng = np.random.default_rng(3)
    x0, y0, x1, y1 = sc.workspace.bounds
    once = np.column_stack([rng.uniform(x0, x1, 200), rng.uniform(y0, y1, 200)])
    pick = rng.integers(0, len(once), 500)
    twice = once[pick]
    got = pef.at(twice, widen=0.05)
    shuffle = rng.permutation(len(once))
    ref = pef.at(once[shuffle], widen=0.05)
    row = np.argsort(shuffle)[pick]
    for name in ("tau", "best", "tau_plain", "fallback"):
        np.testing.assert_array_equal(getattr(got, name), getattr(ref, name)[row])
    assert np.isfinite(got.tau).sum() > 100 and np.unique(got.tau[np.isfinite(got.tau)]).size > 100
    assert not np.array_equal(got.tau, ref.tau[pick])


def test_tau_subset_asked_again_answers_as_the_first_time(warehouse):
    """The last tau_subset is remembered: asked again it is the same, and not the caller's edited copy.

    Negative control: other subsets at the same points (a question the memo must not answer
    with the last answer) give other values.
    """
    pef = PEF(warehouse)
    rng = np.random.default_rng(4)
    x0, y0, x1, y1 = warehouse.workspace.bounds
    pts = np.column_stack([rng.uniform(x0, x1, 300), rng.uniform(y0, y1, 300)])
    subs = np.array([[0, 1], [2, 5], [3, 7]])
    first = pef.tau_subset(pts, subs)
    want = first.copy()
    first[:] = -1.0
    np.testing.assert_array_equal(pef.tau_subset(pts, subs), want)
    other = pef.tau_subset(pts, subs[:, ::-1] + 1)
    assert np.isfinite(want).sum() > 50 and not np.array_equal(other, want)
