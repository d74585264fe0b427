"""The certified bound against its definition, evaluated fix by fix over every later step."""

from __future__ import annotations

import numpy as np
import pytest

import scenarios
from planner.schedule.drift import drift_bound
from sim.episode.certify import certified_bound


def _reference(robot, t, s, heading, fix_t, fix_tau, fix_time):
    # module docstring: the smallest, over the fixes completed before a step (the dock at t[0]
    # with promise 0 among them), of promise + drift since the fix's start
    turn = np.concatenate([[0.0], np.cumsum(np.abs(np.angle(np.exp(1j * np.diff(heading)))))])
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
