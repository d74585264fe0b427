"""Exact PEF values of marker subsets at numbered points, held between calls and never dropped within one.

Under the ``exact`` model a value is a polygon clipping of a millisecond or so; the measurement
schedule asks for the same (point, subset) pairs again (each rung of its ladder, each slow-down
attempt: a slowed stretch moves only the samples after it). A value depends on its point and
subset alone, so a value held is the value computed before and the answers are the same as
without the store.

The store is bounded: when a call begins with more than :data:`MAX_VALUES` values held, only
those the previous call used are kept. A call is never cut short: an attempt of a long slowed
drive asks for more pairs than the bound (seed 23's world 20: 330 subsets of 4 markers at 7 762
points, ~2.4 million pairs), and dropping them while it runs made every later attempt clip them
all again.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

MAX_VALUES = 4_000_000
"""Values held between calls beyond those of the last call (16 bytes each: the point's number and the value)."""


class SubsetValues:
    """Values of subsets (by a hashable tag) at points (by their number in a :class:`~planner.pef.pointmemo.PointMemo`).

    Each subset's values are two arrays sorted by point number: a lookup is a binary search.
    """

    def __init__(self, limit: int | None = None) -> None:
        self.limit = MAX_VALUES if limit is None else limit
        self._held: dict[object, list[np.ndarray]] = {}  # tag -> [numbers (sorted), values, used this call]
        self._size = 0

    @property
    def size(self) -> int:
        """Values held."""
        return self._size

    def begin(self) -> None:
        """Start a call: past the bound, keep only the values the previous call used."""
        if self._size > self.limit:
            kept = {}
            for tag, (ids, vals, used) in self._held.items():
                if used.any():
                    kept[tag] = [ids[used], vals[used], used[used]]
            self._held = kept
            self._size = sum(len(e[0]) for e in kept.values())
        for e in self._held.values():
            e[2] = np.zeros(len(e[0]), dtype=bool)

    def values(self, tag: object, ids: np.ndarray, compute: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        """Return the values of subset ``tag`` at the points numbered ``ids`` (n,), shape (n,).

        ``compute(first)`` returns the values at ``ids[first]`` (``first``: the first position of
        each number not held), computed once per number.
        """
        ids = np.asarray(ids, dtype=np.int64)
        entry = self._held.get(tag)
        if entry is None:
            entry = self._held[tag] = [np.empty(0, np.int64), np.empty(0, float), np.empty(0, bool)]
        pos = self._find(entry[0], ids)
        miss = np.flatnonzero(pos < 0)
        if miss.size:
            new, at = np.unique(ids[miss], return_index=True)
            got = np.asarray(compute(miss[at]), dtype=float).reshape(-1)
            merged = np.concatenate([entry[0], new])
            order = np.argsort(merged, kind="stable")
            entry[0] = merged[order]
            entry[1] = np.concatenate([entry[1], got])[order]
            entry[2] = np.concatenate([entry[2], np.zeros(len(new), dtype=bool)])[order]
            self._size += len(new)
            pos = self._find(entry[0], ids)
        entry[2][pos] = True
        return entry[1][pos]

    @staticmethod
    def _find(held: np.ndarray, ids: np.ndarray) -> np.ndarray:
        """Position of each of ``ids`` in the sorted ``held``, -1 where absent."""
        if held.size == 0:
            return np.full(len(ids), -1, dtype=np.int64)
        pos = np.minimum(np.searchsorted(held, ids), held.size - 1)
        return np.where(held[pos] == ids, pos, -1)
