"""The linearised fault area of a range (and bearing) fix: strips, parallelogram, GDOP.

Linearised at the robot position R, the measurement of marker ``M_i`` constrains the position
error ``delta`` to the strip ``|u_i . delta| <= rho_i`` with the unit vector
``u_i = (R - M_i) / r_i`` (a row of the measurement Jacobian ``H``) and the range bound
``rho_i``. This module holds the geometry of those strips:

- two strips form a parallelogram, area ``A = 4 rho1 rho2 / sin a`` (paper eq. 10) and long
  diagonal ``d = (2 / sin a) sqrt(rho1^2 + rho2^2 + 2 rho1 rho2 |cos a|)`` (paper eq. 12), with
  ``sin a = |u1 x u2|``;
- k strips form a centrally symmetric convex polygon; its diameter is ``2 * max |vertex|``;
- with bearings (bound ``xi``) each marker adds a *tangential* strip
  ``|t_i . delta| <= r_i tan(xi)``, ``t_i`` = ``u_i`` turned by +90 deg. The bearing is taken as
  an *absolute* direction: the robot's heading is assumed known (from the filter), so a bearing
  error moves the position only across the line of sight;
- the least-squares view: ``P = (H^T W H)^-1`` with ``W = diag(sigma_i^-2)`` and
  ``sigma_i = rho_i / 3`` (the gaussian noise model), ``GDOP = sqrt(trace((H^T H)^-1))``; the
  ``gdop`` PEF ``tau = 2 sqrt(chi2.ppf(p, 2) * lambda_max(P))`` is the major axis (the diameter)
  of the p-level confidence ellipse, the same quantity as the other models' diameter of the
  region (the paper's d, eq. 12), so one eps_max means the same under every model. For 2
  degrees of freedom ``chi2.ppf(p, 2) = -2 ln(1 - p)`` exactly.

The region is expressed in *scaled normals* ``g = n / b`` (strip ``|g . delta| <= 1``), which
gives every formula without trigonometry: for two strips the vertex ``G^-1 (1, s)`` has squared
norm ``|g2 - s g1|^2 / det(G)^2``, so ``d^2 = 4 (|g1|^2 + |g2|^2 + 2 |g1 . g2|) / det(G)^2``.

The ``_k`` functions are numba-jitted scalar kernels that the planner's PEF inlines into its
grid loops; the public functions are numpy wrappers over them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from jit import compiled

#: A vertex is inside a strip if ``|g . delta| <= 1 + FEASIBLE_TOL`` (relative to the half-width).
FEASIBLE_TOL = 1e-9


def chi2_2dof_ppf(p: float) -> float:
    """Quantile of the chi-square distribution with 2 degrees of freedom, ``-2 ln(1 - p)``.

    Parameters
    ----------
    p : float
        Probability in [0, 1).

    Returns
    -------
    float
        ``c`` with ``P(chi2_2 <= c) = p``.
    """
    return -2.0 * math.log1p(-p)


# --- scalar kernels (numba) ------------------------------------------------------------------

@compiled.njit(cache=True)
def parallelogram_diag_sq_k(g1x, g1y, g2x, g2y):
    """Squared long diagonal of ``{|g1.d| <= 1, |g2.d| <= 1}`` [m^2]; inf when parallel."""
    det = g1x * g2y - g1y * g2x
    num = g1x * g1x + g1y * g1y + g2x * g2x + g2y * g2y + 2.0 * abs(g1x * g2x + g1y * g2y)
    den = det * det
    if den == 0.0:
        return np.inf
    return 4.0 * num / den


@compiled.njit(cache=True)
def parallelogram_area_k(u1x, u1y, u2x, u2y, rho1, rho2):
    """Area ``4 rho1 rho2 / sin a`` of two strips with unit normals u1, u2 [m^2]."""
    s = abs(u1x * u2y - u1y * u2x)
    if s == 0.0:
        return np.inf
    return 4.0 * rho1 * rho2 / s


@compiled.njit(cache=True)
def parallelogram_diagonal_k(u1x, u1y, u2x, u2y, rho1, rho2):
    """Long diagonal ``(2/sin a) sqrt(rho1^2 + rho2^2 + 2 rho1 rho2 |cos a|)`` [m]."""
    s = abs(u1x * u2y - u1y * u2x)
    if s == 0.0:
        return np.inf
    c = abs(u1x * u2x + u1y * u2y)
    return 2.0 / s * math.sqrt(rho1 * rho1 + rho2 * rho2 + 2.0 * rho1 * rho2 * c)


@compiled.njit(cache=True)
def strip_max_vertex_sq_k(gx, gy, n):
    """Largest squared vertex norm of ``{d : |g_l . d| <= 1, l < n}`` [m^2].

    Every vertex is the crossing of two strip boundaries, ``G^-1 (1, s)`` for ``s = +-1`` (the
    polygon is centrally symmetric, so the other two signs give the mirrored vertices). A
    crossing is a vertex when it satisfies every strip. Cost O(n^3); inf when the normals do not
    span the plane (unbounded region).
    """
    best = -1.0
    for i in range(n):
        for j in range(i + 1, n):
            det = gx[i] * gy[j] - gy[i] * gx[j]
            if det == 0.0:
                continue
            for s in (1.0, -1.0):
                dx = (gy[j] - s * gy[i]) / det
                dy = (s * gx[i] - gx[j]) / det
                nsq = dx * dx + dy * dy
                if nsq <= best:
                    continue
                ok = True
                for m in range(n):
                    if abs(gx[m] * dx + gy[m] * dy) > 1.0 + FEASIBLE_TOL:
                        ok = False
                        break
                if ok:
                    best = nsq
    if best < 0.0:
        return np.inf
    return best


@compiled.njit(cache=True)
def info_lambda_max_inv_k(sxx, sxy, syy):
    """Largest eigenvalue of the inverse of the 2x2 information ``[[sxx, sxy], [sxy, syy]]``.

    ``(T + sqrt(T^2 - 4 D)) / (2 D)`` with trace T and determinant D; inf when singular.
    """
    t = sxx + syy
    d = sxx * syy - sxy * sxy
    if d <= 0.0:
        return np.inf
    disc = t * t - 4.0 * d
    if disc < 0.0:  # rounding for a near-isotropic matrix
        disc = 0.0
    return (t + math.sqrt(disc)) / (2.0 * d)


@compiled.njit(cache=True)
def _strip_max_vertex_sq_rows(gx, gy):
    return strip_max_vertex_sq_k(gx, gy, gx.size)


@compiled.njit(cache=True)
def _strip_max_vertex_sq_many(gx, gy, out):
    for f in range(gx.shape[0]):
        out[f] = strip_max_vertex_sq_k(gx[f], gy[f], gx.shape[1])


@compiled.njit(cache=True)
def _parallelogram_rows(u1, u2, rho1, rho2, area, diag):
    for i in range(rho1.size):
        area[i] = parallelogram_area_k(u1[i, 0], u1[i, 1], u2[i, 0], u2[i, 1], rho1[i], rho2[i])
        diag[i] = parallelogram_diagonal_k(u1[i, 0], u1[i, 1], u2[i, 0], u2[i, 1], rho1[i], rho2[i])


# --- numpy wrappers ---------------------------------------------------------------------------

def _as_unit_rows(u: np.ndarray, name: str) -> np.ndarray:
    u = np.asarray(u, dtype=float)
    if u.shape[-1] != 2:
        raise ValueError(f"{name}: expected shape (..., 2), got {u.shape}")
    return u


def parallelogram(u1: np.ndarray, u2: np.ndarray, rho1: np.ndarray,
                  rho2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Area and long diagonal of the two-strip parallelogram (paper eqs. 10 and 12).

    Parameters
    ----------
    u1, u2 : ndarray, shape (..., 2)
        Unit vectors from the markers to the robot (rows of H).
    rho1, rho2 : ndarray, shape (...)
        Range error bounds [m] (strip half-widths).

    Returns
    -------
    area : ndarray, shape (...)
        ``4 rho1 rho2 / sin a`` [m^2]; inf for parallel u1, u2.
    diagonal : ndarray, shape (...)
        ``(2 / sin a) sqrt(rho1^2 + rho2^2 + 2 rho1 rho2 |cos a|)`` [m]; inf when parallel.
    """
    u1, u2 = _as_unit_rows(u1, "u1"), _as_unit_rows(u2, "u2")
    shape = np.broadcast_shapes(u1.shape[:-1], u2.shape[:-1], np.shape(rho1), np.shape(rho2))
    a = np.ascontiguousarray(np.broadcast_to(u1, shape + (2,)).reshape(-1, 2))
    b = np.ascontiguousarray(np.broadcast_to(u2, shape + (2,)).reshape(-1, 2))
    r1 = np.ascontiguousarray(np.broadcast_to(np.asarray(rho1, float), shape).ravel())
    r2 = np.ascontiguousarray(np.broadcast_to(np.asarray(rho2, float), shape).ravel())
    area, diag = np.empty(r1.size), np.empty(r1.size)
    _parallelogram_rows(a, b, r1, r2, area, diag)
    return area.reshape(shape), diag.reshape(shape)


