"""Placement's gap for redundancy 1 with flat reflectors: count against its own lower bound.

Run: ``python benchmarks/placement_gap.py``. Floors: two 24 x 12 m corridor-like floors written
here (a loop around a 16 x 4 m block; two parallel 3 m aisles between three rack rows) and the
built-in ``warehouse-reflectors`` (30 x 20 m, three rack rows, columns), all with flat reflectors
and ``planning.redundancy = 1``, covering the routes (``place`` without the planning check).

For each: ``place`` (the redundancy-1 cutting planes and integer rounds, :mod:`planner.placement.cover`)
against the way it was done before, measured in the same run: the exact redundancy-0 cover
completed greedily into a robust one (:func:`planner.placement.redundant.greedy_robust`), whose
lower bound was the redundancy-0 count. Printed: count, bound, count / bound and wall time of
each. The last line is one JSON object.
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np  # noqa: E402

import scenarios  # noqa: E402
from planner.placement import cover, placement, redundant  # noqa: E402
from planner.placement.sites import candidate_sites, cover_points  # noqa: E402

COMMON = """
[sensor]
relative_error = 6.7e-5
absolute_error = 0.002
max_range = 25.0
markers_per_fix = 2
[robot]
radius = 0.4
[planning]
eps_max = 0.03
pef_model = "parallelogram"
resolution = 0.1
redundancy = 1
"""

LOOP = """name = "corridor-loop"
seed = 3
[workspace]
size = [24.0, 12.0]
[[obstacles]]
center = [12.0, 6.0]
size = [16.0, 4.0]
[routes]
nodes = { a = [2.0, 2.0], b = [22.0, 2.0], c = [22.0, 10.0], d = [2.0, 10.0] }
segments = [["a", "b"], ["b", "c"], ["c", "d"], ["d", "a"]]
""" + COMMON

AISLES = """name = "corridor-aisles"
seed = 5
[workspace]
size = [24.0, 12.0]
[[obstacles]]
center = [12.0, 1.5]
size = [18.0, 1.0]
[[obstacles]]
center = [12.0, 6.0]
size = [18.0, 2.0]
[[obstacles]]
center = [12.0, 10.5]
size = [18.0, 1.0]
[routes]
nodes = { a = [1.5, 3.5], b = [22.5, 3.5], c = [1.5, 8.5], d = [22.5, 8.5] }
segments = [["a", "b"], ["c", "d"], ["a", "c"], ["b", "d"]]
""" + COMMON


def before(sc) -> tuple[int, int]:
    """Place as before: exact redundancy-0 cover completed greedily; its bound is the r=0 count."""
    cov, _ = placement.build_cover(sc, cover_points(sc), candidate_sites(sc), sc.planning.eps_max)
    k = sc.sensor.markers_per_fix
    chosen, _, _ = cover.solve_exact(cov, k, integral=True, xy=candidate_sites(sc),
                                     seed=placement._search_seed(sc.seed))
    robust, _ = redundant.greedy_robust(cov, k, 1, chosen)
    return int(robust.sum()), max(int(chosen.sum()), k + 1)


def main() -> int:
    floors = [scenarios.loads(LOOP), scenarios.loads(AISLES), scenarios.load("warehouse-reflectors")]
    placement.place(floors[0], points=cover_points(floors[0])[:40])  # JIT warm-up
    rows = []
    for sc in floors:
        t = time.perf_counter()
        res = placement.place(sc)
        t_now = time.perf_counter() - t
        t = time.perf_counter()
        old_count, old_bound = before(sc)
        t_old = time.perf_counter() - t
        row = {"floor": sc.name, "count": res.count, "bound": res.lower_bound, "ratio": res.count / res.lower_bound,
               "optimal": res.optimal, "time_s": round(t_now, 2), "before_count": old_count,
               "before_bound": old_bound, "before_ratio": old_count / old_bound, "before_time_s": round(t_old, 2),
               "sites": len(res.sites), "points": len(res.points)}
        rows.append(row)
        print(f"{sc.name:22s} count {res.count:3d} bound {res.lower_bound:3d} ({row['ratio']:.2f} x) "
              f"{t_now:6.1f} s | before: count {old_count:3d} bound {old_bound:3d} ({row['before_ratio']:.2f} x) "
              f"{t_old:6.1f} s")
    print(json.dumps({"placement_gap_r1": rows, "worst_ratio": float(np.max([r["ratio"] for r in rows]))}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
