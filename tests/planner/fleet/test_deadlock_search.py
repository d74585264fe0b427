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

import heapq
import itertools
import math

import numpy as np
import pytest

from planner.fleet.zones import DEFAULT_MARGIN, ZoneControl
from scenarios.errors import PlanningError
from scenarios.worlds import draw_world
from sim.episode.fleet import BRAKE, LOOKAHEAD, RELEASE_SLACK, STOP_MARGIN
from sim.episode.follower import PurePursuit

SPACING = 0.05       # sample spacing of the paths [m] (the planner's are finer than 0.1 m)
DT = 0.1             # time step of the abstract run [s]
PATIENCE = 60.0      # a fleet in which nobody moved for this long is deadlocked [s]
MAX_ACCEL = PurePursuit.max_accel
GOAL_TOLERANCE = PurePursuit.goal_tolerance
#: Farthest a robot stands from the held sample nearest it [m]: STOP_MARGIN at a stop, the goal
#: tolerance at its dock, half a spacing while it drives.
DEVIATION = max(STOP_MARGIN, GOAL_TOLERANCE, SPACING / 2)


def polyline(pts) -> np.ndarray:
    """Points along the polyline through ``pts``, at most SPACING apart, shape (N, 2)."""
    pts = np.asarray(pts, float)
    out = [pts[:1]]
    for a, b in itertools.pairwise(pts):
        n = max(1, int(np.ceil(np.hypot(*(b - a)) / SPACING)))
        out.append(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
    return np.concatenate(out)


def shortest_route(nodes: dict, segments: list, a: str, b: str) -> list[str] | None:
    """Node names of the shortest route from ``a`` to ``b`` on the network (Dijkstra), None if none."""
    adj: dict[str, list[tuple[str, float]]] = {}
    for u, v in segments:
        d = math.dist(nodes[u], nodes[v])
        adj.setdefault(u, []).append((v, d))
        adj.setdefault(v, []).append((u, d))
    best, prev, heap = {a: 0.0}, {}, [(0.0, a)]
    while heap:
        d, u = heapq.heappop(heap)
        if u == b:
            break
        if d > best[u]:
            continue
        for v, w in adj.get(u, []):
            if d + w < best.get(v, math.inf):
                best[v], prev[v] = d + w, u
                heapq.heappush(heap, (d + w, v))
    if b not in best:
        return None
    route = [b]
    while route[-1] != a:
        route.append(prev[route[-1]])
    return route[::-1]


def floor(rng: np.random.Generator) -> tuple[dict[str, np.ndarray], list, float]:
    """Draw a world; return its route network's nodes [m] (origin removed), segments and robot radius [m]."""
    world = draw_world(rng, "search", max_size=float(rng.choice([20.0, 30.0, 40.0])))
    routes = world.data["routes"]
    origin = np.asarray(world.data["workspace"]["origin"], float)
    nodes = {k: np.asarray(p, float) - origin for k, p in routes["nodes"].items()}
    return nodes, routes["segments"], float(world.data["robot"]["radius"])


def random_fleet(rng: np.random.Generator, nodes, segments, radius: float,
                 tries: int = 20, clear: bool = True) -> tuple[ZoneControl, list[float], list[float]] | None:
    """Draw a fleet on a floor: its zone control, speeds [m/s] and start times [s].

    The routes are drawn once; the docks' spurs up to ``tries`` times until every dock is clear
    of the other robots' paths (None if never; ``clear`` False: the first draw, wherever its docks).
    """
    names = sorted(nodes)
    n = int(rng.integers(2, 6))
    routes, pairs = [], []
    for i in range(n):
        if i > 0 and rng.random() < 0.5:
            b, a = pairs[int(rng.integers(len(pairs)))]           # head-on: another's route backwards
        else:
            a, b = (str(x) for x in rng.choice(names, size=2, replace=False))
        route = shortest_route(nodes, segments, a, b) or [a, b]
        pairs.append((a, b))
        routes.append([nodes[k] for k in route])
    speeds = list(rng.uniform(0.3, 1.5, size=n))
    starts = list(rng.uniform(0.0, 8.0, size=n))
    for _ in range(tries):
        paths = []
        for pts in routes:
            ang = rng.uniform(0.0, 2.0 * np.pi, size=2)
            spur = rng.uniform(1.2, 3.0, size=2)[:, None] * np.column_stack([np.cos(ang), np.sin(ang)])
            paths.append(polyline([pts[0] + spur[0], *pts, pts[-1] + spur[1]]))
        # zone control refuses a dock nearer another path than the two reaches (and a little
        # farther, by its cells): skip those draws without building it
        reach = 2.0 * (radius + DEFAULT_MARGIN)
        if clear and any(np.min(np.hypot(*(paths[j] - paths[i][k]).T)) < reach
                         for i in range(n) for k in (0, -1) for j in range(n) if j != i):
            continue
        try:
            zc = ZoneControl(paths, [radius] * n)
        except PlanningError as exc:
            assert "of each other" in str(exc), exc   # two robots' docks overlap: drawn again
            continue
        if not clear or zc.dock_conflict is None:
            return zc, speeds, starts
    return None


def run_abstract(zc: ZoneControl, speeds, starts) -> tuple[bool, float, str]:
    """Drive the fleet through ``zc`` as the simulation does (module docstring).

    Returns (all arrived, the closest approach of two robots' path points [m], what stood still).
    """
    n = len(zc.paths)
    s = [0.0] * n
    length = [zc.length(i) for i in range(n)]
    done = [False] * n
    t, idle, closest = 0.0, 0.0, math.inf
    while not all(done):
        moved = False
        for i in range(n):
            if done[i] or t < starts[i]:
                continue
            v = speeds[i]
            zc.release(i, s[i] - RELEASE_SLACK)
            zc.request(i, s[i] + v * DT + v * v / (2.0 * BRAKE * MAX_ACCEL) + LOOKAHEAD)
            full = zc.reserved_to(i) >= length[i]
            limit = length[i] - GOAL_TOLERANCE if full else zc.reserved_to(i) - STOP_MARGIN
            new = min(s[i] + v * DT, max(limit, s[i]))
            moved |= new > s[i] + 1e-12
            s[i] = new
            if full and new >= limit - 1e-12:
                done[i] = True
                zc.stand(i)
            elif new >= limit - 1e-12:
                zc.stand(i)
        xy = [zc.point(i, s[i]) for i in range(n)]
        for a, b in itertools.combinations(range(n), 2):   # (one not started yet stands on its dock)
            closest = min(closest, float(np.hypot(*(xy[a] - xy[b]))))
        started = all(t >= st for st in starts)
        idle = idle + DT if (started and not moved) else 0.0
        if idle > PATIENCE:
            still = ", ".join(f"{zc.names[i]} at s = {s[i]:.2f} of {length[i]:.2f} m (waits for "
                              f"{zc.names[zc.refused_by[i]]})" for i in range(n) if not done[i])
            return False, closest, still
        t += DT
    return True, closest, ""


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
