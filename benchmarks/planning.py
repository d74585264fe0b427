"""Planner costs: free-space grid search on a 1000 x 1000 grid, route choice on a 50-segment network.

Run: ``python benchmarks/planning.py [--queries 8]``. The baseline is a pure-Python heapq
A* with the same cost model and heuristic, measured in this same run on a 200 x 200 subgrid
and extrapolated to the full grid per expanded node. Each figure is the best of several
repeats (robust to other load on the machine). The last line is one JSON object.
"""

from __future__ import annotations

import argparse
import dataclasses
import heapq
import importlib.util
import json
import math
import time
from pathlib import Path

import numpy as np  # noqa: E402

import scenarios  # noqa: E402
from planner import plan
from planner.pef.map import PEF  # noqa: E402
from planner.routes import criteria, gridsearch, network, ranking  # noqa: E402
from scenarios.route_network import RouteNetwork  # noqa: E402
from scenarios.schema import Dock, Marker, Obstacle, Task


def hall() -> scenarios.Scenario:
    """Build a 100 x 100 m hall: 4 rows of 6 racks, reflectors on every rack face and on the walls."""
    base = scenarios.load("warehouse")
    centres = [(12.0 + 15.0 * i, 14.0 + 24.0 * j) for i in range(6) for j in range(4)]
    racks = tuple(Obstacle(c, (10.0, 2.0)) for c in centres)
    sites = [(x, y + d) for x, y in centres for d in (-1.0, 1.0)]
    for v in np.arange(10.0, 100.0, 20.0):
        sites += [(v, 0.0), (v, 100.0), (0.0, v), (100.0, v)]
    markers = tuple(Marker(f"M{i}", (float(x), float(y))) for i, (x, y) in enumerate(sites))
    docks = (Dock("A", (3.0, 3.0, 0.0)), Dock("B", (97.0, 97.0, 0.0)))
    return dataclasses.replace(
        base, name="hall", workspace=dataclasses.replace(base.workspace, size=(100.0, 100.0)),
        obstacles=racks, markers=markers, docks=docks, routes=None, tasks=(Task("A", "B"),),
        sensor=dataclasses.replace(base.sensor, max_range=30.0),
        planning=dataclasses.replace(base.planning, eps_max=0.05, resolution=0.1))


def python_astar(cost, allowed, start, goal, hx, hy, cmin):
    """Run the reference A*: heapq, dicts, the same moves, costs and octile heuristic as the numba one."""
    ny, nx = cost.shape
    hd = math.hypot(hx, hy)
    moves = [(-1, 0, hy), (1, 0, hy), (0, -1, hx), (0, 1, hx),
             (-1, -1, hd), (-1, 1, hd), (1, -1, hd), (1, 1, hd)]

    def h(r, c):
        ar, ac = abs(r - goal[0]), abs(c - goal[1])
        m = min(ar, ac)
        return cmin * (hd * m + hy * (ar - m) + hx * (ac - m))

    g = {start: 0.0}
    closed = set()
    heap = [(h(*start), start)]
    expanded = 0
    while heap:
        _, u = heapq.heappop(heap)
        if u in closed:
            continue
        closed.add(u)
        expanded += 1
        if u == goal:
            return g[u], expanded
        r, c = u
        for dr, dc, step in moves:
            rr, cc = r + dr, c + dc
            if not (0 <= rr < ny and 0 <= cc < nx) or not allowed[rr, cc] or (rr, cc) in closed:
                continue
            if dr and dc and not (allowed[r, cc] and allowed[rr, c]):
                continue
            ng = g[u] + step * 0.5 * (cost[r, c] + cost[rr, cc])
            if ng < g.get((rr, cc), math.inf):
                g[(rr, cc)] = ng
                heapq.heappush(heap, (ng + h(rr, cc), (rr, cc)))
    return math.inf, expanded


