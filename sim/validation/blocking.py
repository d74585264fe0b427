"""The ``blocking`` check: the plan's predicted robot blocking against what a fleet's episodes saw.

Each fix of a fleet sweep carries the plan's probability that another robot hides at least one
of the scheduled fix's markers at its start (fixes column ``p_block_robot``,
:attr:`planner.fleet.exposure.RobotBlocking.p_fix`) and what happened (``blocked_by_robot_count``
> 0: the simulation found a scheduled line of sight hidden by a robot's body).

**Design.** The fixes are binned by predicted probability (:data:`EDGES`). In bin b the observed
count S_b of blocked fixes is compared with its expectation E_b = sum of p (what the fixes would
give if each were a Bernoulli trial of its predicted probability):
``z_b = (S_b - E_b) / sqrt(V_b)``. Fixes of one run are not independent (one robot late hides
a reflector at several fixes in a row, and every robot of a run shares the episode), but runs
are: V_b is the variance of S_b estimated from the runs' totals (``sum_r (D_r - mean D)^2 *
R / (R - 1)`` with ``D_r`` run r's observed minus expected count in the bin, R runs; the
cluster-robust variance of a sum of independent runs), and never less than the variance the
fixes would have if they were independent (``sum p (1 - p)``), so that a bin with few events does
not get a variance of zero. With many runs S_b is near normal (the central limit theorem over
runs): bin b fails when ``|z_b| > z*``, ``z* = Phi^-1(1 - alpha / (2 B))`` over the B bins tested
(Bonferroni: family false-alarm probability <= alpha). A bin with fewer than
:data:`MIN_EXPECTED` expected blocked or unblocked fixes is merged with its neighbour first (the
usual condition for a normal approximation to binomial counts).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.stats import norm

from sim.validation.data import CheckResult, CheckStatus, SweepData

EDGES = (0.0, 0.02, 0.1, 0.3, 0.7, 0.9, 0.98, 1.0)
"""Bin edges of the predicted probability: fine near 0 and 1, where most fixes are."""
MIN_EXPECTED = 5.0
"""Fewest expected blocked (and unblocked) fixes a bin is tested with; fewer: merged with a neighbour."""


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
    """Group the fixes by bin of :data:`EDGES`, merging bins until each has enough expected counts."""
    which = np.clip(np.searchsorted(EDGES, p, side="right") - 1, 0, len(EDGES) - 2)
    groups = [np.flatnonzero(which == b) for b in range(len(EDGES) - 1)]
    groups = [g for g in groups if len(g)]

    def thin(g: np.ndarray) -> bool:
        e = float(p[g].sum())
        return e < MIN_EXPECTED or len(g) - e < MIN_EXPECTED

    while len(groups) > 1:
        bad = [i for i, g in enumerate(groups) if thin(g)]
        if not bad:
            break
        i = bad[0]
        j = i + 1 if i + 1 < len(groups) else i - 1
        lo, hi = min(i, j), max(i, j)
        groups[lo:hi + 1] = [np.sort(np.concatenate([groups[lo], groups[hi]]))]
    return groups


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
    n_runs = int(runs.max(initial=-1)) + 1
    groups = _bins(p)
    z_crit = float(norm.ppf(1.0 - alpha / (2.0 * len(groups))))
    rows, worst = [], 0.0
    for g in groups:
        e, s = float(p[g].sum()), float(obs[g].sum())
        d = np.bincount(runs[g], weights=obs[g] - p[g], minlength=n_runs)
        v_runs = float(np.sum((d - d.mean()) ** 2) * n_runs / (n_runs - 1)) if n_runs > 1 else 0.0
        v_ind = float(np.sum(p[g] * (1.0 - p[g])))
        v = max(v_runs, v_ind)
        z = (s - e) / math.sqrt(v) if v > 0 else (0.0 if s == e else math.copysign(math.inf, s - e))
        worst = max(worst, abs(z))
        rows.append({"p_from": float(p[g].min()), "p_to": float(p[g].max()), "fixes": int(len(g)),
                     "expected": e, "observed": int(s), "z": z if math.isfinite(z) else None})
    failed = [r for r in rows if r["z"] is None or abs(r["z"]) > z_crit]
    total_e, total_s = float(p.sum()), int(obs.sum())
    bins_txt = "; ".join(f"p {r['p_from']:.3g}..{r['p_to']:.3g}: {r['observed']}/{r['expected']:.1f} "
                         f"(z {r['z'] if r['z'] is not None else math.inf:+.2f})" for r in rows)
    detail = (f"fixes with a scheduled line of sight hidden by a robot, observed/expected per bin of the "
              f"predicted probability ({bins_txt}); variance from the {n_runs} runs' totals (fixes of a run "
              f"are dependent), at least the independent fixes'; z* for alpha / (2 x {len(groups)} bins)")
    return CheckResult("blocking", CheckStatus.FAIL if failed else CheckStatus.PASS,
                       f"max |z| {worst:.3g} ({total_s} blocked, {total_e:.1f} expected)",
                       f"|z| <= {z_crit:.3g} in every bin", alpha, detail,
                       {"bins": len(groups), "z_crit": z_crit, "max_abs_z": worst, "observed": total_s,
                        "expected": total_e, "fixes": int(ok.sum()), "runs": n_runs,
                        "failed_bins": len(failed), "per_bin": rows})
