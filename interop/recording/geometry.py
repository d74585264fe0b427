"""Pure-numpy geometry for recordings: ellipses, strip polygons, contours, rings.

Kept apart from :mod:`interop.recording` so that it can be tested without rerun and so the
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


#: Rows and columns of a tile of :func:`level_contours` with a cache.
CONTOUR_TILE = 256


def level_contours(x: np.ndarray, y: np.ndarray, z: np.ndarray, level: float,
                   cache: dict | None = None) -> list[np.ndarray]:
    """Iso-lines ``z = level`` of a grid, for the boundary of the navigation region ``{tau < eps_max}``.

    Uses contourpy, matplotlib's contour generator. Non-finite values (tau = inf where
    too few markers are visible) count as far above the level (``10 level + 1``), so the
    region's boundary is traced around them.

    Parameters
    ----------
    x : (nx,) float
        Cell-centre x coordinates [m], increasing and uniformly spaced.
    y : (ny,) float
        Cell-centre y coordinates [m], increasing and uniformly spaced.
    z : (ny, nx) float
        Values on the grid (row = y index).
    level : float
        Iso-value.
    cache : dict, optional
        Given (empty at first, then passed again with each new ``z`` of the same grid): the grid
        is traced in tiles of :data:`CONTOUR_TILE` cells that share their border rows, and a tile
        whose values, level and coordinates equal the last call's reuses its lines (a live view
        where one edit changes a window of the map). The lines then break at tile borders.

    Returns
    -------
    list of (n_i, 2) float arrays
        Polylines [m]; closed ones repeat their first point (without a cache).
    """
    x, y = np.asarray(x, float), np.asarray(y, float)
    z = np.asarray(z, dtype=float)
    ny, nx = z.shape
    if cache is None:
        return _contours(x, y, z, level)
    out = []
    for r0 in range(0, max(ny - 1, 1), CONTOUR_TILE):
        for c0 in range(0, max(nx - 1, 1), CONTOUR_TILE):
            rows, cols = slice(r0, min(r0 + CONTOUR_TILE + 1, ny)), slice(c0, min(c0 + CONTOUR_TILE + 1, nx))
            key = (r0, c0)
            tile, tx, ty = z[rows, cols], x[cols], y[rows]
            hit = cache.get(key)
            if (hit is None or hit[0] != level or not np.array_equal(hit[1], tx) or not np.array_equal(hit[2], ty)
                    or not np.array_equal(hit[3], tile)):
                hit = cache[key] = (level, tx.copy(), ty.copy(), tile.copy(), _contours(tx, ty, tile, level))
            out.extend(hit[4])
    return out


def _contours(x: np.ndarray, y: np.ndarray, z: np.ndarray, level: float) -> list[np.ndarray]:
    """:func:`level_contours` of one grid in one piece."""
    import contourpy  # a matplotlib dependency; imported here to keep `import sim` light

    if min(z.shape) < 2 or not np.isfinite(z).any():
        return []
    # on cell indices, then scaled to metres (x, y uniform): contourpy given x and y would
    # build their (ny, nx) mesh, most of its time on a big map
    dx = (x[-1] - x[0]) / (x.size - 1)
    dy = (y[-1] - y[0]) / (y.size - 1)
    gen = contourpy.contour_generator(z=np.where(np.isfinite(z), z, 10.0 * level + 1.0))
    origin, step = np.array([x[0], y[0]]), np.array([dx, dy])
    return [origin + step * np.asarray(line, dtype=float) for line in gen.lines(level) if len(line) >= 2]
