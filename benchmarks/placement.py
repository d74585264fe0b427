"""Marker placement cost: 200 candidate sites x 2000 route samples (target <= 30 s).

Run: ``python benchmarks/placement.py``. The warehouse scenario's walls and rack faces give
200 sites, its route network 2000 samples. Stages: good pairs (visibility + per-pair tau in
the numba kernel), greedy, LP cutting planes (the lower bound), and ``place`` end to end
(above 150 sites it is greedy + LP bound). The baseline, measured in this same run, is the
naive way: one ``PEF.tau_subset`` call per pair over all points, timed on a sample of pairs and
extrapolated to all pairs. The exact solver is also timed on the default warehouse instance
(112 sites). The JIT is warmed up first. The last line is one JSON object.
"""

from __future__ import annotations

import json
import time

import numpy as np  # noqa: E402

import scenarios  # noqa: E402
from planner.pef.map import PEF  # noqa: E402
from planner.placement import cover, placement  # noqa: E402
from planner.placement.sites import candidate_sites, route_points  # noqa: E402

N_SITES, N_POINTS, BASELINE_PAIRS = 200, 2000, 200


def instance():
    """Warehouse sites (exactly N_SITES) and route samples (exactly N_POINTS)."""
    sc = scenarios.load("warehouse")
    sites = candidate_sites(sc, spacing=1.12)
    sites = sites[np.linspace(0, len(sites) - 1, N_SITES).round().astype(int)]
    pts = route_points(sc, step=0.05)
    pts = pts[np.linspace(0, len(pts) - 1, N_POINTS).round().astype(int)]
    return sc, sites, pts


def timed(fn, *args, **kw):
    t = time.perf_counter()
    out = fn(*args, **kw)
    return out, time.perf_counter() - t


def bench_placement() -> dict:
    """Time the placement stages on 200 sites x 2000 points; see the module doc."""
    sc, sites, pts = instance()
    placement.place(sc, points=pts[:50], sites=sites[:12])  # JIT warm-up
    k = sc.sensor.markers_per_fix
    (cov, coverable), t_pairs = timed(placement.build_cover, sc, pts, sites, sc.planning.eps_max)
    greedy, t_greedy = timed(cover.greedy, cov, k)
    (_, lp, _), t_lp = timed(cover.solve_exact, cov, k, integral=False, work=0)  # LP and roundings only
    res, t_place = timed(placement.place, sc, points=pts, sites=sites)

    pef = PEF(placement._site_scenario(sc, sites), k=2)
    rng = np.random.default_rng(3)
    pairs = rng.choice(len(pef.subsets), BASELINE_PAIRS, replace=False)
    _, t_base = timed(lambda: [pef.tau_subset(pts, pef.subsets[p]) for p in pairs])
    t_naive = t_base / BASELINE_PAIRS * len(pef.subsets)

    default = scenarios.load("warehouse")
    exact, t_exact = timed(placement.place, default, method="milp")
    return {
        "sites": len(sites), "points": len(pts), "coverable": int(coverable.sum()),
        "good_pairs": int(len(cov.pj)), "rows": int(len(cov.weight)), "entries": int(len(cov.ep)),
        "pairs_s": t_pairs, "greedy_s": t_greedy, "greedy_count": int(greedy.sum()),
        "lp_s": t_lp, "lp_bound": lp, "place_s": t_place, "count": res.count,
        "lower_bound": res.lower_bound, "method": res.method,
        "naive_pairs_extrapolated_s": t_naive, "pairs_speedup_vs_naive": t_naive / t_pairs,
        "target_s": 30.0, "within_target": t_place <= 30.0,
        "warehouse_exact_s": t_exact, "warehouse_exact_sites": len(exact.sites),
        "warehouse_exact_count": exact.count, "warehouse_exact_optimal": exact.optimal,
    }


def main() -> None:
    r = bench_placement()
    print(f"placement: {r['sites']} sites x {r['points']} route samples "
          f"({r['good_pairs']} good pairs, {r['rows']} distinct rows, {r['entries']} row-pair entries)")
    print(f"  {'good pairs (visibility + tau kernel)':<40} {r['pairs_s']:8.2f} s   naive tau_subset per pair "
          f"{r['naive_pairs_extrapolated_s']:.1f} s extrapolated (x{r['pairs_speedup_vs_naive']:.0f})")
    print(f"  {'greedy':<40} {r['greedy_s']:8.2f} s   {r['greedy_count']} markers")
    print(f"  {'LP cutting planes (lower bound)':<40} {r['lp_s']:8.2f} s   bound {r['lp_bound']:.2f}")
    print(f"  {'place() end to end':<40} {r['place_s']:8.2f} s   {r['count']} markers, lower bound "
          f"{r['lower_bound']} ({r['method']}; target <= {r['target_s']:g} s)")
    print(f"  {'exact on the default warehouse':<40} {r['warehouse_exact_s']:8.2f} s   "
          f"{r['warehouse_exact_sites']} sites: {r['warehouse_exact_count']} markers, "
          f"optimal {r['warehouse_exact_optimal']}")
    print(json.dumps(r))


if __name__ == "__main__":
    main()