def best_of(fn, repeat: int = 3):
    best, out = math.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def free_cells_far_apart(allowed: np.ndarray, rng: np.random.Generator, n: int, min_cells: int):
    """Pairs of cells of the largest 4-connected free component (so every query has a path)."""
    from scipy import ndimage

    labels, _ = ndimage.label(allowed)
    biggest = np.argmax(np.bincount(labels.ravel())[1:]) + 1
    free = np.argwhere(labels == biggest)
    idx = rng.integers(len(free), size=(20_000, 2))
    dist = np.hypot(*(free[idx[:, 0]] - free[idx[:, 1]]).T)
    far = np.flatnonzero(dist >= min_cells)
    pick = far[:n] if len(far) >= n else np.argsort(dist)[::-1][:n]
    return [(tuple(int(v) for v in free[i]), tuple(int(v) for v in free[j])) for i, j in idx[pick]]


def bench_grid(n_queries: int, rng: np.random.Generator) -> dict:
    sc = hall()
    t0 = time.perf_counter()
    pm = PEF(sc).grid()
    t_map = time.perf_counter() - t0
    grid = gridsearch.Grid(pm.x, pm.y)
    clear = criteria.clearance(grid.centres().reshape(-1, 2), sc).reshape(grid.shape)
    tau_c = gridsearch.conservative_tau(pm.tau)
    allowed = (clear - math.hypot(grid.hx, grid.hy) / 2 >= sc.robot.radius) & (tau_c < sc.planning.eps_max)
    w = sc.planning.weights.accuracy
    cost = gridsearch.cell_cost(np.where(allowed, tau_c, 0.0), sc.planning.eps_max, w)
    gridsearch.grid_astar(grid, cost, allowed, (0, 0), (0, 0)) if allowed[0, 0] else None  # compile/load
    times, expanded = [], []
    for a, b in free_cells_far_apart(allowed, rng, n_queries, 500):
        t, res = best_of(lambda a=a, b=b: gridsearch.grid_astar(grid, cost, allowed, a, b))
        if res is None:
            continue
        times.append(t)
        expanded.append(res.expanded)
    corners = free_cells_far_apart(allowed, np.random.default_rng(7), 1, 1200)[0]
    t_alt, alts = best_of(lambda: gridsearch.alternatives(grid, tau_c, allowed, sc.planning.eps_max,
                                                          corners[0], corners[1], w, n_routes=4), 2)
    # Baseline on a 200 x 200 subgrid, numba on the same subgrid for a like-for-like ratio.
    sub = (slice(300, 500), slice(300, 500))
    sa, sc_ = allowed[sub].copy(), cost[sub]
    sg = gridsearch.Grid(grid.x[sub[1]], grid.y[sub[0]])
    a, b = free_cells_far_apart(sa, np.random.default_rng(1), 1, 150)[0]
    t_py, (c_py, e_py) = best_of(lambda: python_astar(sc_, sa, a, b, sg.hx, sg.hy, float(sc_[sa].min())), 2)
    t_nb, res_nb = best_of(lambda: gridsearch.grid_astar(sg, sc_, sa, a, b), 5)
    assert res_nb is not None and abs(res_nb.cost - c_py) <= 1e-9 * c_py, (res_nb.cost, c_py)
    py_per_node = t_py / e_py
    return {
        "grid_cells": int(allowed.size), "navigable_fraction": float(allowed.mean()), "pef_grid_s": t_map,
        "query_median_s": float(np.median(times)), "query_max_s": float(np.max(times)),
        "expanded_median": int(np.median(expanded)), "expanded_max": int(np.max(expanded)),
        "python_subgrid_s": t_py, "numba_subgrid_s": t_nb, "subgrid_speedup": t_py / t_nb,
        "python_extrapolated_median_s": py_per_node * float(np.median(expanded)),
        "speedup_vs_python": py_per_node * float(np.median(expanded)) / float(np.median(times)),
        "queries": len(times), "alternatives_4_s": t_alt, "alternatives_found": len(alts),
    }


