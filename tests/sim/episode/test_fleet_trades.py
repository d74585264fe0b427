"""Robots trading docks, in physics: a swap and a three-way rotation drive without a collision.

``tests.sim.fleets.SWAP``: r1 W -> E while r2 E -> W on a hall with two aisles; planned on one
route they would meet head-on, so the later robot is routed around the earlier one's segments
(:func:`planner.fleet.plan._reroute`) and takes the other aisle. ``ROTATION``: r1 W -> E, r2
E -> N, r3 N -> W, each ending on the dock the next one leaves. Every dock lies on another robot's
path: the robots keep the plan's order of passage (``FleetPlan.order``). The abstract cases and
their negative control are ``tests/planner/fleet/test_dock_trades.py``.
"""

from __future__ import annotations

import pytest

from scenarios import loads
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
