"""The certified bound against its definition, evaluated fix by fix over every later step."""

from __future__ import annotations

import numpy as np
import pytest

import scenarios
from planner.schedule.drift import drift_bound
from sim.episode.certify import certified_bound, heading_quantum, lost_markers, single_failure_excused, turning


def _played_turning(heading, quantum):
    # turning's docstring, step by step: the play follows the unwrapped heading only when it
    # leaves the band of +-quantum around it, and its moves add up
    turn, y, prev, u = [0.0], heading[0], heading[0], heading[0]
    for h in heading[1:]:
        u += (h - prev + np.pi) % (2.0 * np.pi) - np.pi
        prev = h
        z = min(max(y, u - quantum), u + quantum)
        turn.append(turn[-1] + abs(z - y))
        y = z
    return np.array(turn)


def _reference(robot, t, s, heading, fix_t, fix_tau, fix_time):
    # module docstring: the smallest, over the fixes completed before a step (the dock at t[0]
    # with promise 0 among them), of promise + drift since the fix's start
    turn = _played_turning(heading, heading_quantum(robot))
    fix_t, fix_tau = np.r_[t[0], fix_t], np.r_[0.0, fix_tau]
    out = np.full(t.size, np.inf)
    for ft, tau in zip(fix_t, fix_tau, strict=True):
        s0, u0 = np.interp(ft - fix_time, t, s), np.interp(ft - fix_time, t, turn)
        for i in np.flatnonzero(t >= ft):
            b = tau + float(drift_bound(robot, max(s[i] - s0, 0.0), max(turn[i] - u0, 0.0)))
            out[i] = min(out[i], b)
    return out


def _case(seed: int, monotone: bool):
    rng = np.random.default_rng(seed)
    n = 900
    t = np.arange(n) / 60.0
    v = rng.uniform(0.0, 1.2, n) if monotone else rng.uniform(-0.3, 1.2, n)
    s = np.cumsum(v) / 60.0
    heading = np.cumsum(rng.normal(0.0, 0.02, n))
    fix_t = np.sort(rng.choice(t[5:], 70, replace=False))
    fix_tau = rng.uniform(0.002, 0.02, fix_t.size)
    fix_tau[rng.random(fix_t.size) < 0.1] = np.inf            # fixes without a promise
    return t, s, heading, fix_t, fix_tau


@pytest.mark.parametrize("monotone", [True, False])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_certified_bound_is_its_definition(seed, monotone):
    robot = scenarios.load("warehouse").robot
    args = (*_case(seed, monotone), 0.04)
    np.testing.assert_allclose(certified_bound(robot, *args), _reference(robot, *args), rtol=1e-12, atol=0)


def test_a_fix_left_out_is_told_apart():
    # negative control: the comparison sees one promise 1 mm off
    robot = scenarios.load("warehouse").robot
    t, s, heading, fix_t, fix_tau = _case(0, True)
    worse = fix_tau.copy()
    worse[np.flatnonzero(np.isfinite(worse))[10]] += 0.001
    assert not np.allclose(certified_bound(robot, t, s, heading, fix_t, fix_tau, 0.04),
                           certified_bound(robot, t, s, heading, fix_t, worse, 0.04), rtol=1e-12, atol=0)


def _excused_reference(t, attempt_t, beyond, done_t, planned, fix_time):
    # the docstring, step by step: excused when some attempt beyond the test started at or before
    # the step and no fix completed before the step that a later attempt within the test
    # started (the last attempt at least fix_time before its completion) and that was planned
    out = np.zeros(t.size, dtype=bool)
    owner = [int(np.flatnonzero(attempt_t <= d - fix_time + 1e-12)[-1]) for d in done_t]
    for i, ti in enumerate(t):
        for a in np.flatnonzero(beyond & (attempt_t <= ti)):
            cleared = any(o > a and not beyond[o] and p and d < ti
                          for o, d, p in zip(owner, done_t, planned, strict=True))
            if not cleared:
                out[i] = True
                break
    return out


def _attempts(seed):
    rng = np.random.default_rng(seed)
    t = np.arange(1200) / 60.0
    attempt_t = np.sort(rng.choice(t[3:-30], 90, replace=False))
    beyond = rng.random(attempt_t.size) < 0.25
    completes = rng.random(attempt_t.size) < 0.85          # some attempts start or finish no fix
    done_t = attempt_t[completes] + 0.04 + rng.uniform(0.0, 1.0 / 240.0, completes.sum())
    planned = rng.random(done_t.size) < 0.9                 # some completed fixes improvised
    return t, attempt_t, beyond, done_t, planned


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_single_failure_excused_matches_its_definition(seed):
    t, attempt_t, beyond, done_t, planned = _attempts(seed)
    got = single_failure_excused(t, attempt_t, beyond, done_t, planned, fix_time=0.04)
    np.testing.assert_array_equal(got, _excused_reference(t, attempt_t, beyond, done_t, planned, 0.04))
    assert 0 < got.sum() < t.size
    # an attempt that completes nothing, or improvises, does not end the excuse
    every = single_failure_excused(t, attempt_t, beyond, attempt_t + 0.04, np.ones(attempt_t.size, bool), 0.04)
    assert np.all(got >= every) and got.sum() > every.sum()
    # negative control: no attempt beyond the test excuses nothing
    assert not single_failure_excused(t, attempt_t, np.zeros_like(beyond), done_t, planned, 0.04).any()


def test_lost_markers_counts_the_scheduled_subset_and_its_fallback():
    sched, fbs = (3, 7), ((7, 9), (3, 11))
    assert lost_markers(frozenset(), sched, fbs) == 0
    assert lost_markers(frozenset({5, 9}), sched, fbs) == 0          # neither is counted on
    assert lost_markers(frozenset({3}), sched, fbs) == 1             # the fallback (7, 9) is clear
    assert lost_markers(frozenset({3, 9}), sched, fbs) == 2          # ... and then its 9 is blocked too
    assert lost_markers(frozenset({3, 7}), sched, fbs) == 2
    assert lost_markers(frozenset({7, 11}), sched, fbs) == 2
    assert lost_markers(frozenset({3}), sched, ((), (3, 11))) == 1   # no fallback named: one lost
    assert lost_markers(frozenset({3, 9}), sched, ()) == 1


def test_turning_is_the_play_of_the_heading_and_ignores_the_quantum():
    """A straight whose estimate steps back and forth by a quantum did not turn; a real turn counts.

    Negative control: summing the steps themselves (what the bound counted before) charges the
    straight a quantum per step.
    """
    robot = scenarios.load("warehouse").robot
    q = heading_quantum(robot)
    assert q == pytest.approx(2.0 * np.pi * 0.1 / 2048 / 0.5)
    rng = np.random.default_rng(3)
    straight = 0.3 + q * rng.integers(0, 2, 600)           # the count one tick either way
    assert turning(straight, q)[-1] == 0.0
    raw = np.sum(np.abs(np.diff(straight)))
    assert raw > 100 * q                                   # the old count: some 300 quanta
    # a quarter turn with the same jitter, across the wrap at +-pi: at least the turn less a band
    turn = np.angle(np.exp(1j * (np.pi - 0.5 + np.linspace(0.0, np.pi / 2, 600) + q * rng.integers(0, 2, 600))))
    got = turning(turn, q)
    assert np.pi / 2 - 2 * q <= got[-1] <= np.pi / 2 + 2 * q
    assert np.all(np.diff(got) >= 0.0)
    np.testing.assert_allclose(got, _played_turning(turn, q), rtol=0, atol=1e-12)
