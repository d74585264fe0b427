"""The filter at rest: a robot held minutes at its goal stays consistent.

A lone robot drives a diagonal task on an empty floor (``tests/data/rest_floor.toml``) and is
held ``HOLD`` s at its goal (``montecarlo.hold``), parked, fixing at the laser's rate; it stands
heading 37 deg off the floor's axes, where the drift was large (none along the axes). Before the parking brake, Bullet's
friction let the standing robot slide 10-30 um/s and turn 5-15 urad/s, unseen by the encoders
(and a wheel held at a tick edge toggled its count): the filter, fixing ever more precisely on
a pose it believed still, went to NEES 65 after 200 s. Runs are independent (own seeds), so at
the hold's end the runs' NEES sum to chi2 with 3 N degrees of freedom, and the hold's last
``WINDOW`` s of range updates, whose innovations are white in a consistent filter, to chi2 with
their count: each checked against its two-sided interval of false-alarm probability ``ALPHA``.
Negative control: the robot not parked (the old physics) fails the NEES test.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.stats import chi2

import scenarios
from sim.episode.drive import prepare, run_episode

DATA = Path(__file__).resolve().parents[2] / "data"
HOLD = 120.0     # montecarlo.hold of the scenario [s]
WINDOW = 60.0    # the hold's last seconds whose updates' NIS are summed [s]
RUNS = 6
ALPHA = 0.01     # false-alarm probability of each check (two-sided)


def interval(dof: int) -> tuple[float, float]:
    return float(chi2.ppf(ALPHA / 2, dof)), float(chi2.ppf(1 - ALPHA / 2, dof))


def held_runs() -> tuple[float, int, float, int]:
    """Return the runs' NEES sum at the hold's end, its dof, the NIS sum over the window and its dof."""
    sc = scenarios.load(str(DATA / "rest_floor.toml"))
    assert sc.montecarlo.hold == HOLD
    prep = prepare(sc, 0)
    nees = nis = 0.0
    updates = 0
    for seed in range(RUNS):
        r = run_episode(sc, 0, seed, prepared=prep)
        assert r.summary["reached"]
        end = float(r.steps.t[-1])
        assert end >= HOLD
        nees += float(r.steps.nees[-1])
        late = r.fixes.t >= end - WINDOW
        nis += float(np.sum(r.fixes.nis[late]))
        updates += int(np.sum(r.fixes.n_accepted[late]))
    return nees, 3 * RUNS, nis, updates


@pytest.mark.e2e
def test_a_robot_held_at_its_goal_stays_consistent():
    nees, dof, nis, updates = held_runs()
    lo, hi = interval(dof)
    assert lo <= nees <= hi, f"NEES sum {nees:.1f} outside [{lo:.1f}, {hi:.1f}] ({dof} dof)"
    assert updates > RUNS * WINDOW   # a fix a second at least
    lo, hi = interval(updates)
    assert lo <= nis <= hi, f"NIS sum {nis:.1f} outside [{lo:.1f}, {hi:.1f}] ({updates} updates)"


@pytest.mark.e2e
def test_negative_control_a_robot_that_slides_at_rest_fails(monkeypatch):
    from sim.physics.robot import DiffDriveRobot

    monkeypatch.setattr(DiffDriveRobot, "park", lambda self, on: None)
    nees, dof, _, _ = held_runs()
    assert nees > interval(dof)[1]
