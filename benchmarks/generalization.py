"""Do the validation verdicts hold on worlds nobody tuned them on? Validate N random honest worlds.

Draws N worlds (``pefsim.worlds``: declared sensor and robot = the simulated ones, redrawn
until every task plans), sweeps each (``pefsim.sweep``, R runs) and validates it
(``pefsim.validate`` at the family alpha), then prints per check:

- the worlds it applies to, passed, failed;
- for a statistical check, the false alarms the stated alpha allows: each world's check has
  false-alarm probability ``alpha / m`` (m = the statistical checks that apply there), so the
  count of failures over independent worlds is Poisson-binomial: its mean ``sum alpha_i``, its
  95 % upper count, and the one-sided p-value ``P(X >= observed)``
  (``scipy.stats.poisson_binom``; the binomial when the alphas are equal);
- a deterministic check (containment, promise, bound: alpha 0) cannot fail by chance: every
  failure under bounded (uniform) noise is a defect, listed apart.

Then the failing worlds, each with the failing check's detail and what was drawn.

    python -m benchmarks.generalization --worlds 6 --runs 20 --workers 1 --seed 1

``--out DIR`` keeps the worlds' TOML files and sweeps there; by default they go to a temporary
directory removed at the end. ``--resume`` (with ``--out``) reads back the worlds already drawn
there and completes their sweeps (``pefsim.sweep(resume=True)``): a benchmark cut short goes on
where it stopped. A sweep resumed on a different code version mixes runs of both; say so when
quoting its table. ``--noise uniform`` (or ``gaussian``) sweeps only the worlds drawn with that
noise: the bounded worlds alone decide the deterministic checks (containment, promise, bound).
"""

from __future__ import annotations

import argparse
import re
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy import stats

import pefsim
import scenarios
from planner.worlds import PlannedWorld


def false_alarm_row(alphas: list[float], failed: int) -> tuple[float, int, float]:
    """Return the expected false alarms, their 95 % upper count and the p-value ``P(X >= failed)``.

    Parameters
    ----------
    alphas : list of float
        Per-world false-alarm probability of the check (worlds where it applies).
    failed : int
        Observed failures.
    """
    if not alphas:
        return 0.0, 0, 1.0
    dist = stats.poisson_binom(np.asarray(alphas, float))
    return float(np.sum(alphas)), int(dist.ppf(0.95)), float(dist.sf(failed - 1))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", type=int, default=6, help="number of random worlds")
    ap.add_argument("--runs", type=int, default=20, help="Monte-Carlo runs per world")
    ap.add_argument("--workers", type=int, default=1, help="worker processes drawing the worlds, and per sweep")
    ap.add_argument("--seed", type=int, default=1, help="root seed of the worlds")
    ap.add_argument("--first", type=int, default=0, help="index of the first world (then first + 1, ...)")
    ap.add_argument("--alpha", type=float, default=0.01, help="family false-alarm probability per world")
    ap.add_argument("--out", help="keep the worlds and sweeps in this directory")
    ap.add_argument("--resume", action="store_true",
                    help="read back the worlds drawn into --out and complete their sweeps")
    ap.add_argument("--noise", choices=[m.value for m in scenarios.NoiseModel],
                    help="sweep only the worlds drawn with this noise model")
    args = ap.parse_args()
    if args.resume and not args.out:
        ap.error("--resume needs --out")

    tmp = None if args.out else tempfile.TemporaryDirectory(prefix="pefsim-generalization-")
    root = Path(args.out) if args.out else Path(tmp.name)
    try:
        run(args, root)
    finally:
        if tmp is not None:
            tmp.cleanup()


def drawn_world(path: Path) -> PlannedWorld:
    """Return the world ``pefsim.worlds`` wrote to ``path``: its header says attempts and summary."""
    text = path.read_text(encoding="utf-8")
    header = [line for line in text.splitlines() if line.startswith("#")]
    attempts = int(re.search(r"draw (\d+)", header[0]).group(1))
    summary = tuple(line.removeprefix("#   ") for line in header[1:])
    return PlannedWorld(name=path.stem, text=text, scenario=scenarios.loads(text, source=path.name),
                        attempts=attempts, summary=summary, path=path)


def run(args: argparse.Namespace, root: Path) -> None:
    t0 = time.perf_counter()
    paths = [root / f"random-{args.seed}-{i:03d}.toml" for i in range(args.first, args.first + args.worlds)]
    if args.resume and all(p.is_file() for p in paths):
        worlds = [drawn_world(p) for p in paths]
    else:
        worlds = pefsim.worlds(args.worlds, seed=args.seed, out=root, first=args.first, workers=args.workers)
    t_draw = time.perf_counter() - t0
    print(f"drew {len(worlds)} worlds in {t_draw:.1f} s ({sum(w.attempts for w in worlds)} draws)")
    if args.noise is not None:
        worlds = [w for w in worlds if w.scenario.sensor.noise.value == args.noise]
        print(f"{len(worlds)} of them with {args.noise} noise")
    reports = []
    for w in worlds:
        t = time.perf_counter()
        sweep_dir = pefsim.sweep(w.scenario, root / w.name, runs=args.runs, workers=args.workers, report=False,
                                 resume=args.resume and (root / w.name).is_dir())
        rep = pefsim.validate(sweep_dir, alpha=args.alpha)
        reports.append((w, rep))
        verdicts = " ".join(f"{c.name}={c.status.value}" for c in rep.checks)
        print(f"{w.name}: {rep.fixes} fixes, {time.perf_counter() - t:.0f} s: {verdicts}", flush=True)

    names = [c.name for c in reports[0][1].checks] if reports else []
    print()
    print(f"{len(reports)} worlds x {args.runs} runs, family alpha {args.alpha:g} per world")
    print(f"{'check':<12} {'applies':>7} {'passed':>6} {'failed':>6} {'E[false alarms]':>16} "
          f"{'95% upper':>9} {'p(X>=failed)':>12}")
    defects = []
    for name in names:
        rows = [(w, rep.check(name)) for w, rep in reports]
        applies = [(w, c) for w, c in rows if c.status.value != "not applicable"]
        failed = [(w, c) for w, c in applies if c.status.value == "FAIL"]
        statistical = any(c.alpha for _, c in applies)
        if statistical:
            expected, upper, p = false_alarm_row([c.alpha or 0.0 for _, c in applies], len(failed))
            tail = f"{expected:16.3f} {upper:9d} {p:12.3g}"
        else:
            tail = f"{'0 (deterministic)':>16} {0:9d} {'-':>12}"
            defects += [(w, c) for w, c in failed if w.scenario.sensor.noise.value == "uniform"]
        print(f"{name:<12} {len(applies):7d} {len(applies) - len(failed):6d} {len(failed):6d} {tail}")

    print()
    print(f"defects (a deterministic check failed under bounded noise): {len(defects)}")
    for w, c in defects:
        print(f"  {w.name} {c.name}: {c.statistic} ({c.detail})")
    print()
    print("failing worlds:")
    for w, rep in reports:
        bad = [c for c in rep.checks if c.status.value == "FAIL"]
        if not bad:
            continue
        print(f"  {w.name}: " + "; ".join(w.summary[:3]) + f"; {w.summary[5]}")
        for c in bad:
            print(f"    {c.name}: {c.statistic} against {c.acceptance}: {c.detail}")
    print(f"\ntotal {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
