"""A linear Kalman filter on a planar pose, many runs at once: NEES and NIS with real time correlation.

The pose error of a robot driving a route at speed v: position errors gain ``v dt e_theta``
across the direction of travel each step, the heading is seen only through that coupling,
and a fix every ``fix_every`` steps brings two scalar range updates (unit vectors to two
markers on either side of the route). Errors then decorrelate slowly across fixes (heading)
and hardly at all within a fix interval, as in a warehouse run (~3000 steps, ~150 fixes).

The filter's covariances are exact (a consistent filter), so its per-step NEES is chi2(3)
and each fix's NIS sum is chi2(2), with innovations white. A filter that runs with Q, R and
P0 all multiplied by c has the same gain and estimates and covariance c P, so its NEES and
NIS are the consistent ones divided by c: :func:`simulate` returns those of c = 1 and the
tests scale them ("a covariance 5 % off": c = 0.95 or 1.05).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

DT = 0.05          # control step [s]
SPEED = 0.5        # [m/s]
POS_STD = 4e-4     # process noise per step on x, y [m]
HEADING_STD = 4e-4  # process noise per step on the heading [rad]
RANGE_STD = 2e-3   # range measurement noise [m]
P0_STD = (5e-3, 5e-3, 5e-3)  # initial pose std [m, m, rad]


@dataclass(frozen=True)
class Sweep:
    """NEES and NIS of N runs.

    Attributes
    ----------
    nees : (N, K) float
        Per step; NaN past a run's end.
    nis : (N, F) float
        Per fix, the sum of its two scalar updates' NIS (2 dof); NaN past a run's end.
    run_mean_nees : (N,) float
        Each run's time-averaged NEES.
    """

    nees: np.ndarray
    nis: np.ndarray
    run_mean_nees: np.ndarray


def _route(steps: int) -> np.ndarray:
    """Heading along a warehouse-like route [rad] (straights and turns), shape (K,)."""
    s = np.arange(steps) / steps
    return 0.5 * np.pi * np.floor(4 * s) + 0.3 * np.sin(2 * np.pi * 7 * s)


def simulate(runs: int, rng: np.random.Generator, steps: int = 3000, fix_every: int = 20,
             length_spread: float = 0.1) -> Sweep:
    """Simulate ``runs`` runs of the consistent filter.

    Parameters
    ----------
    runs : int
        N.
    rng : numpy.random.Generator
    steps : int
        K, control steps of the longest run.
    fix_every : int
        Steps between fixes.
    length_spread : float
        Runs end at a uniform fraction in ``[1 - length_spread, 1]`` of ``steps``.

    Returns
    -------
    Sweep
    """
    heading = _route(steps)
    q = np.diag([POS_STD**2, POS_STD**2, HEADING_STD**2])
    p = np.diag(np.square(P0_STD))
    e = rng.standard_normal((runs, 3)) @ np.linalg.cholesky(p).T
    lq = np.linalg.cholesky(q)
    nees = np.empty((runs, steps))
    nis = []
    for k in range(steps):
        if k:
            f = np.eye(3)
            f[0, 2], f[1, 2] = -SPEED * DT * np.sin(heading[k]), SPEED * DT * np.cos(heading[k])
            e = e @ f.T - rng.standard_normal((runs, 3)) @ lq.T
            p = f @ p @ f.T + q
        if k % fix_every == fix_every - 1:
            total = np.zeros(runs)
            for side in (1.1, -0.8):  # markers ahead-left and ahead-right of the route
                h = np.array([np.cos(heading[k] + side), np.sin(heading[k] + side), 0.0])
                s = h @ p @ h + RANGE_STD**2
                gain = p @ h / s
                innovation = -(e @ h) + RANGE_STD * rng.standard_normal(runs)
                total += innovation**2 / s
                e = e + np.outer(innovation, gain)
                p = p - np.outer(gain, gain) * s
            nis.append(total)
        nees[:, k] = np.einsum("ri,ij,rj->r", e, np.linalg.inv(p), e, optimize=False)
    nis = np.column_stack(nis)
    ends = np.ceil(steps * rng.uniform(1.0 - length_spread, 1.0, runs)).astype(int)
    nees[np.arange(steps) >= ends[:, None]] = np.nan
    fix_steps = np.arange(nis.shape[1]) * fix_every + fix_every - 1
    nis[fix_steps >= ends[:, None]] = np.nan
    return Sweep(nees=nees, nis=nis, run_mean_nees=np.nanmean(nees, axis=1))
