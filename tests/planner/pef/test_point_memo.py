"""The PEF's memo of points asked before (:mod:`planner.pef.pointmemo`) changes no answer.

A PEF asked for overlapping batches of points (a schedule's sampling of the same path, again
and again) must give, bit for bit, what a fresh PEF gives for each batch alone: the memo holds
a value for the exact bits of its point, and ``-0.0`` and ``0.0`` are two points to it. Exact
equality is the claim (the memo returns the stored float), so no tolerance.

Negative control: a memo that finds points by their coordinates rounded to 1 cm (a plausible
"nearby point" shortcut) returns a neighbour's value, and the comparison must fail.
"""

from __future__ import annotations

import numpy as np
import pytest

import scenarios
from planner.pef import map as pef_map
from planner.pef import pointmemo
from planner.pef.map import PEF


def batches(rng: np.random.Generator) -> list[np.ndarray]:
    """Return three batches of points over paper-docks' floor.

    The second repeats half the first, the third the second's points moved by 1-9 mm (what a
    coarse memo confuses) and the signed zeros.
    """
    def draw(n):
        return np.column_stack([rng.uniform(0.5, 19.5, n), rng.uniform(0.5, 11.5, n)])
    a = draw(40)
    b = np.vstack([a[::2], draw(20)])
    c = np.vstack([b + rng.uniform(0.001, 0.009, b.shape), [[0.0, 0.0], [-0.0, 0.0], [0.0, -0.0]], b[:5]])
    return [a, b, c]


def answers(pef: PEF, pts: np.ndarray, subsets: np.ndarray) -> list[np.ndarray]:
    r = pef.at(pts)
    return [r.tau, r.best, r.tau_plain, r.fallback, pef.tau_subset(pts, subsets)]


@pytest.mark.parametrize("model", ["exact", "parallelogram"])
def test_a_pef_asked_again_answers_as_a_fresh_one(model):
    sc = scenarios.load("paper-docks")
    subsets = np.array([[0, 1], [0, 2], [1, 2], [3, 5]])
    memo = PEF(sc, model=model, redundancy=1)
    for pts in batches(np.random.default_rng(7)):
        got = answers(memo, pts, subsets)
        want = answers(PEF(sc, model=model, redundancy=1), pts, subsets)
        for g, w in zip(got, want, strict=True):
            assert g.tobytes() == w.tobytes()
        assert np.isfinite(got[0]).sum() > len(pts) // 2  # the points see markers: values to confuse


def test_negative_control_a_memo_by_rounded_points_is_caught(monkeypatch):
    """Keys of points rounded to 1 cm: the third batch gets the second's values, and they differ."""
    def coarse(pts):
        return pointmemo.point_keys(np.round(np.asarray(pts, dtype=float), 2) + 0.0)
    monkeypatch.setattr(pef_map, "point_keys", coarse)
    sc = scenarios.load("paper-docks")
    subsets = np.array([[0, 1], [0, 2], [1, 2], [3, 5]])
    memo = PEF(sc, model="exact", redundancy=1)
    differ = False
    for pts in batches(np.random.default_rng(7)):
        got = answers(memo, pts, subsets)
        want = answers(PEF(sc, model="exact", redundancy=1), pts, subsets)
        differ |= any(g.tobytes() != w.tobytes() for g, w in zip(got, want, strict=True))
    assert differ, "a memo of neighbouring points gave the same answers: the test could not fail"


def test_the_memo_starts_afresh_past_its_size(monkeypatch):
    """Past :data:`pointmemo.MAX_POINTS` the rows are numbered again: the answers stay those of a fresh PEF."""
    monkeypatch.setattr(pointmemo, "MAX_POINTS", 50)
    sc = scenarios.load("paper-docks")
    subsets = np.array([[0, 1], [1, 2]])
    memo = PEF(sc, model="exact", redundancy=1)
    for pts in batches(np.random.default_rng(8)):
        got = answers(memo, pts, subsets)
        want = answers(PEF(sc, model="exact", redundancy=1), pts, subsets)
        for g, w in zip(got, want, strict=True):
            assert g.tobytes() == w.tobytes()
    assert memo._memo("at", 0.0).epoch > 0  # it did start afresh
