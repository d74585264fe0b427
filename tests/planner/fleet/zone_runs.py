"""Fleets driven through zone control without physics, shared by the zone-control tests.

Paths sampled along polylines (:func:`polyline`), constant-speed time profiles
(:func:`kinematics`), the closest approach of predicted timelines (:func:`min_distance`), and the
abstract run of the simulation's stopping points and releases with the random floors and fleets
it searches (:func:`run_abstract`, :func:`floor`, :func:`random_fleet`; ``test_deadlock_search.py``
says how).
"""

from __future__ import annotations

import heapq
import itertools
import math

import numpy as np

from planner.fleet.gate import BRAKE, LOOKAHEAD, RELEASE_SLACK, STOP_MARGIN
from planner.fleet.zones import DEFAULT_MARGIN, ZoneControl
from planner.schedule.pathtime import Kinematics
from scenarios.errors import PlanningError
from scenarios.worlds import draw_world
from sim.episode.follower import PurePursuit

SPACING = 0.05       # sample spacing of the paths [m] (the planner's are finer than 0.1 m)
RADIUS = 0.4         # robot radius of the hand-drawn layouts [m]
DT = 0.1             # time step of the abstract run [s]
PATIENCE = 60.0      # a fleet in which nobody moved for this long is deadlocked [s]
MAX_ACCEL = PurePursuit.max_accel
GOAL_TOLERANCE = PurePursuit.goal_tolerance
#: Farthest a robot stands from the held sample nearest it [m]: STOP_MARGIN at a stop, the goal
#: tolerance at its dock, half a spacing while it drives.
DEVIATION = max(STOP_MARGIN, GOAL_TOLERANCE, SPACING / 2)
#: Closest two robots driven by :func:`run_abstract` may come [m]: held footprints are disjoint and
#: each robot is within DEVIATION of a held sample.
CLEAR = 2.0 * (RADIUS + DEFAULT_MARGIN) - 2.0 * DEVIATION
TRIALS = 30          # timings drawn per fleet by :func:`timings`


def polyline_of(pts) -> np.ndarray:
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
            paths.append(polyline_of([pts[0] + spur[0], *pts, pts[-1] + spur[1]]))
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


def timings(rng: np.random.Generator, n: int) -> list[tuple[list[float], list[float]]]:
    """TRIALS draws of speeds [m/s] (0.3-1.5) and start times [s] (0-40) for n robots: timings no plan saw."""
    return [(list(rng.uniform(0.3, 1.5, n)), list(rng.uniform(0.0, 40.0, n))) for _ in range(TRIALS)]


def polyline(*pts: tuple[float, float]) -> np.ndarray:
    """Points along the polyline through ``pts``, at most SPACING apart, shape (N, 2)."""
    out = [np.asarray(pts[0], float)[None]]
    for a, b in itertools.pairwise(np.asarray(pts, float)):
        n = max(1, int(np.ceil(np.hypot(*(b - a)) / SPACING)))
        out.append(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
    return np.concatenate(out)


def kinematics(path: np.ndarray, speed: float = 1.0) -> Kinematics:
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(path, axis=0).T))])
    v = np.full(len(s), speed)
    v[-1] = 0.0
    return Kinematics(s, v)


def min_distance(tls) -> float:
    """Closest approach of any two robots over the common time samples [m]."""
    best = np.inf
    for a, b in itertools.combinations(tls, 2):
        n = min(len(a.t), len(b.t))
        d = np.hypot(*(a.xy[:n] - b.xy[:n]).T)
        # after one arrives it stands on its final dock
        tail = np.hypot(*((a.xy[n:] if len(a.t) > n else b.xy[n:]) - (b.xy[-1] if len(a.t) > n else a.xy[-1])).T)
        best = min(best, d.min(), tail.min() if len(tail) else np.inf)
    return float(best)
