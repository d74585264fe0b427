"""Pure-numpy geometry for recordings: ellipses, strip polygons, contours, rings.

Kept apart from :mod:`sim.recording` so that it can be tested without rerun and so the
recording modules only hold the mapping of arrays onto entities. Everything here is in
metres in the workspace frame and vectorised over steps or fixes.
"""

from __future__ import annotations

import math

import numpy as np

ELLIPSE_SEGMENTS = 48
"""Segments of a covariance-ellipse polygon: the chord error is 1 - cos(pi/48) ~ 0.2 %."""


def chi2_2dof_radius(p: float) -> float:
    """Mahalanobis radius of the p-level region of a 2-D Gaussian.

    For two degrees of freedom the chi-square CDF is 1 - exp(-r^2/2), so the radius has a
    closed form and needs no scipy.

    Parameters
    ----------
    p : float
        Probability in (0, 1).

    Returns
    -------
    float
        k such that P(d^T P^-1 d <= k^2) = p.
    """
    if not 0.0 < p < 1.0:
        raise ValueError(f"probability must lie in (0, 1), got {p}")
    return math.sqrt(-2.0 * math.log1p(-p))


def covariance_ellipses(centers: np.ndarray, pos_cov: np.ndarray, p: float,
                        segments: int = ELLIPSE_SEGMENTS) -> np.ndarray:
    """Return closed polygons of the p-level ellipses of 2x2 position covariances.

    Parameters
    ----------
    centers : (T, 2) float
        Ellipse centres [m].
    pos_cov : (T, 2, 2) float
        Position covariances [m^2] (symmetric; tiny negative eigenvalues from round-off
        are clipped to zero).
    p : float
        Probability mass inside each ellipse.
    segments : int
        Polygon segments per ellipse.

    Returns
    -------
    (T, segments + 1, 2) float
        Closed rings (first point repeated last) [m].
    """
    k = chi2_2dof_radius(p)
    cov = np.asarray(pos_cov, dtype=float)
    a, b, c = cov[:, 0, 0], 0.5 * (cov[:, 0, 1] + cov[:, 1, 0]), cov[:, 1, 1]
    # Closed-form eigen-decomposition of a symmetric 2x2 matrix (np.linalg.eigh on T tiny
    # matrices costs more than the rest of the recording).
    mean, half_gap = 0.5 * (a + c), np.hypot(0.5 * (a - c), b)
    major_std = np.sqrt(np.clip(mean + half_gap, 0.0, None))[:, None]     # [m]
    minor_std = np.sqrt(np.clip(mean - half_gap, 0.0, None))[:, None]
    angle = 0.5 * np.arctan2(2.0 * b, a - c)[:, None]                    # major axis direction [rad]
    cos_a, sin_a = np.cos(angle), np.sin(angle)
    phi = np.linspace(0.0, 2.0 * np.pi, segments + 1)[None, :]
    along = k * major_std * np.cos(phi)                                   # (T, S+1) [m]
    across = k * minor_std * np.sin(phi)
    ctr = np.asarray(centers, dtype=float)
    ring = np.empty(along.shape + (2,))
    ring[..., 0] = ctr[:, 0:1] + cos_a * along - sin_a * across
    ring[..., 1] = ctr[:, 1:2] + sin_a * along + cos_a * across
    ring[:, -1] = ring[:, 0]                                              # exact closure
    return ring


def heading_vectors(theta: np.ndarray, length: float) -> np.ndarray:
    """Arrow vectors of ``length`` [m] along headings ``theta`` (T,) [rad]; returns (T, 2)."""
    theta = np.asarray(theta, dtype=float)
    return length * np.stack([np.cos(theta), np.sin(theta)], axis=-1)


