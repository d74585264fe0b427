"""Plan a route, look at its measurement schedule, and drive it once with a recording.

    python examples/plan_and_drive.py [OUT_DIR]

Writes ``OUT_DIR/episode.rrd`` (open it with ``rerun OUT_DIR/episode.rrd``) and the TUM
trajectories ``OUT_DIR/groundtruth.txt`` and ``OUT_DIR/estimate.txt``; OUT_DIR defaults to
``plan-and-drive``.
"""

import sys
from pathlib import Path

import numpy as np

import pefsim

out = Path(sys.argv[1] if len(sys.argv) > 1 else "plan-and-drive")
out.mkdir(parents=True, exist_ok=True)

sc = pefsim.load("paper-docks")
plan = pefsim.plan(sc)
chosen = plan.candidates[plan.chosen]
print(f"{sc.name}: route {chosen.id} via {'-'.join(chosen.nodes or [])}, {chosen.length:.1f} m in {chosen.time:.1f} s")
print(f"  why: {plan.reason}")
fixes = plan.schedule.fixes
promise = np.array([f.predicted_tau for f in fixes])
print(f"  {len(fixes)} fixes; the largest promise {promise.max() * 1e3:.2f} mm against eps_max "
      f"{sc.planning.eps_max * 1e3:g} mm; {sum(f.slowed for f in fixes)} slowed down")

result = pefsim.run_episode(sc, seed=3, rrd=out / "episode.rrd", tum=out)
s, fx = result.summary, result.fixes
ratio = fx.fault_diameter / fx.predicted_tau
print(f"episode: reached {s['reached']}, rmse {s['rmse'] * 1e3:.2f} mm, max error {s['max_error'] * 1e3:.2f} mm")
print(f"  {len(fx.t)} fixes: truth inside the realised fault area at {fx.contained.mean():.0%}, "
      f"realised / promised diameter at most {np.nanmax(ratio):.3f}")
print(f"wrote {out / 'episode.rrd'}, {out / 'groundtruth.txt'}, {out / 'estimate.txt'}")
