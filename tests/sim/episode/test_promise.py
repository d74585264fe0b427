"""An episode keeps the plan's promise at every fix (uniform noise), and the static PEF does not."""

from __future__ import annotations

import numpy as np
import pytest

import scenarios
from estimators.fault.exact import DEFAULT_TOLERANCE_FRACTION
from planner.schedule.promise import PROMISE_TOLERANCE
from sim.episode.drive import prepare, run_episode


@pytest.fixture(scope="module")
def episode():
    sc = scenarios.load("paper-docks")
    return sc, run_episode(sc, 0, seed=11, prepared=prepare(sc, 0))


def _broken(fixes, promise):
    # the realised polygon may reach one polygon tolerance beyond each arc: twice on a diameter
    tol = DEFAULT_TOLERANCE_FRACTION * np.nanmin(fixes.rho, axis=1)
    return fixes.fault_diameter > (1.0 + PROMISE_TOLERANCE) * promise + 2.0 * tol


def test_every_fix_has_a_promise_and_keeps_it(episode):
    sc, ep = episode
    fx = ep.fixes
    assert len(fx.t) > 50
    assert np.all(np.isfinite(fx.predicted_tau))
    assert not _broken(fx, fx.predicted_tau).any()
    assert np.all(fx.fault_diameter < sc.planning.eps_max)
    assert np.all(fx.contained)


def test_the_static_pef_is_not_what_a_moving_robot_realises(episode):
    # negative control: the paper's static PEF of the same subsets at the truth
    _, ep = episode
    fx = ep.fixes
    assert _broken(fx, fx.static_tau).mean() > 0.5
