"""Snapshot-fix speed: the two-range closed form against the shapely path, on an episode's fixes.

Records the arguments of every ``snapshot_fix`` call of ``run_episode(warehouse, 0, seed=1)``
(about 200 two-range fixes), then replays them, measuring in the same run and interleaved:

- ``exact_fault_area`` (closed form where it applies) against ``fault_area._general`` (the
  windowed shapely construction, which every fix took before) on the fixes' own inputs;
- ``solve_position`` (compiled ranges-only Gauss-Newton) against ``lsq._gauss_newton`` (numpy);
- ``snapshot_fix`` as a whole (target: <= 100 us per call).

Times are per call, the best of ``--repeat`` passes over all fixes. The ratios are new / old.

Run: ``python benchmarks/fault_area.py [--repeat N]``. The last line is one JSON object.
"""

from __future__ import annotations

import argparse
import inspect
import json
import time

import numpy as np  # noqa: E402

import scenarios  # noqa: E402
import sim.episode.drive  # noqa: E402
import sim.episode.fixes  # noqa: E402
from estimators import lsq  # noqa: E402
from estimators.fault import exact as fault_area  # noqa: E402
from estimators.fault.annuli import two_annuli_region  # noqa: E402
from estimators.measurements import range_std  # noqa: E402
from estimators.snapshot import snapshot_fix  # noqa: E402


def record_fixes(name: str = "warehouse") -> list[tuple[tuple, dict]]:
    """Run one episode and return the (args, kwargs) of each snapshot_fix call."""
    calls = []

    def recording(*args, **kwargs):
        calls.append((args, kwargs))
        return snapshot_fix(*args, **kwargs)

    original = sim.episode.fixes.snapshot_fix
    sim.episode.fixes.snapshot_fix = recording
    try:
        sim.episode.drive.run_episode(scenarios.load(name), 0, seed=1)
    finally:
        sim.episode.fixes.snapshot_fix = original
    if not calls:
        raise SystemExit("benchmark: the episode made no snapshot fixes (did fix_recorder change?)")
    return calls


def per_call(fn, items) -> float:
    """Wall time per item of one pass [s]."""
    t0 = time.perf_counter()
    for args, kwargs in items:
        fn(*args, **kwargs)
    return (time.perf_counter() - t0) / len(items)


def main() -> None:
    """Record, replay, print a table and the JSON line."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=15)
    opts = ap.parse_args()
    calls = record_fixes()
    fixes = [snapshot_fix(*a, **k) for a, k in calls]
    # the fault-area and least-squares calls each snapshot_fix makes
    fa_new, fa_old, ls_new, ls_old, closed = [], [], [], [], 0
    signature = inspect.signature(snapshot_fix)
    for (args, kwargs), fix in zip(calls, fixes, strict=True):
        kw = signature.bind(*args, **kwargs).arguments
        markers, meas, rho = (np.asarray(kw[v], dtype=float) for v in ("markers", "ranges", "rho"))
        if kw.get("bearings") is not None:
            continue
        rho_fa = rho + kw["fault_margin"] if kw.get("fault_margin") is not None else rho
        tol = fault_area.DEFAULT_TOLERANCE_FRACTION * float(rho_fa.min())
        fa_new.append(((markers, meas, rho_fa, fix.position), {}))
        fa_old.append(((markers, meas, rho_fa, fix.position, None, 0.0, tol), {}))
        closed += two_annuli_region(markers, meas, rho_fa, fix.position, tol) is not None
        std = rho * range_std(1.0, kw["noise"])
        if kw.get("extra_var") is not None:
            std = np.sqrt(std**2 + kw["extra_var"])
        ls_new.append(((markers, meas, std, kw["prior"]), {}))
        ls_old.append(((markers, meas, 1.0 / std, np.array(kw["prior"], dtype=float), None, 20, 1e-10), {}))
    cases = {
        "snapshot_fix": (snapshot_fix, calls),
        "fault_area_new": (fault_area.exact_fault_area, fa_new),
        "fault_area_shapely": (fault_area._general, fa_old),
        "lsq_compiled": (lsq.solve_position, ls_new),
        "lsq_numpy": (lsq._gauss_newton, ls_old),
    }
    best = dict.fromkeys(cases, float("inf"))
    for _ in range(opts.repeat):
        for key, (fn, items) in cases.items():
            best[key] = min(best[key], per_call(fn, items))
    us = {key: round(v * 1e6, 2) for key, v in best.items()}
    out = {
        "fixes": len(calls), "ranges_only": len(fa_new), "closed_form": closed,
        **{f"{key}_us": v for key, v in us.items()},
        "fault_area_ratio": round(best["fault_area_new"] / best["fault_area_shapely"], 4),
        "lsq_ratio": round(best["lsq_compiled"] / best["lsq_numpy"], 4),
        "snapshot_fix_target_us": 100.0,
    }
    w = max(map(len, out))
    for k, v in out.items():
        print(f"{k:<{w}}  {v}")
    print(json.dumps(out))


if __name__ == "__main__":
    main()
