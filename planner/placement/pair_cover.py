"""The pair-cover problem of marker placement: point rows, their good pairs of sites, visibility.

Built by :func:`planner.placement.placement.build_cover`; solved by
:mod:`planner.placement.cover` (greedy, cutting planes + MILP), improved by
:mod:`planner.placement.search` and made robust by :mod:`planner.placement.redundant`, which all
read it (it lives on its own so that none of them imports another for it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class PairCover:
    """A pair-cover problem on unique point rows (R rows, P good pairs, E row-pair entries).

    A row is covered by a set of sites when the set holds both sites of one of its entries
    and at least k sites visible from the row.
    """

    weight: np.ndarray   # (R,) number of points with this row
    row_of: np.ndarray   # (N_coverable,) row of each coverable point
    row_ptr: np.ndarray  # (R + 1,) entries of row r: row_ptr[r]:row_ptr[r + 1]
    ep: np.ndarray       # (E,) pair of each entry
    ea: np.ndarray       # (E,) first site of each entry's pair
    eb: np.ndarray       # (E,) second site
    pj: np.ndarray       # (P,) first site of each pair
    pl: np.ndarray       # (P,) second site
    vis: np.ndarray      # (R, S) bool, sites visible from the row's points
    n_sites: int

    @property
    def er(self) -> np.ndarray:
        """Row of each entry, shape (E,)."""
        return np.repeat(np.arange(len(self.weight)), np.diff(self.row_ptr))


def subset_rows(cov: PairCover, keep: np.ndarray) -> PairCover:
    """Return the problem on the rows ``keep`` (R,) bool only (same sites and pairs).

    ``row_of`` maps a point of a dropped row to -1.
    """
    idx = np.flatnonzero(keep)
    lengths = np.diff(cov.row_ptr)[idx]
    starts = cov.row_ptr[idx]
    entries = (np.repeat(starts - np.concatenate([[0], np.cumsum(lengths)[:-1]]), lengths)
               + np.arange(int(lengths.sum())))
    new_row = np.full(len(cov.weight), -1)
    new_row[idx] = np.arange(len(idx))
    return PairCover(weight=cov.weight[idx], row_of=new_row[cov.row_of],
                     row_ptr=np.concatenate([[0], np.cumsum(lengths)]).astype(cov.row_ptr.dtype),
                     ep=cov.ep[entries], ea=cov.ea[entries], eb=cov.eb[entries], pj=cov.pj, pl=cov.pl,
                     vis=np.ascontiguousarray(cov.vis[idx]), n_sites=cov.n_sites)
