"""Robots trading docks, in physics: a swap and a three-way rotation drive without a collision.

``tests.sim.fleets.SWAP``: r1 W -> E while r2 E -> W on a hall with two aisles; planned on one
route they would meet head-on, so the later robot is routed around the earlier one's segments
(:func:`planner.fleet.plan._reroute`) and takes the other aisle. ``ROTATION``: r1 W -> E, r2
E -> N, r3 N -> W, each ending on the dock the next one leaves. Every dock lies on another robot's
path: the robots keep the plan's order of passage (``FleetPlan.order``). ``PARKED``: r1 finishes on
the only corridor, which r0 drives later, and drives on to its parking place. The abstract cases
and their negative controls are ``tests/planner/fleet/test_dock_trades.py`` and ``test_parking.py``.
"""

from __future__ import annotations

import numpy as np
import pytest

from scenarios import load, loads
from sim.episode.fleet import prepare_fleet, run_fleet_episode
from tests.sim import fleets


@pytest.mark.e2e   # plans and drives a fleet on a small floor: ~10 s each
@pytest.mark.parametrize("name", ["SWAP", "ROTATION"])
def test_trading_fleets_drive_without_a_collision(name):
    sc = loads(getattr(fleets, name), source=f"{name.lower()}.toml")
    prepared = prepare_fleet(sc)
    assert prepared.plan.order is not None     # docks on each other's paths: the order of passage rules
    routes = [tuple(p.candidates[p.chosen].nodes) for rp in prepared.plan.robots for p in rp.plans]
    if name == "SWAP":
        assert {"sw", "nw"} <= {n for r in routes for n in r} and routes[0] != routes[1][::-1]   # one aisle each
    for seed in (1, 2):
        res = run_fleet_episode(sc, seed=seed, prepared=prepared)
        assert res.collisions == 0
        for r in res.robots:
            s = r.result.summary
            assert s["reached"] and s["status"] == "ok" and s["collisions"] == 0, (r.name, s["status"])


@pytest.mark.e2e   # plans and drives a fleet twice: ~5 s of CPU
def test_a_robot_finishing_on_the_only_corridor_parks_off_it_and_nobody_touches():
    # r1 M1 -> M2 on the corridor r0 drives 15 s later, then on to its parking place P up a spur
    # (planner.fleet.parking); without P no robot can move (tests/planner/fleet/test_parking.py)
    sc = loads(fleets.PARKED, source="parked.toml")
    prepared = prepare_fleet(sc)
    assert prepared.plan.robots[1].park == "P"
    for seed in (1, 2):
        res = run_fleet_episode(sc, seed=seed, prepared=prepared)
        assert res.collisions == 0
        for r, dock in zip(res.robots, ("E", "P"), strict=True):
            s = r.result.summary
            assert s["reached"] and s["status"] == "ok" and s["collisions"] == 0, (r.name, s["status"])
            end = r.result.steps.true_pose[-1, :2]
            assert np.hypot(*(end - sc.dock(dock).position)) < 0.05 + sc.planning.eps_max, (r.name, end)


@pytest.mark.e2e   # plans twelve tasks on the 120 x 80 m hall and drives ~600 robot-seconds: about a minute of CPU
def test_the_hall_fleet_trades_docks_without_a_collision():
    # six robots in three pairs, each pair trading docks, two tasks each (scenarios/library/hall-fleet.toml)
    sc = load("hall-fleet")
    prepared = prepare_fleet(sc)
    assert prepared.plan.order is not None     # docks on other robots' paths: the order of passage rules
    res = run_fleet_episode(sc, seed=1, prepared=prepared)
    assert res.collisions == 0
    for r, fr in zip(res.robots, sc.robots, strict=True):
        s = r.result.summary
        assert s["reached"] and s["status"] == "ok" and s["collisions"] == 0, (r.name, s["status"])
        goal = sc.dock(sc.tasks[fr.tasks[-1]].goal).position
        assert np.hypot(*(r.result.steps.true_pose[-1, :2] - goal)) < 0.05 + sc.planning.eps_max, r.name
