"""A fleet robot's declared timing spread: the keys, the per-run draws, and the lag model they imply."""

from __future__ import annotations

import numpy as np
import pytest

import scenarios
from planner.fleet import timing
from planner.fleet.blocking import TIMING
from scenarios.errors import ScenarioError
from tests.sim.fleets import CROSS


def _robot(**spread):
    keys = "\n".join(f"{k} = {v}" for k, v in spread.items())
    sc = scenarios.loads(CROSS.replace('name = "east"\ntasks = [0]', 'name = "east"\ntasks = [0]\n' + keys),
                         source="cross.toml")
    return sc.robots[0]


def test_the_keys_load_and_bad_values_are_refused_by_name():
    fr = _robot(start_jitter=4.0, dwell=2.5, speed_spread=0.1)
    assert (fr.start_jitter, fr.dwell, fr.speed_spread) == (4.0, 2.5, 0.1)
    assert (_robot().start_jitter, _robot().dwell, _robot().speed_spread) == (0.0, 0.0, 0.0)
    with pytest.raises(ScenarioError, match=r"robots\[0\]\.start_jitter.*>= 0"):
        _robot(start_jitter=-1.0)
    with pytest.raises(ScenarioError, match=r"robots\[0\]\.speed_spread.*<= 0\.5"):
        _robot(speed_spread=0.8)


def test_draws_follow_the_seed_and_nothing_declared_draws_nothing():
    fr = _robot(start_jitter=4.0, speed_spread=0.1)
    ss = np.random.SeedSequence(7, spawn_key=(3,))
    a, b = timing.draw(fr, timing.stream(ss, 1)), timing.draw(fr, timing.stream(ss, 1))
    assert a == b                                           # the same run: the same numbers
    assert timing.draw(fr, timing.stream(ss, 2)) != a       # another robot: its own stream
    assert 0.0 <= a.release_delay <= 4.0 and 0.9 <= a.speed_factor <= 1.0
    still = timing.draw(_robot(), timing.stream(ss, 1))
    assert still == timing.TimingDraw(0.0, (), 1.0)          # exactly: the drive is as it was


def test_speed_moments_match_the_draws():
    # mean and variance of 1/f - 1 over 200000 draws of f: the sample mean is within 5 standard
    # errors (false alarm 6e-7); negative control: the moments of f itself miss by far more
    s = 0.3
    f = 1.0 - s * np.random.default_rng(1).random(200_000)
    x = 1.0 / f - 1.0
    m, v = timing.speed_moments(s)
    se = np.sqrt(v / len(x))
    assert abs(x.mean() - m) < 5 * se
    assert abs(x.var() - v) < 5 * np.sqrt(np.mean((x - x.mean()) ** 4) / len(x))
    assert abs(x.mean() - (1.0 - (1.0 - s / 2.0))) > 50 * se      # E[1 - f] is not E[1/f - 1]
    assert timing.speed_moments(0.0) == (0.0, 0.0)


def test_the_declared_model_adds_the_spread_to_the_robots_own():
    fr = _robot(start_jitter=6.0, dwell=3.0, speed_spread=0.1)
    model = timing.declared_model(fr, docks=[20.0])
    m, v = timing.speed_moments(0.1)
    assert model.lag0 == pytest.approx(TIMING.lag0 + 3.0) and model.base_var == pytest.approx(TIMING.base_var + 3.0)
    assert model.lag_rate == pytest.approx(TIMING.lag_rate + m) and model.var_quad == pytest.approx(v)
    # a dwell of U[0, 3] s once the robot has passed its dock at 20 s driven
    assert model.mean(25.0) - model.mean(19.0) == pytest.approx(1.5 + 6.0 * model.lag_rate)
    assert model.var(25.0) - model.var(19.0) == pytest.approx(0.75 + 6.0 * TIMING.var_rate + v * (25**2 - 19**2))
    assert model.tie_wait and not timing.declared_model(_robot()).tie_wait
