"""A search for deadlocks: random fleets on random worlds' floors, driven through zone control.

Zone control's rule (:mod:`planner.fleet.zones`) is simulated abstractly, as a discrete-event
run of the reservations with the robots' real stopping points and releases, the ones the
simulation's fleet episode uses (:mod:`sim.episode.fleet`): each robot asks for the floor up to
its braking distance plus ``LOOKAHEAD`` ahead, frees what lies ``RELEASE_SLACK`` behind it,
stops ``STOP_MARGIN`` short of its reservation's end and parks within the follower's goal
tolerance of its final dock, standing (:meth:`ZoneControl.stand`) wherever it stops. No physics:
a fleet takes milliseconds, so the search covers many.

The fleets: :func:`scenarios.worlds.draw_world` floors (loops, U-turns, combs, L-halls), 2-5
robots, each between two nodes of the floor's route network along its shortest route, half the
pairs head-on (one robot drives another's route backwards), the others crossing or sharing
corridors; every dock on a spur 1.2-3 m long off the network (drawn in any direction: zone
control is pure logic, walls do not matter to it), random speeds and start times. Spurs that put
a dock within reach of another robot's path are drawn again: the stop rule's argument needs docks
clear (``tests/planner/fleet/test_dock_trades.py`` searches fleets whose docks are not).

Negative control: with :meth:`ZoneControl.stand` a no-op (a robot keeps the cells just behind
its stop, which need not be safe: what the simulation did before a stopped robot released them)
the same search finds robots that wait for each other for ever.
"""

from __future__ import annotations

import numpy as np
import pytest

from planner.fleet.zones import DEFAULT_MARGIN, ZoneControl
from tests.planner.fleet.zone_runs import DEVIATION, floor, random_fleet, run_abstract

FLEETS_PER_FLOOR = 5


def search(seed: int, count: int) -> tuple[int, list[str]]:
    """Run ``count`` accepted random fleets; return how many were drawn and the deadlocks found."""
    rng = np.random.default_rng(seed)
    drawn, accepted, stuck = 0, 0, []
    while accepted < count:
        nodes, segments, radius = floor(rng)
        for _ in range(FLEETS_PER_FLOOR):
            drawn += 1
            fleet = random_fleet(rng, nodes, segments, radius)
            if fleet is None:
                continue
            zc, speeds, starts = fleet
            accepted += 1
            ok, closest, still = run_abstract(zc, speeds, starts)
            if not ok:
                stuck.append(f"fleet {accepted} of seed {seed}: {still}")
                continue
            # held footprints are disjoint, each robot within DEVIATION of a held sample
            bound = 2.0 * (radius + DEFAULT_MARGIN) - 2.0 * DEVIATION
            assert closest >= bound - 1e-9, f"fleet {accepted} of seed {seed}: robots {closest:.3f} m apart"
    return drawn, stuck


@pytest.mark.parametrize("count,seed", [(20, 48), pytest.param(400, 4747, marks=pytest.mark.e2e)])
def test_random_fleets_never_deadlock(count, seed):
    drawn, stuck = search(seed, count)
    assert not stuck, "\n".join(stuck)
    assert drawn < 3 * count   # the draw is not mostly fleets whose docks zone control refuses


@pytest.mark.parametrize("count,seed", [(20, 48), pytest.param(400, 4747, marks=pytest.mark.e2e)])
def test_negative_control_keeping_the_cells_behind_a_stop_deadlocks(count, seed, monkeypatch):
    monkeypatch.setattr(ZoneControl, "stand", lambda self, i: None)
    _, stuck = search(seed, count)
    assert stuck, "the search found no deadlock with the defect put back: it cannot catch one"