def closed_ring(points: np.ndarray) -> np.ndarray:
    """Return ``points`` (n, 2) with the first point appended, unless already closed or empty."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(pts) == 0 or np.array_equal(pts[0], pts[-1]):
        return pts
    return np.vstack([pts, pts[:1]])


def rectangle_ring(width: float, height: float, origin: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """Return the closed ring (5, 2) of the rectangle ``origin + [0, width] x [0, height]`` [m]."""
    x0, y0 = origin
    return np.array([[x0, y0], [x0 + width, y0], [x0 + width, y0 + height], [x0, y0 + height], [x0, y0]])


def strip_polygons(positions: np.ndarray, marker_xy: np.ndarray, rho: np.ndarray) -> list[np.ndarray]:
    """Linearised fault areas: intersections of the strips ``|u_i . d| <= rho_i`` around each position.

    This is the parallelogram of `docs/design.md` §1 for k = 2 and the centrally symmetric
    strip polygon for k > 2. Its vertices are the pairwise intersections of the strips'
    boundary lines that satisfy every strip. Same polygon as
    :func:`estimators.fault.linearized.strip_polygon` (the tests compare them), vectorised over
    fixes: a loop over that function costs ~30x more for a recording's hundred fixes.

    Parameters
    ----------
    positions : (F, 2) float
        Points at which to linearise (the true positions of the fixes) [m].
    marker_xy : (F, k, 2) float
        Positions of each fix's markers [m].
    rho : (F, k) float
        Range error bounds of each fix's measurements [m].

    Returns
    -------
    list of F arrays (n_f, 2)
        Closed rings, counter-clockwise [m]; empty (0, 2) where the strips do not bound a
        polygon (fewer than two independent directions, e.g. collinear markers).
    """
    pos = np.asarray(positions, dtype=float)
    mk = np.asarray(marker_xy, dtype=float)
    rho = np.asarray(rho, dtype=float)
    n_fix, k = rho.shape
    diff = pos[:, None, :] - mk                                           # (F, k, 2)
    u = diff / np.linalg.norm(diff, axis=-1, keepdims=True)
    verts, valid = [], []
    for i in range(k):
        for j in range(i + 1, k):
            a = np.stack([u[:, i], u[:, j]], axis=1)                      # (F, 2, 2) rows u_i, u_j
            det = a[:, 0, 0] * a[:, 1, 1] - a[:, 0, 1] * a[:, 1, 0]
            ok = np.abs(det) > 1e-9
            inv = np.empty_like(a)
            safe = np.where(ok, det, 1.0)
            inv[:, 0, 0], inv[:, 1, 1] = a[:, 1, 1] / safe, a[:, 0, 0] / safe
            inv[:, 0, 1], inv[:, 1, 0] = -a[:, 0, 1] / safe, -a[:, 1, 0] / safe
            for si in (-1.0, 1.0):
                for sj in (-1.0, 1.0):
                    rhs = np.stack([si * rho[:, i], sj * rho[:, j]], axis=-1)
                    d = np.einsum("fab,fb->fa", inv, rhs)                 # (F, 2) offset [m]
                    slack = np.abs(np.einsum("fkc,fc->fk", u, d)) <= rho * (1 + 1e-9) + 1e-12
                    verts.append(d)
                    valid.append(ok & slack.all(axis=1))
    verts_arr = np.stack(verts, axis=1)                                   # (F, V, 2)
    valid_arr = np.stack(valid, axis=1)                                   # (F, V)
    rings = []
    for f in range(n_fix):
        d = verts_arr[f, valid_arr[f]]
        if len(d) < 3:
            rings.append(np.zeros((0, 2)))
            continue
        order = np.argsort(np.arctan2(d[:, 1], d[:, 0]))
        rings.append(closed_ring(d[order] + pos[f]))
    return rings


def level_contours(x: np.ndarray, y: np.ndarray, z: np.ndarray, level: float) -> list[np.ndarray]:
    """Iso-lines ``z = level`` of a grid, for the boundary of the navigation region ``{tau < eps_max}``.

    Uses contourpy, matplotlib's contour generator. Non-finite values (tau = inf where
    too few markers are visible) count as far above the level, so the region's boundary
    is traced around them.

    Parameters
    ----------
    x : (nx,) float
        Cell-centre x coordinates [m], increasing.
    y : (ny,) float
        Cell-centre y coordinates [m], increasing.
    z : (ny, nx) float
        Values on the grid (row = y index).
    level : float
        Iso-value.

    Returns
    -------
    list of (n_i, 2) float arrays
        Polylines [m]; closed ones repeat their first point.
    """
    import contourpy  # a matplotlib dependency; imported here to keep `import sim` light

    z = np.asarray(z, dtype=float)
    finite = np.isfinite(z)
    if not finite.any():
        return []
    big = max(float(np.max(z[finite])), level) * 10.0 + 1.0
    gen = contourpy.contour_generator(x=np.asarray(x, float), y=np.asarray(y, float),
                                      z=np.where(finite, z, big))
    return [np.asarray(line, dtype=float) for line in gen.lines(level) if len(line) >= 2]
