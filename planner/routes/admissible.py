"""One admissibility: whether a path keeps τ under the target everywhere along it.

``place`` (the points it covers), ``plan`` (its candidate routes), ``export`` (the segments of a
route graph) and ``watch`` judge a path by :func:`judge_paths`, so that "covered" means what
"plans" and "admissible" mean.

Continuity. A path is judged at samples no farther apart than ``spacing``
(:func:`planner.routes.criteria.sample_polyline`), and every point of it lies within
``spacing / 2`` of a sample (:func:`stretch_widen`). A marker counts at a sample only when it is
seen from every position within ``spacing / 2`` of the sample as well (the line-of-sight rule
of :mod:`planner.pef.sight` with its margin widened by ``spacing / 2``,
:meth:`planner.pef.map.PEF.at`): the subset a sample's τ is taken with stays in sight over the
whole stretch the sample stands for, so no gap between samples hides a lost line of sight (τ = ∞
between two finite samples). Between samples τ of that subset varies with the geometry (up to
3 % over 5 cm on random floors): the sample is compared with the target by the bound of τ over
its whole stretch (:meth:`planner.pef.map.PEF.stretch_bound`, derived in
:mod:`planner.pef.stretch`), so a path under the target at its samples is under it between them
too. ``place`` covers a point by the same bound (:mod:`planner.placement.placement`).

The verdict is the first failed condition (:data:`CONDITIONS` order): τ, then whatever other
condition joins (a clearance condition takes the same points).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from planner.routes.criteria import sample_polyline
from scenarios.schema import Scenario


def stretch_widen(spacing: float) -> float:
    """Return how far [m] a path's point may lie from the nearest of its samples ``spacing`` apart."""
    return 0.5 * float(spacing)


def tau_along(pef, points: np.ndarray, spacing: float, target: float) -> np.ndarray:
    """τ at samples of a path ``spacing`` apart, each standing for its stretch (module docstring) [m].

    Parameters
    ----------
    pef : planner.pef.map.PEF
        The PEF (its ``at`` and ``stretch_bound``).
    points : ndarray, shape (N, 2)
        Samples [m], consecutive ones at most ``spacing`` apart.
    spacing : float
        Largest distance between consecutive samples [m].
    target : float
        The τ the path must stay under [m].

    Returns
    -------
    ndarray, shape (N,)
        τ [m] at each sample whose whole stretch stays under ``target`` (the bound over the
        stretch is); elsewhere that bound (>= target): compared with ``target``, the value
        says whether the stretch does, and the scores of admissible paths stay the PEF's own.
        inf where fewer than k markers stay in sight over the sample's stretch.
    """
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    h = stretch_widen(spacing)
    tau = np.asarray(pef.at(p, widen=h).tau, dtype=float)
    bound = np.asarray(pef.stretch_bound(p, h, target), dtype=float)
    return np.where(bound < target, tau, bound)


@dataclass(frozen=True)
class PathVerdict:
    """Whether a path is admissible, and where it fails.

    Attributes
    ----------
    points : ndarray, shape (N, 2)
        The samples [m].
    s : ndarray, shape (N,)
        Their arc length [m].
    tau : ndarray, shape (N,)
        τ at each sample, over its stretch [m].
    why_not : str
        "" when admissible, else the first failed condition, naming the value and the place.
    """

    points: np.ndarray
    s: np.ndarray
    tau: np.ndarray
    why_not: str

    @property
    def admissible(self) -> bool:
        return not self.why_not

    @property
    def worst(self) -> int:
        """Index of the sample with the largest τ (NaN counts as inf)."""
        return int(np.argmax(np.where(np.isnan(self.tau), np.inf, self.tau)))


def tau_condition(scenario: Scenario, target: float, points: np.ndarray, tau: np.ndarray) -> str:
    """Return the τ condition: "" when every sample's τ is under ``target`` [m], else where it is not."""
    bad = ~(tau < target)
    if not bad.any():
        return ""
    i = int(np.argmax(np.where(np.isnan(tau), np.inf, tau)))
    x, y = points[i]
    return f"tau {tau[i] * 1e3:.4g} mm >= eps_max {target * 1e3:g} mm at ({x:.2f}, {y:.2f})"


CONDITIONS = (tau_condition,)
"""The conditions a path must meet, in the order they are reported: ``f(scenario, target, points,
tau) -> reason or ""``."""


def judge_paths(scenario: Scenario, pef, polylines: Sequence[np.ndarray], spacing: float | None = None,
                target: float | None = None) -> list[PathVerdict]:
    """Judge paths by the one admissibility (module docstring).

    Parameters
    ----------
    scenario : Scenario
    pef : planner.pef.map.PEF
        The PEF (its ``at`` with ``widen``).
    polylines : sequence of ndarray, shape (n_i, 2)
        The paths' vertices [m].
    spacing : float, optional
        Largest distance between samples [m]; default ``planning.resolution``.
    target : float, optional
        τ must stay under it [m]; default ``planning.eps_max``.

    Returns
    -------
    list of PathVerdict
        One per path, in order.
    """
    spacing = scenario.planning.resolution if spacing is None else float(spacing)
    target = scenario.planning.eps_max if target is None else float(target)
    samples = [sample_polyline(np.asarray(p, dtype=float).reshape(-1, 2), spacing) for p in polylines]
    if not samples:
        return []
    # one PEF evaluation for every path: the kernels work best on many points
    tau_all = tau_along(pef, np.vstack([p for p, _ in samples]), spacing, target)
    out, start = [], 0
    for p, s in samples:
        tau = tau_all[start:start + len(p)]
        start += len(p)
        why = ""
        for cond in CONDITIONS:
            why = cond(scenario, target, p, tau)
            if why:
                break
        out.append(PathVerdict(points=p, s=s, tau=tau, why_not=why))
    return out
