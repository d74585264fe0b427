"""Cold and warm starts of ``pefsim map``, ``plan`` and ``run``, side by side; the last line is JSON.

Run: ``python benchmarks/commands.py [--scenario warehouse] [--repeat 3]``. Each command runs as a
subprocess (``python -m cli ... --json``), measured by ``os.wait4``: wall time and CPU (user +
sys) [s].

- **cold**: numba's cache empty (``NUMBA_CACHE_DIR`` a new temporary folder for that command), as
  on a fresh machine: the command compiles every kernel it calls, and says so once on stderr
  (``compile_said_s``: the seconds it printed);
- **warm**: the same command again ``--repeat`` times with that cache (medians), as every later
  run; it must say nothing on stderr (``warm_quiet``).

Baselines measured in the same run, so that a shared machine's load cancels out in the ratios:
``cold / warm`` per command, and ``pefsim list`` (Python, the command line and the scenario
library, no kernel) as the floor every command pays: ``warm - floor`` is the command's own work.
Nothing is written outside the temporary folders.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

import numpy as np  # noqa: E402

ROOT = HERE.parent
SAID = re.compile(r"pefsim: compiled the kernels once \((\d+) s\)")


def measured(args: list[str], cache: Path) -> dict:
    """Run ``python -m cli ARGS`` with numba's cache in ``cache``: wall [s], CPU [s], exit, stderr."""
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""),
               NUMBA_CACHE_DIR=str(cache))
    with tempfile.TemporaryFile("w+") as fe:
        t0 = time.perf_counter()
        p = subprocess.Popen([sys.executable, "-m", "cli", *args], cwd=cache.parent, env=env,
                             stdout=subprocess.DEVNULL, stderr=fe)
        _, status, ru = os.wait4(p.pid, 0)
        wall = time.perf_counter() - t0
        fe.seek(0)
        return {"wall_s": wall, "cpu_s": ru.ru_utime + ru.ru_stime, "code": os.waitstatus_to_exitcode(status),
                "stderr": fe.read()}


def cold_and_warm(name: str, args: list[str], folder: Path, repeat: int) -> dict:
    """One cold run of ``args`` on an empty numba cache, then ``repeat`` warm ones on the cache it left."""
    cache = folder / f"numba-{name}"
    cold = measured(args, cache)
    warm = [measured(args, cache) for _ in range(max(1, repeat))]
    said = SAID.search(cold["stderr"])
    out = {"code": max([cold["code"]] + [w["code"] for w in warm]),
           "cold_wall_s": cold["wall_s"], "cold_cpu_s": cold["cpu_s"],
           "warm_wall_s": float(np.median([w["wall_s"] for w in warm])),
           "warm_cpu_s": float(np.median([w["cpu_s"] for w in warm])),
           "compile_said_s": int(said.group(1)) if said else None,
           "warm_quiet": all(w["stderr"] == "" for w in warm)}
    out["cold_over_warm_cpu"] = out["cold_cpu_s"] / out["warm_cpu_s"]
    return {f"{name}_{k}": v for k, v in out.items()}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="warehouse", help="built-in scenario or TOML file")
    ap.add_argument("--repeat", type=int, default=3, help="warm runs of each command (medians printed)")
    args = ap.parse_args()
    commands = {"map": ["map", args.scenario, "--json"], "plan": ["plan", args.scenario, "--json"],
                "run": ["run", args.scenario, "--seed", "0", "--json"]}
    r: dict = {"scenario": args.scenario, "repeat": args.repeat, "load_before": os.getloadavg()[0]}
    with tempfile.TemporaryDirectory(prefix="pefsim-bench-") as tmp:
        folder = Path(tmp)
        floor = [measured(["list"], folder / "numba-list") for _ in range(max(1, args.repeat))]
        r["floor_wall_s"] = float(np.median([f["wall_s"] for f in floor]))
        r["floor_cpu_s"] = float(np.median([f["cpu_s"] for f in floor]))
        print(f"floor (pefsim list, median of {args.repeat}): {r['floor_wall_s']:.2f} s wall, "
              f"{r['floor_cpu_s']:.2f} s CPU")
        print(f"{'command':8} {'cold wall':>10} {'cold CPU':>9} {'warm wall':>10} {'warm CPU':>9} "
              f"{'cold/warm CPU':>14} {'warm-floor CPU':>15} {'said':>6}")
        for name, argv in commands.items():
            one = cold_and_warm(name, argv, folder, args.repeat)
            r |= one
            g = {k[len(name) + 1:]: v for k, v in one.items()}
            said = "-" if g["compile_said_s"] is None else f"{g['compile_said_s']} s"
            print(f"{name:8} {g['cold_wall_s']:9.1f}s {g['cold_cpu_s']:8.1f}s {g['warm_wall_s']:9.2f}s "
                  f"{g['warm_cpu_s']:8.2f}s {g['cold_over_warm_cpu']:13.1f}x "
                  f"{g['warm_cpu_s'] - r['floor_cpu_s']:14.2f}s {said:>6}"
                  + ("" if g["code"] == 0 else f"  exit {g['code']}")
                  + ("" if g["warm_quiet"] else "  (a warm run wrote on stderr)"))
    r["load_after"] = os.getloadavg()[0]
    print(json.dumps(r))
    return 0


if __name__ == "__main__":
    sys.exit(main())
