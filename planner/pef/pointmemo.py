"""Rows of per-point results already computed, found again by the point's exact bits.

A PEF value at a point depends on that point alone (and on the scenario the PEF was made for),
so a point asked again, in a later call, need not be computed again: the measurement schedule
samples the same path over and over (each rung of its ladder, each slow-down attempt, which
moves only the samples after the stretch it slowed), and under the ``exact`` model every value
is a polygon clipping of milliseconds. A point is the same point only when its coordinates are
the same bit for bit (``-0.0`` and ``0.0`` are two points here), so a row found again is the row
computed before, and the answers are the same as without the memo.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

MAX_POINTS = 2_000_000
"""Most points a memo holds; beyond, it starts afresh (the hall's route samples: ~50 000)."""


def point_keys(pts: np.ndarray) -> list[bytes]:
    """Return the exact bits of each point of ``pts`` (N, 2) float64, contiguous, as N keys."""
    return np.ascontiguousarray(pts, dtype=float).view(np.dtype((np.void, 16))).ravel().tolist()


class PointMemo:
    """Per-point rows of some arrays, each with the point axis first.

    Attributes
    ----------
    size : int
        Points held; a point's row is its index in the order added.
    epoch : int
        Times the memo started afresh (past :data:`MAX_POINTS`): rows numbered in an earlier
        epoch name other points now.
    """

    def __init__(self) -> None:
        self._index: dict[bytes, int] = {}
        self._rows: list[np.ndarray] | None = None
        self.size = 0
        self.epoch = 0

    def find(self, keys: list[bytes]) -> np.ndarray:
        """Return the row of each key, -1 where not held, shape (N,) int64."""
        get = self._index.get
        return np.fromiter((get(k, -1) for k in keys), dtype=np.int64, count=len(keys))

    def held(self, keys: list[bytes], compute: Callable[[np.ndarray], list[np.ndarray]] | None = None) -> np.ndarray:
        """Return the row of each key, shape (N,) int64, the points not held yet computed and added first.

        ``compute(first)`` returns the arrays' rows of the points ``first`` (indices into
        ``keys``: the first occurrence of each key not held); None: the memo holds no arrays.
        """
        idx = self.find(keys)
        miss = np.flatnonzero(idx < 0)
        if miss.size == 0:
            return idx
        if self.size + miss.size > MAX_POINTS:
            self._index, self._rows, self.size = {}, None, 0
            self.epoch += 1
            miss = np.arange(len(keys))
        fresh: dict[bytes, int] = {}
        for i in miss.tolist():
            fresh.setdefault(keys[i], i)
        first = np.fromiter(fresh.values(), dtype=np.int64, count=len(fresh))
        self._add(list(fresh), [] if compute is None else compute(first))
        return self.find(keys)

    def _add(self, keys: list[bytes], rows: list[np.ndarray]) -> None:
        base, n = self.size, len(keys)
        self._index.update(zip(keys, range(base, base + n), strict=True))
        if self._rows is None:
            self._rows = [np.empty((max(n, 1024), *np.shape(r)[1:]), dtype=np.asarray(r).dtype) for r in rows]
        elif self._rows and base + n > len(self._rows[0]):  # doubling: a row is copied O(1) times on average
            cap = max(2 * len(self._rows[0]), base + n)
            grown = []
            for a in self._rows:
                b = np.empty((cap, *a.shape[1:]), dtype=a.dtype)
                b[:base] = a[:base]
                grown.append(b)
            self._rows = grown
        for a, r in zip(self._rows, rows, strict=True):
            a[base:base + n] = r
        self.size = base + n

    def rows(self, idx: np.ndarray) -> list[np.ndarray]:
        """Return the held rows ``idx`` (N,) (all >= 0) of each array, copies."""
        return [a[idx] for a in self._rows]
