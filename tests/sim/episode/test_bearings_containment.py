"""Episodes with bearings under bounded noise: the truth is in every realised fault area.

The realised area uses the robot-frame bearings through their pairwise differences, with no
heading (:mod:`estimators.fault.exact`); carried bearings get the odometry's turn bound. Under
the declared bounded noise a miss is impossible, so none is allowed (false-alarm probability
0). The negative control of the construction is in ``tests/estimators/fault/test_heading_free.py``.
"""

from __future__ import annotations

import numpy as np
import pytest

import estimators.snapshot
import scenarios
from sim.episode.drive import prepare, run_episode

SMALL_L = """
name = "small-l-bearings"
description = "10 x 8 m L-shaped room, bearings 0.15 deg, 1 cm ranges, uniform noise, three markers per fix"
seed = 5

[workspace]
size = [10.0, 8.0]

[[obstacles]]
center = [7.5, 6.0]
size = [5.0, 4.0]

[[markers]]
id = "W1"
position = [0.0, 2.0]

[[markers]]
id = "W2"
position = [0.0, 6.0]

[[markers]]
id = "N1"
position = [3.0, 8.0]

[[markers]]
id = "S1"
position = [4.0, 0.0]

[[markers]]
id = "S2"
position = [8.0, 0.0]

[[markers]]
id = "E1"
position = [10.0, 2.0]

[[markers]]
id = "I1"
position = [5.0, 6.0]

[[markers]]
id = "I2"
position = [7.5, 4.0]

[sensor]
relative_error = 6.7e-5
absolute_error = 0.01              # ranges about as good as the bearings (r xi = 8 mm at 3 m)
noise = "uniform"
bearing_error_deg = 0.15
max_range = 15.0
measurement_time = 0.02
markers_per_fix = 3
fix_rate_hz = 5.0

[robot]
wheel_radius = 0.05
wheel_base = 0.3
radius = 0.201
max_speed = 0.8
encoder_ticks = 1024
wheel_radius_error = 0.002
odometry_noise = 0.01
turn_slip = 0.13

[planning]
eps_max = 0.1
pef_model = "strips"
gdop_level = 0.95
resolution = 0.1

[[docks]]
name = "A"
pose = [1.5, 6.5, -90.0]

[[docks]]
name = "B"
pose = [8.5, 1.5, 0.0]

[[tasks]]
from = "A"
to = "B"
"""


@pytest.fixture(scope="module")
def small_l():
    s = scenarios.loads(SMALL_L, source="small-l-bearings.toml")
    return s, prepare(s, 0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_no_fix_with_bearings_misses_containment(small_l, seed, monkeypatch):
    s, p = small_l
    original, ratio = estimators.snapshot.exact_fault_area, []

    def with_ranges_only(*args, **kwargs):
        area = original(*args, **kwargs)
        ratio.append(area.area / original(*args).area)
        return area

    monkeypatch.setattr(estimators.snapshot, "exact_fault_area", with_ranges_only)
    r = run_episode(s, 0, seed=seed, prepared=p)
    # the world is chosen so that the bearings do cut the annuli (else the test shows nothing)
    assert np.sum(np.array(ratio) < 0.9) > len(ratio) // 4
    assert r.summary["reached"] and r.summary["fixes"] > 20, r.summary
    # three markers, all measured: three bearing pairs in each area
    assert np.all(r.fixes.markers >= 0)
    assert np.all(np.isfinite(r.fixes.fault_diameter))
    assert r.fixes.contained.all(), np.flatnonzero(~r.fixes.contained)
