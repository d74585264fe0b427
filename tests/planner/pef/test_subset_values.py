"""The store of exact subset values (:mod:`planner.pef.subsetvalues`): held across calls, bounded, never cut within one.

A slow-down search asks a PEF for the same (point, subset) pairs call after call; one call of
a long slowed drive may ask for more pairs than the store's bound. The store must then keep
them all until the next call (which asks for them again) and drop older ones only between
calls. Counts are exact (each value is computed once or not at all), so no tolerance.

Negative control: a store that starts afresh as soon as it passes its bound inside a call (what
the PEF did before) computes the second call's values again, and the count check must fail.
"""

from __future__ import annotations

import numpy as np

import scenarios
from planner.pef import subsetvalues
from planner.pef.map import PEF
from planner.pef.subsetvalues import SubsetValues


class Counted:
    """A value function of (tag, point number) that counts the values it computes."""

    def __init__(self):
        self.n = 0

    def __call__(self, tag, ids):
        def compute(first):
            self.n += len(first)
            return ids[first] * 10.0 + tag
        return compute


def two_calls(store: SubsetValues, tags=(1, 2, 3), n=40) -> tuple[int, int, list[np.ndarray]]:
    """Make the same call twice (each tag at points 0..n-1, some twice); return both counts and the second's values."""
    ids = np.concatenate([np.arange(n), np.arange(0, n, 3)])
    counts, out = [], []
    for _ in range(2):
        f = Counted()
        store.begin()
        out = [store.values(t, ids, f(t, ids)) for t in tags]
        counts.append(f.n)
    return counts[0], counts[1], out


def test_a_call_past_the_bound_is_held_whole_for_the_next():
    """120 values against a bound of 50: the second call computes none, and reads the values computed."""
    first, second, out = two_calls(SubsetValues(limit=50))
    assert (first, second) == (120, 0)
    ids = np.concatenate([np.arange(40), np.arange(0, 40, 3)])
    for t, got in zip((1, 2, 3), out, strict=True):
        assert got.tobytes() == (ids * 10.0 + t).tobytes()


class CutInCall(SubsetValues):
    """The old policy: start afresh as soon as the bound is passed, within a call too."""

    def values(self, tag, ids, compute):
        if self.size > self.limit:
            self._held, self._size = {}, 0
        return super().values(tag, ids, compute)


def test_negative_control_a_store_cut_within_a_call_is_caught():
    first, second, _ = two_calls(CutInCall(limit=50))
    assert second > 0, "a store cut within a call computed nothing again: the test could not fail"


def test_past_the_bound_only_the_last_call_is_kept():
    """Between calls, past the bound, the values the last call did not use are dropped (memory stays bounded)."""
    store = SubsetValues(limit=50)
    two_calls(store, tags=(1,))
    two_calls(store, tags=(2,))
    store.begin()
    assert store.size == 40
    f = Counted()
    ids = np.arange(40)
    store.values(1, ids, f(1, ids))
    assert f.n == 40  # tag 1 was dropped


def test_a_pef_past_the_bound_answers_as_a_fresh_one(monkeypatch):
    """With a bound of 20 values, the exact PEF's subset values and best subsets stay those of a fresh PEF."""
    monkeypatch.setattr(subsetvalues, "MAX_VALUES", 20)
    sc = scenarios.load("paper-docks")
    subsets = np.array([[0, 1], [0, 2], [1, 2], [3, 5]])
    rng = np.random.default_rng(9)
    pts = np.column_stack([rng.uniform(0.5, 19.5, 30), rng.uniform(0.5, 11.5, 30)])
    memo = PEF(sc, model="exact")
    for batch in (pts, pts[::2], pts):
        fresh = PEF(sc, model="exact")
        assert memo.tau_subset(batch, subsets).tobytes() == fresh.tau_subset(batch, subsets).tobytes()
        assert memo.at(batch).tau.tobytes() == fresh.at(batch).tau.tobytes()
    assert memo._exact_values(begin=False).limit == 20
