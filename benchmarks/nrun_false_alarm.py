"""Empirical false-alarm and power of the filter-consistency checks on synthetic Kalman runs.

Replicates sweeps of the linear Kalman filter of ``tests/estimators/synthetic_kf.py`` (time
correlation like a warehouse run: 3000 steps, a fix every 20) and counts how often each check
fails, for the consistent filter (c = 1: the false-alarm rate) and for covariances 5 % off
(c = 0.95 overconfident, 1.05 pessimistic: the power).

    PYTHONPATH=. python benchmarks/nrun_false_alarm.py --runs 200 --replicates 200

Each check is run at the per-check alpha of ``pefsim validate`` (0.01 over 6 checks) and at
0.05 (so that a false-alarm rate can be resolved with a few hundred replicates). ``naive`` is
the unthinned fraction test (every step a Bernoulli trial), shown as the negative control.
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy import stats

from estimators import nrun
from estimators.consistency import chi2_interval
from tests.estimators import synthetic_kf as kf

ALPHAS = (0.01 / 6, 0.05)
SCALES = (1.0, 0.95, 1.05)
CHECKS = ("nees", "nis", "nees_nrun", "nis_nrun", "naive_nees_nrun")


def verdicts(sweep: kf.Sweep, c: float, alpha: float) -> dict[str, bool]:
    """Return check -> failed for one sweep whose covariances are c times the true ones."""
    nees, nis, means = sweep.nees / c, sweep.nis / c, sweep.run_mean_nees / c
    finite = np.isfinite(nis)
    lo, hi = chi2_interval(1, int(2 * finite.sum()), alpha)
    pooled_nis = nis[finite].sum() / (2 * finite.sum())
    thinned = nrun.nees_fraction_test(nees, 3, alpha)
    naive = nrun.fraction_outside_band(nees, np.full(nees.shape, 3.0), alpha)
    return {"nees": not nrun.pooled_nees_test(means, 3, alpha).result.passed,
            "nis": not lo <= pooled_nis <= hi,
            "nees_nrun": not thinned.passed,
            "nis_nrun": not nrun.fraction_outside_band(nis, np.full(nis.shape, 2.0), alpha).passed,
            "naive_nees_nrun": not naive.passed}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--replicates", type=int, default=200)
    ap.add_argument("--seed", type=int, default=2024)
    ap.add_argument("--batch", type=int, default=2000, help="runs simulated at once")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    per_batch = max(1, args.batch // args.runs)
    fails = {(a, c, k): 0 for a in ALPHAS for c in SCALES for k in CHECKS}
    spacings = []
    done = 0
    while done < args.replicates:
        m = min(per_batch, args.replicates - done)
        big = kf.simulate(m * args.runs, rng)
        for r in range(m):
            rows = slice(r * args.runs, (r + 1) * args.runs)
            sweep = kf.Sweep(big.nees[rows], big.nis[rows], big.run_mean_nees[rows])
            for a in ALPHAS:
                for c in SCALES:
                    for k, failed in verdicts(sweep, c, a).items():
                        fails[a, c, k] += failed
            spacings.append(nrun.nees_fraction_test(sweep.nees, 3, 0.05).spacing)
        done += m
    print(f"N = {args.runs} runs, {args.replicates} replicate sweeps, seed {args.seed}; thinning spacing "
          f"{min(spacings)}-{max(spacings)} steps (median {int(np.median(spacings))})")
    for a in ALPHAS:
        print(f"alpha {a:.4g}: failure rate (95 % Clopper-Pearson)")
        for k in CHECKS:
            cells = []
            for c in SCALES:
                f = fails[a, c, k]
                lo = stats.beta.ppf(0.025, f, args.replicates - f + 1) if f else 0.0
                hi = stats.beta.isf(0.025, f + 1, args.replicates - f) if f < args.replicates else 1.0
                cells.append(f"c={c:g}: {f / args.replicates:.3f} [{lo:.3f}, {hi:.3f}]")
            print(f"  {k:16s} " + "  ".join(cells))


if __name__ == "__main__":
    main()