def unit_rows(markers: np.ndarray, position: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows of H and ranges for a robot at ``position``.

    Parameters
    ----------
    markers : ndarray, shape (k, 2)
        Marker positions [m].
    position : ndarray, shape (2,)
        Linearisation point (robot position) [m].

    Returns
    -------
    u : ndarray, shape (k, 2)
        Unit vectors ``(R - M_i) / r_i``.
    r : ndarray, shape (k,)
        Ranges ``|R - M_i|`` [m].
    """
    diff = np.asarray(position, float)[None, :] - np.asarray(markers, float).reshape(-1, 2)
    r = np.hypot(diff[:, 0], diff[:, 1])
    if np.any(r == 0.0):
        raise ValueError("position coincides with a marker: the range direction is undefined")
    return diff / r[:, None], r


def fix_strips(u: np.ndarray, rho: np.ndarray, r: np.ndarray | None = None,
               bearing_error: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Return the strips of a linearised fix: range strips, plus tangential bearing strips.

    Parameters
    ----------
    u : ndarray, shape (k, 2)
        Unit vectors from the markers to the robot.
    rho : ndarray, shape (k,)
        Range error bounds [m].
    r : ndarray, shape (k,), optional
        Ranges [m]; needed when ``bearing_error > 0``.
    bearing_error : float
        Bound xi of the (absolute) bearing error [rad]; 0 = ranges only.

    Returns
    -------
    normals : ndarray, shape (s, 2)
        Unit strip normals, s = k (ranges only) or 2k (with bearings; range strips first).
    half_widths : ndarray, shape (s,)
        ``rho_i`` and then ``r_i tan(xi)`` [m].
    """
    u = np.asarray(u, float).reshape(-1, 2)
    rho = np.asarray(rho, float).reshape(-1)
    if bearing_error <= 0.0:
        return u, rho
    if r is None:
        raise ValueError("fix_strips: ranges r are needed when bearing_error > 0")
    t = np.stack([-u[:, 1], u[:, 0]], axis=1)
    return np.concatenate([u, t]), np.concatenate([rho, np.asarray(r, float) * math.tan(bearing_error)])


@dataclass(frozen=True)
class StripPolygon:
    """The intersection of strips ``|n_l . delta| <= b_l`` around the linearisation point.

    Attributes
    ----------
    vertices : ndarray, shape (n, 2)
        Offsets delta of the vertices from the linearisation point, counter-clockwise [m].
    area : float
        Area [m^2]; inf when unbounded.
    diameter : float
        ``2 * max |vertex|`` (the polygon is centrally symmetric) [m]; inf when unbounded.
    """

    vertices: np.ndarray
    area: float
    diameter: float


def strip_polygon(normals: np.ndarray, half_widths: np.ndarray) -> StripPolygon:
    """Vertices, area and diameter of the intersection of centred strips.

    Parameters
    ----------
    normals : ndarray, shape (s, 2)
        Strip normals (unit vectors; any non-zero length works, the strip is ``|n.d| <= b``).
    half_widths : ndarray, shape (s,)
        Half-widths b_l > 0 [m].

    Returns
    -------
    StripPolygon
        Unbounded (all normals parallel) gives no vertices and inf area and diameter.
    """
    n = np.asarray(normals, float).reshape(-1, 2)
    b = np.asarray(half_widths, float).reshape(-1)
    if n.shape[0] != b.shape[0]:
        raise ValueError(f"strip_polygon: {n.shape[0]} normals but {b.shape[0]} half-widths")
    g = n / b[:, None]
    gx, gy = np.ascontiguousarray(g[:, 0]), np.ascontiguousarray(g[:, 1])
    diameter = 2.0 * math.sqrt(_strip_max_vertex_sq_rows(gx, gy))
    if not math.isfinite(diameter):
        return StripPolygon(np.zeros((0, 2)), math.inf, math.inf)
    # All boundary crossings that satisfy every strip, both signs, then ordered by angle.
    i, j = np.triu_indices(len(b), 1)
    det = gx[i] * gy[j] - gy[i] * gx[j]
    keep = det != 0.0
    i, j, det = i[keep], j[keep], det[keep]
    cand = []
    for s in (1.0, -1.0):
        v = np.stack([(gy[j] - s * gy[i]) / det, (s * gx[i] - gx[j]) / det], axis=1)
        cand.extend([v, -v])
    v = np.concatenate(cand)
    v = v[np.all(np.abs(v @ g.T) <= 1.0 + FEASIBLE_TOL, axis=1)]
    ang = np.arctan2(v[:, 1], v[:, 0])
    v = v[np.argsort(ang)]
    # Crossings of three or more lines at one vertex appear several times.
    scale = max(diameter, 1e-300)
    dup = np.r_[False, np.hypot(*np.diff(v, axis=0).T) <= 1e-9 * scale]
    v = v[~dup]
    if len(v) > 1 and np.hypot(*(v[0] - v[-1])) <= 1e-9 * scale:
        v = v[:-1]
    x, y = v[:, 0], v[:, 1]
    area = 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
    return StripPolygon(v, area, diameter)


def strip_diameters(normals: np.ndarray, half_widths: np.ndarray) -> np.ndarray:
    """Diameters of many strip polygons: :func:`strip_polygon`'s ``diameter``, without the vertices.

    The planner's promise bounds hundreds of fixes per schedule, each needing only the diameter;
    the vertices, their ordering and the area cost ten times as much.

    Parameters
    ----------
    normals : ndarray, shape (F, s, 2)
        Strip normals of each polygon (any non-zero length).
    half_widths : ndarray, shape (F, s)
        Half-widths b > 0 [m].

    Returns
    -------
    ndarray, shape (F,)
        ``2 * max |vertex|`` [m]; inf where the normals of a polygon do not span the plane.
    """
    n = np.asarray(normals, float)
    b = np.asarray(half_widths, float)
    if n.ndim != 3 or n.shape[2] != 2 or b.shape != n.shape[:2]:
        raise ValueError(f"strip_diameters: expected normals (F, s, 2) and half-widths (F, s), got "
                         f"{n.shape} and {b.shape}")
    g = n / b[..., None]
    best = np.empty(n.shape[0])
    if n.shape[0]:
        _strip_max_vertex_sq_many(np.ascontiguousarray(g[..., 0]), np.ascontiguousarray(g[..., 1]), best)
    return 2.0 * np.sqrt(best)


def lsq_covariance(u: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Least-squares position covariance ``P = (H^T W H)^-1``, ``W = diag(sigma^-2)``.

    Parameters
    ----------
    u : ndarray, shape (s, 2)
        Rows of H (unit measurement directions).
    sigma : ndarray, shape (s,)
        Standard deviations of the measurements along those rows [m].

    Returns
    -------
    ndarray, shape (2, 2)
        P_cov [m^2]; inf entries when H^T W H is singular.
    """
    u = np.asarray(u, float).reshape(-1, 2)
    w = 1.0 / np.asarray(sigma, float).reshape(-1) ** 2
    info = (u * w[:, None]).T @ u
    if np.linalg.det(info) <= 0.0:
        return np.full((2, 2), np.inf)
    return np.linalg.inv(info)


def gdop(u: np.ndarray) -> float:
    """Geometric dilution of precision ``sqrt(trace((H^T H)^-1))`` (paper eq. 13).

    Parameters
    ----------
    u : ndarray, shape (s, 2)
        Rows of H.

    Returns
    -------
    float
        GDOP [-]; inf when H^T H is singular.
    """
    p = lsq_covariance(u, np.ones(np.asarray(u).reshape(-1, 2).shape[0]))
    return float(np.sqrt(np.trace(p)))


def gaussian_sigma(half_widths: np.ndarray) -> np.ndarray:
    """Return the standard deviations of the gaussian noise model, ``sigma = rho / 3`` [m]."""
    return np.asarray(half_widths, float) / 3.0


def gdop_diameter(u: np.ndarray, half_widths: np.ndarray, level: float) -> float:
    """Return the gdop model's error ``tau = 2 sqrt(chi2.ppf(level, 2) * lambda_max(P))`` [m].

    Parameters
    ----------
    u : ndarray, shape (s, 2)
        Rows of H (strip normals, see :func:`fix_strips`).
    half_widths : ndarray, shape (s,)
        Error bounds rho [m]; the model's sigma is rho / 3.
    level : float
        Probability p of the confidence ellipse, in (0, 1).

    Returns
    -------
    float
        Major axis (twice the semi-major axis) of the p-level ellipse of the least-squares fix
        [m]: the diameter of the region the error lies in with probability p; inf if singular.
    """
    p_cov = lsq_covariance(u, gaussian_sigma(half_widths))
    if not np.all(np.isfinite(p_cov)):
        return math.inf
    return 2.0 * math.sqrt(chi2_2dof_ppf(level) * float(np.linalg.eigvalsh(p_cov)[-1]))