def network_50(rng: np.random.Generator) -> RouteNetwork:
    """50 segments on the hall's aisles: a 7 x 5 lattice, all 30 rows, 20 of the 28 columns."""
    xs, ys = (3.5, 19.5, 34.5, 49.5, 64.5, 79.5, 95.5), (2.0, 26.0, 50.0, 74.0, 98.0)
    nodes = {f"n{i}{j}": (x, y) for i, x in enumerate(xs) for j, y in enumerate(ys)}
    rows = [(f"n{i}{j}", f"n{i + 1}{j}") for i in range(6) for j in range(5)]
    cols = [(f"n{i}{j}", f"n{i}{j + 1}") for i in range(7) for j in range(4)]
    keep = [c for c in cols if c[0][1] == "0"]  # column 0 keeps every row gap connected
    rest = [c for c in cols if c not in keep]
    keep += [rest[k] for k in rng.choice(len(rest), 20 - len(keep), replace=False)]
    segs = rows + keep
    traffic = {f"{a}-{b}": float(rng.uniform()) for a, b in segs if rng.random() < 0.3}
    return RouteNetwork(nodes=nodes, segments=tuple(segs), traffic=traffic)


def bench_network(rng: np.random.Generator) -> dict:
    net = network_50(rng)
    sc = dataclasses.replace(hall(), routes=net)
    pef = PEF(sc)
    pef.at(np.array([[3.0, 3.0]]))  # compile/load
    t_plan, p = best_of(lambda: plan.plan_route(sc, "A", "B", pef=pef, schedule=False), 2)
    values = np.array([c.vector() for c in p.candidates])
    adm = np.array([c.admissible for c in p.candidates])
    t_rank, _ = best_of(lambda: ranking.rank(values, adm, sc.planning.weights), 20)
    g = network.build_graph(net)
    t_enum, (routes, method) = best_of(lambda: network.candidate_routes(g, "n00", "n64"), 3)
    return {"segments": len(net.segments), "candidates": len(p.candidates), "method": method,
            "admissible": int(adm.sum()), "plan_route_s": t_plan, "enumerate_s": t_enum, "rank_s": t_rank}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--queries", type=int, default=8)
    args = ap.parse_args()
    rng = np.random.default_rng(2024)
    res = {"grid": bench_grid(args.queries, rng), "network": bench_network(rng)}
    placement = Path(__file__).with_name("placement.py")
    if placement.is_file():
        spec = importlib.util.spec_from_file_location("bench_placement_mod", placement)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        res["placement"] = mod.bench_placement()
    g, n = res["grid"], res["network"]
    print(f"{'free-space search, 1000 x 1000 grid':<44} {'':>12}")
    print(f"  {'PEF map (setup)':<42} {g['pef_grid_s']:10.2f} s")
    print(f"  {'A* per query, median / max':<42} {g['query_median_s']:10.3f} s / {g['query_max_s']:.3f} s"
          f"  (target <= 0.2 s; {g['expanded_median']} / {g['expanded_max']} nodes expanded)")
    print(f"  {'pure-Python A*, extrapolated median':<42} {g['python_extrapolated_median_s']:10.2f} s"
          f"  (x{g['speedup_vs_python']:.0f})")
    print(f"  {'4 diverse alternatives, far corners':<42} {g['alternatives_4_s']:10.3f} s"
          f"  ({g['alternatives_found']} routes)")
    print(f"  {'200 x 200 subgrid: Python / numba':<42} {g['python_subgrid_s']:10.3f} s / "
          f"{g['numba_subgrid_s'] * 1000:.2f} ms  (x{g['subgrid_speedup']:.0f})")
    print(f"{'route choice, ' + str(n['segments']) + '-segment network':<44}")
    print(f"  {'plan_route (no schedule)':<42} {n['plan_route_s']:10.2f} s  ({n['candidates']} candidates,"
          f" {n['method']}, {n['admissible']} admissible)")
    print(f"  {'enumerate / rank':<42} {n['enumerate_s'] * 1000:10.2f} ms / {n['rank_s'] * 1000:.3f} ms")
    if "placement" in res:
        print(f"placement: {res['placement']}")
    print(json.dumps(res))


if __name__ == "__main__":
    main()
