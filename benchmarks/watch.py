"""``pefsim watch``: warm update latency on the 120 x 80 m hall at 5 cm (3.84 M cells). Target <= 0.5 s.

Run: ``python benchmarks/watch.py [--repeat N]``. The hall (``benchmarks/hall_scenario.py``, 286
reflectors, 81 route segments, one task) is written at ``planning.resolution = 0.05`` into a
temporary folder, and the recording goes to a temporary ``.rrd`` (nothing is written elsewhere).
In process, as ``pefsim watch`` does it: a first view (numba kernels loaded or compiled), then
``--repeat`` edits (default 5) that each move one rack-face reflector by 1 m and back. Each warm
update is timed as ``pefsim watch`` reports it: the view (load, PEF map, route segments, logged:
the ``updated in`` time, against the target) and the plans that follow it (plan, logged: the
``planned in`` time), and by phase, with the process's CPU time beside; the baseline, measured
in the same run, is the same update with a fresh :class:`ViewBuilder` (the whole map computed
again, as a re-run of the commands would), plans included. The last line is one JSON object.
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

    from interop.recording import close
    from interop.recording.live import log_plans, log_view, open_live
    from interop.watch.view import ViewBuilder
    from scenarios import load

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "hall.toml"
        text = _hall_toml(args.resolution)
        old = next(line for line in text.splitlines() if line.startswith("position = [6.9, 17.6]"))
        moved = text.replace(old, "position = [6.9, 18.6]", 1)
        assert moved != text
        path.write_text(text)
        rec = open_live("hall.toml", save=Path(tmp) / "watch.rrd")
        builder, contours = ViewBuilder(), {}
        t0 = time.perf_counter()
        view = builder.build(load(path))
        log_view(rec, 0, view.scenario, view.pef_map, view.reports, view.plans, view.unplanned, view.summary(),
                 contours=contours)
        first = time.perf_counter() - t0
        print(f"first view: {first:.2f} s ({view.summary()}, {view.pef_map.tau.size / 1e6:.2f} M cells)")

        warm, planned, base, cpu, cpu_planned = [], [], [], [], []
        phases = {"load": [], "map": [], "routes": [], "log": [], "plans": [], "log_plans": []}
        for i in range(args.repeat):
            path.write_text(moved if i % 2 == 0 else text)
            t0, c0 = time.perf_counter(), time.process_time()
            sc = load(path)
            t1 = time.perf_counter()
            view = builder.build_map(sc)
            t2 = time.perf_counter()
            log_view(rec, i + 1, view.scenario, view.pef_map, view.reports, None, {}, view.summary(),
                     contours=contours)
            t3, c3 = time.perf_counter(), time.process_time()
            view = builder.plan(view)
            t4 = time.perf_counter()
            log_plans(rec, i + 1, view.scenario, view.plans, view.unplanned, view.summary())
            t5, c5 = time.perf_counter(), time.process_time()
            warm.append(t3 - t0)
            cpu.append(c3 - c0)
            cpu_planned.append(c5 - c0)
            planned.append(t5 - t0)
            phases["load"].append(t1 - t0)
            for k in ("map", "routes", "plans"):
                phases[k].append(view.seconds[k])
            phases["log"].append(t3 - t2)
            phases["log_plans"].append(t5 - t4)
            assert view.map_work == "window", view.map_work
            # baseline: the same update with nothing reused
            t6 = time.perf_counter()
            fresh = ViewBuilder().build(load(path))
            log_view(rec, i + 1, fresh.scenario, fresh.pef_map, fresh.reports, fresh.plans, fresh.unplanned,
                     fresh.summary())
            base.append(time.perf_counter() - t6)
            assert np.array_equal(fresh.pef_map.tau, view.pef_map.tau), "the window's map differs from a whole map"
            assert np.array_equal(fresh.pef_map.best, view.pef_map.best)
            assert [p.chosen if p else None for p in fresh.plans] == [p.chosen if p else None for p in view.plans]
            builder = ViewBuilder()  # the fresh builder holds the state the next edit starts from
            builder.build(load(path))  # (the contour cache holds this map already: the warm view's, equal)
        close(rec)

    med = {k: statistics.median(v) for k, v in phases.items()}
    w, pl, b = statistics.median(warm), statistics.median(planned), statistics.median(base)
    print(f"warm update (one reflector moved 1 m), view shown: median {w:.3f} s over {args.repeat} "
          f"(target <= 0.5 s): {'ok' if w <= 0.5 else 'MISSED'}; plans shown after: median {pl:.3f} s")
    print(f"  CPU of the process (all threads; the machine may be shared): view {statistics.median(cpu):.3f} s, "
          f"with the plans {statistics.median(cpu_planned):.3f} s")
    print("  by phase (median): " + ", ".join(f"{k} {v:.3f} s" for k, v in med.items()))
    print(f"baseline (whole map and plans, nothing reused): median {b:.3f} s; view / baseline = {w / b:.2f}, "
          f"plans / baseline = {pl / b:.2f}")
    print(json.dumps({"cells": int(view.pef_map.tau.size), "first_s": first, "warm_s": w, "warm_all_s": warm,
                      "planned_s": pl, "planned_all_s": planned,
                      "cpu_s": statistics.median(cpu), "cpu_planned_s": statistics.median(cpu_planned),
                      "baseline_s": b, "ratio": w / b,
                      "planned_ratio": pl / b, "phases_s": med, "target_s": 0.5, "met": w <= 0.5}))


if __name__ == "__main__":
    main()
