"""The ``blocking`` check: the plan's predicted robot blocking against what a fleet's episodes saw.

Each fix of a fleet sweep carries the plan's probability that another robot hides at least one
of the scheduled fix's markers at its start (fixes column ``p_block_robot``,
:attr:`planner.fleet.exposure.RobotBlocking.p_fix`) and what happened (``blocked_by_robot_count``
> 0: the simulation found a scheduled line of sight hidden by a robot's body).

**Design.** The fixes are binned by predicted probability (:data:`EDGES`). In bin b the observed
count S_b of blocked fixes is compared with its expectation E_b = sum of p (what the fixes would
give if each were a Bernoulli trial of its predicted probability). Fixes of one run are not
independent (one robot late hides a reflector at several fixes in a row, and every robot of a run
shares the episode), but runs are. So:

* a bin with at least :data:`MIN_EXPECTED` expected blocked and unblocked fixes is judged by
  ``z_b = (S_b - E_b) / sqrt(V_b)``, V_b the larger of two variances of S_b. One is estimated from
  the runs' totals (``sum_r (D_r - mean D)^2 * R / (R - 1)`` with D_r run r's observed minus
  expected count in the bin, R runs: the cluster-robust variance of a sum over independent runs).
  The other is what the prediction itself allows when the uncertainty it expresses is not drawn
  anew in each run: the simulated robots are nearly deterministic (their lag varies by 0.01 s
  over seeds, :data:`planner.fleet.blocking.TIMING`), and most of the spread the model states is
  its own error, the same in every run. So the rows of one scheduled fix (one robot's rows of the
  same predicted probability, a property of the plan) are taken as fully dependent, different
  fixes as independent: ``sum_f (sum_{rows of f} sqrt(p (1 - p)))^2`` (Cauchy-Schwarz, whatever
  the dependence within a fix). S_b is then near normal by the central limit theorem over runs
  and over fixes, and the bin fails when ``|z_b| > Phi^-1(1 - a / 2)``;
* a bin with fewer expected blocked fixes (predictions near 0) fails when it saw too many: by
  Markov's inequality, which holds whatever the dependence, ``P(S_b >= s) <= E_b / s``, so it
  fails when ``S_b >= max(1, E_b / a)``; likewise a bin with fewer expected *unblocked* fixes
  (predictions near 1) fails when ``n_b - S_b >= max(1, (n_b - E_b) / a)``. (A too-few-blocks
  verdict is out of reach there: too few events are expected for any.)

``a = alpha / m`` over the m tests made (Bonferroni: family false-alarm probability <= alpha).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.stats import norm

from validation.data import CheckResult, CheckStatus, SweepData

EDGES = (0.0, 0.02, 0.1, 0.3, 0.7, 0.9, 0.98, 1.0)
"""Bin edges of the predicted probability: fine near 0 and 1, where most fixes are."""
MIN_EXPECTED = 5.0
"""Fewest expected blocked (and unblocked) fixes of a bin for the normal test; fewer: the Markov bound."""


def blocking_why_not(data: SweepData) -> str | None:
    """Return why the check does not apply (no predicted or observed robot blocking), or None."""
    fx = data.fixes
    if fx.p_block_robot is None or fx.robot_blocked is None:
        return ("the fixes table has no predicted robot blocking (p_block_robot) and observed blocking "
                "(blocked_by_robot_count): not a fleet sweep")
    if not np.isfinite(fx.p_block_robot).any():
        return "no fix has a predicted robot blocking probability"
    return None


def _bins(p: np.ndarray) -> list[np.ndarray]:
    """Group the fixes by bin of :data:`EDGES` (non-empty bins only)."""
    which = np.clip(np.searchsorted(EDGES, p, side="right") - 1, 0, len(EDGES) - 2)
    groups = [np.flatnonzero(which == b) for b in range(len(EDGES) - 1)]
    return [g for g in groups if len(g)]


def _tests(p: np.ndarray, groups: list[np.ndarray]) -> list[str]:
    """Choose the test of each bin: ``normal``, or the Markov bound on too many ``blocked`` and/or ``unblocked``."""
    kinds = []
    for g in groups:
        e = float(p[g].sum())
        few_blocked, few_clear = e < MIN_EXPECTED, len(g) - e < MIN_EXPECTED
        kinds.append("normal" if not (few_blocked or few_clear) else
                     "+".join(k for k, on in (("blocked", few_blocked), ("unblocked", few_clear)) if on))
    return kinds


def _runs_of(data: SweepData) -> np.ndarray:
    """Return the run of each fix (a fleet's tables number each robot of each run as a unit, ``run * n + robot``)."""
    n = max(len(data.scenario.robots), 1)
    return np.asarray(data.fixes.run, dtype=np.int64) // n


def blocking(data: SweepData, alpha: float, rng: np.random.Generator) -> CheckResult:
    """Compare the predicted robot blocking of the fixes with the observed, bin by bin (module docstring)."""
    fx = data.fixes
    ok = np.isfinite(fx.p_block_robot)
    p = np.clip(fx.p_block_robot[ok], 0.0, 1.0)
    obs = np.asarray(fx.robot_blocked, bool)[ok].astype(float)
    runs = np.unique(_runs_of(data)[ok], return_inverse=True)[1]
    robot = np.asarray(fx.run, dtype=np.int64)[ok] % max(len(data.scenario.robots), 1)
    # one scheduled fix: one robot's rows of one predicted probability (the plan's, the same every run)
    # numbered as np.unique(rows (robot, p), axis=0) would, at a tenth of its cost
    p_rank = np.unique(p, return_inverse=True)[1].reshape(-1)
    fix_of = np.unique(robot * (int(p_rank.max(initial=0)) + 1) + p_rank, return_inverse=True)[1].reshape(-1)
    n_runs = int(runs.max(initial=-1)) + 1
    groups = _bins(p)
    kinds = _tests(p, groups)
    m = sum(len(k.split("+")) for k in kinds)
    a = alpha / m
    z_crit = float(norm.ppf(1.0 - a / 2.0))
    rows, worst = [], 0.0
    for g, kind in zip(groups, kinds, strict=True):
        e, s, n = float(p[g].sum()), float(obs[g].sum()), len(g)
        row = {"p_from": float(p[g].min()), "p_to": float(p[g].max()), "fixes": int(n), "expected": e,
               "observed": int(s), "test": kind, "z": None, "failed": False}
        if kind == "normal":
            d = np.bincount(runs[g], weights=obs[g] - p[g], minlength=n_runs)
            v_runs = float(np.sum((d - d.mean()) ** 2) * n_runs / (n_runs - 1)) if n_runs > 1 else 0.0
            sd = np.bincount(fix_of[g], weights=np.sqrt(p[g] * (1.0 - p[g])))
            v = max(v_runs, float(np.sum(sd * sd)))
            z = (s - e) / math.sqrt(v)
            worst = max(worst, abs(z))
            row.update(z=z, failed=abs(z) > z_crit)
        else:
            many_blocked = "blocked" in kind.split("+") and s >= max(1.0, e / a)
            many_clear = "unblocked" in kind.split("+") and n - s >= max(1.0, (n - e) / a)
            row["failed"] = bool(many_blocked or many_clear)
        rows.append(row)
    failed = [r for r in rows if r["failed"]]
    total_e, total_s = float(p.sum()), int(obs.sum())

    def txt(r):
        how = f"z {r['z']:+.2f}" if r["z"] is not None else f"Markov on too many {r['test'].replace('+', '/')}"
        return f"p {r['p_from']:.3g}..{r['p_to']:.3g}: {r['observed']}/{r['expected']:.1f} ({how})"

    detail = (f"fixes with a scheduled line of sight hidden by a robot, observed/expected per bin of the "
              f"predicted probability ({'; '.join(txt(r) for r in rows)}); normal bins: variance the larger of "
              f"the {n_runs} runs' totals' and the prediction's with each scheduled fix's rows dependent; bins "
              f"with < {MIN_EXPECTED:g} expected blocked or unblocked fixes: Markov bound; a = alpha / {m} tests")
    return CheckResult("blocking", CheckStatus.FAIL if failed else CheckStatus.PASS,
                       f"max |z| {worst:.3g}, {len(failed)}/{len(rows)} bins off ({total_s} blocked, "
                       f"{total_e:.1f} expected)",
                       f"|z| <= {z_crit:.3g}; Markov bins under 1/a = {1 / a:.3g} x expected", alpha, detail,
                       {"bins": len(groups), "tests": m, "z_crit": z_crit, "max_abs_z": worst, "observed": total_s,
                        "expected": total_e, "fixes": int(ok.sum()), "runs": n_runs,
                        "failed_bins": len(failed), "per_bin": rows})
