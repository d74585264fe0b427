"""A fleet episode keeps each robot's drawn timing: it leaves late and drives slower as drawn."""

from __future__ import annotations

import numpy as np
import pytest

from planner.fleet import timing
from scenarios import loads
from sim.episode.drive import seed_sequence
from sim.episode.fleet import prepare_fleet, run_fleet_episode
from tests.sim.fleets import CROSS

SPREAD = CROSS.replace('name = "north"\ntasks = [1]',
                       'name = "north"\ntasks = [1]\nstart_jitter = 6.0\nspeed_spread = 0.3')


@pytest.mark.e2e   # two fleet episodes on the small crossing: ~10 s
def test_a_robot_leaves_and_drives_as_its_run_drew():
    sc = loads(SPREAD, source="cross.toml")
    prepared = prepare_fleet(sc)
    for seed in (4, 5):
        drawn = timing.draw(sc.robots[1], timing.stream(seed_sequence(seed), 1))
        res = run_fleet_episode(sc, seed=seed, prepared=prepared)
        steps = res.robots[1].result.steps
        moved = np.hypot(*(steps.true_pose[:, :2] - steps.true_pose[0, :2]).T) > 0.02
        left = float(steps.t[np.argmax(moved)])
        # it stands until start_time + the drawn delay, then accelerates (2 cm take ~0.3 s at 0.5 m/s^2)
        assert drawn.release_delay <= left <= drawn.release_delay + 0.5, (seed, drawn, left)
        # slower as drawn: its drive, waits aside, takes about 1/f of the plan's (the follower's
        # ramps at 0.5 m/s^2 and its turns are not scaled: within 15 %)
        s = res.robots[1].result.summary
        drive = s["arrival"] - left - res.robots[1].wait_time
        assert drive == pytest.approx(prepared.plan.robots[1].alone_time / drawn.speed_factor, rel=0.15), (seed, drawn)
        assert res.collisions == 0 and all(r.result.summary["reached"] for r in res.robots)
    assert drawn.speed_factor < 1.0
