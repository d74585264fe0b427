"""Route choice among scored candidates (paper fig. 7-8): normalising, ranking, the Pareto front.

Weighted choice min-max normalises each criterion (:data:`planner.routes.criteria.CRITERIA`) over the
admissible candidates (a criterion equal on all of them contributes 0) and minimises
``Σ weight · normalised``; lexicographic choice compares criteria in the scenario's order.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from planner.routes.criteria import CRITERIA, tie_round
from scenarios.schema import Weights


def normalise(values: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """Min-max normalise each column over the rows in ``mask`` (all rows if None).

    Parameters
    ----------
    values : ndarray, shape (n, c)
    mask : ndarray of bool, shape (n,), optional

    Returns
    -------
    ndarray, shape (n, c)
        0 at the best masked row, 1 at the worst; a column constant over the masked rows is
        0; unmasked rows are NaN.
    """
    v = np.asarray(values, float)
    m = np.ones(len(v), bool) if mask is None else np.asarray(mask, bool)
    out = np.full_like(v, np.nan)
    if not m.any():
        return out
    lo, hi = v[m].min(axis=0), v[m].max(axis=0)
    span = hi - lo
    scale = np.where(span > 0, span, 1.0)
    out[m] = np.where(span > 0, (v[m] - lo) / scale, 0.0)
    return out


def weight_vector(weights: Weights) -> np.ndarray:
    """Return the weights in :data:`CRITERIA` order, shape (5,)."""
    return np.array([getattr(weights, c) for c in CRITERIA], dtype=float)


def weighted_scores(values: np.ndarray, weights: Weights, mask: np.ndarray | None = None) -> np.ndarray:
    """``Σ weight · normalised criterion`` per row; NaN for rows outside ``mask``.

    Parameters
    ----------
    values : ndarray, shape (n, 5)
        Criteria in :data:`CRITERIA` order.
    weights : Weights
    mask : ndarray of bool, shape (n,), optional
        The admissible rows.
    """
    return normalise(values, mask) @ weight_vector(weights)


def lexicographic_key(row: np.ndarray, order: Sequence[str]) -> tuple[float, ...]:
    """Sort key of one criteria row for the lexicographic ``order`` (names from :data:`CRITERIA`)."""
    return tuple(float(row[CRITERIA.index(c)]) for c in order)


def pareto_front(values: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """Rows not dominated by another masked row (no other is ≤ everywhere and < somewhere).

    Parameters
    ----------
    values : ndarray, shape (n, c)
    mask : ndarray of bool, shape (n,), optional
        Only these rows compete and can be on the front.

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    v = np.asarray(values, float)
    m = np.ones(len(v), bool) if mask is None else np.asarray(mask, bool)
    le = np.all(v[None, :, :] <= v[:, None, :], axis=2)  # le[i, j]: row j <= row i everywhere
    lt = np.any(v[None, :, :] < v[:, None, :], axis=2)
    dominated = np.any(le & lt & m[None, :], axis=1)
    return m & ~dominated


@dataclass(frozen=True)
class Ranking:
    """Result of a route choice.

    Attributes
    ----------
    order : tuple[int, ...]
        Admissible row indices, best first.
    scores : ndarray, shape (n,)
        Weighted scores (NaN for inadmissible rows); also the tie-break under lexicographic order.
    pareto : ndarray of bool, shape (n,)
    lexicographic : tuple[str, ...]
        The criteria order used, empty for the weighted choice.
    """

    order: tuple[int, ...]
    scores: np.ndarray
    pareto: np.ndarray
    lexicographic: tuple[str, ...]


def rank(values: np.ndarray, admissible: np.ndarray, weights: Weights,
         order: Sequence[str] = ()) -> Ranking:
    """Rank the admissible routes by weighted score, or lexicographically if ``order`` is set.

    Values are first rounded to :data:`TIE_DIGITS` significant digits (:func:`tie_round`);
    normalisation, lexicographic order and the Pareto front all use the rounded values.

    Parameters
    ----------
    values : ndarray, shape (n, 5)
        Criteria in :data:`CRITERIA` order, lower is better.
    admissible : ndarray of bool, shape (n,)
    weights : Weights
    order : sequence of str
        Criteria names for lexicographic choice; ties fall back to the weighted score, then
        to the row index.

    Returns
    -------
    Ranking
    """
    values = tie_round(np.asarray(values, float).reshape(-1, len(CRITERIA)))
    admissible = np.asarray(admissible, bool)
    for c in order:
        if c not in CRITERIA:
            raise ValueError(f"unknown criterion {c!r}; expected one of {CRITERIA}")
    scores = tie_round(weighted_scores(values, weights, admissible))
    rows = np.flatnonzero(admissible)
    if order:
        key = lambda i: (*lexicographic_key(values[i], order), scores[i], i)
    else:
        key = lambda i: (scores[i], i)
    ranked = tuple(int(i) for i in sorted(rows, key=key))
    return Ranking(order=ranked, scores=scores, pareto=pareto_front(values, admissible),
                   lexicographic=tuple(order))
