"""``pefsim watch``: warm update latency on the 120 x 80 m hall at 5 cm (3.84 M cells). Target <= 0.5 s.

Run: ``python benchmarks/watch.py [--repeat N]``. The hall (``benchmarks/hall_scenario.py``, 286
reflectors, 81 route segments, one task) is written at ``planning.resolution = 0.05`` into a
temporary folder, and the recording goes to a temporary ``.rrd`` (nothing is written elsewhere).
In process, as ``pefsim watch`` does it: a first view (numba kernels loaded or compiled), then
``--repeat`` edits (default 5) that each move one rack-face reflector by 1 m and back. Each warm
update is timed as a whole (load, PEF map, route segments, plan, logging) and by phase; the
baseline, measured in the same run, is the same update with a fresh :class:`ViewBuilder` (the
whole map computed again, as a re-run of the commands would). The last line is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != HERE]  # benchmarks/planner.py would shadow planner
sys.path.insert(0, str(HERE.parent))


def _hall_toml(resolution: float) -> str:
    import importlib.util

    spec = importlib.util.spec_from_file_location("hall_scenario", HERE / "hall_scenario.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.hall_toml(resolution=resolution)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--resolution", type=float, default=0.05)
    args = ap.parse_args()

    import numpy as np

    from scenarios import load
    from sim.recording import close
    from sim.recording.live import log_view, open_live
    from sim.watch.view import ViewBuilder

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "hall.toml"
        text = _hall_toml(args.resolution)
        old = next(line for line in text.splitlines() if line.startswith("position = [6.9, 17.6]"))
        moved = text.replace(old, "position = [6.9, 18.6]", 1)
        assert moved != text
        path.write_text(text)
        rec = open_live("hall.toml", save=Path(tmp) / "watch.rrd")
        builder = ViewBuilder()
        t0 = time.perf_counter()
        view = builder.build(load(path))
        log_view(rec, 0, view.scenario, view.pef_map, view.reports, view.plans, view.unplanned, view.summary())
        first = time.perf_counter() - t0
        print(f"first view: {first:.2f} s ({view.summary()}, {view.pef_map.tau.size / 1e6:.2f} M cells)")

        warm, base, phases = [], [], {"load": [], "map": [], "routes": [], "plans": [], "log": []}
        for i in range(args.repeat):
            path.write_text(moved if i % 2 == 0 else text)
            t0 = time.perf_counter()
            sc = load(path)
            t1 = time.perf_counter()
            view = builder.build(sc)
            t2 = time.perf_counter()
            log_view(rec, i + 1, view.scenario, view.pef_map, view.reports, view.plans, view.unplanned, view.summary())
            t3 = time.perf_counter()
            warm.append(t3 - t0)
            phases["load"].append(t1 - t0)
            for k in ("map", "routes", "plans"):
                phases[k].append(view.seconds[k])
            phases["log"].append(t3 - t2)
            assert view.map_work == "window", view.map_work
            # baseline: the same update with nothing reused
            t4 = time.perf_counter()
            fresh = ViewBuilder().build(load(path))
            log_view(rec, i + 1, fresh.scenario, fresh.pef_map, fresh.reports, fresh.plans, fresh.unplanned,
                     fresh.summary())
            base.append(time.perf_counter() - t4)
            assert np.array_equal(fresh.pef_map.tau, view.pef_map.tau), "the window's map differs from a whole map"
            assert np.array_equal(fresh.pef_map.best, view.pef_map.best)
            builder = ViewBuilder()  # the fresh builder holds the state the next edit starts from
            builder.build(load(path))
        close(rec)

    med = {k: statistics.median(v) for k, v in phases.items()}
    w, b = statistics.median(warm), statistics.median(base)
    print(f"warm update (one reflector moved 1 m): median {w:.3f} s over {args.repeat} "
          f"(target <= 0.5 s): {'ok' if w <= 0.5 else 'MISSED'}")
    print("  by phase (median): " + ", ".join(f"{k} {v:.3f} s" for k, v in med.items()))
    print(f"baseline (whole map, nothing reused): median {b:.3f} s; warm / baseline = {w / b:.2f}")
    print(json.dumps({"cells": int(view.pef_map.tau.size), "first_s": first, "warm_s": w, "warm_all_s": warm,
                      "baseline_s": b, "ratio": w / b, "phases_s": med, "target_s": 0.5, "met": w <= 0.5}))


if __name__ == "__main__":
    main()
