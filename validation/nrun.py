"""Filter-consistency checks over the runs of a sweep: pooled NEES and Bar-Shalom's N-run tests.

`docs/design.md` §6: the pooled NEES, and the N-run tests per step (NEES) and per fix (NIS).

The statistics and their false-alarm derivations are in :mod:`estimators.nrun`. In short:

- ``nees``: the grand mean of the runs' time-averaged NEES, against a scaled chi2 whose dof
  comes from the spread between the (independent) runs; this is the check with the power
  to see a covariance a few per cent off;
- ``nees_nrun``: at each step the NEES averaged over the runs that reach it, against the 95 %
  band ``chi2(3 N_k) / N_k``; steps are thinned to a spacing where the NEES autocorrelation
  (estimated across runs) is at most 0.2, so the count outside is binomial, judged one-sided;
- ``nis_nrun``: at each fix index the summed NIS of the runs against its 95 % band (dof = the
  runs' scalar updates at that fix); innovations are white, so every fix index counts.

Runs are aligned by step (fix) index from their start; a step is tested when at least half
the runs reach it. Runs of a sweep may have different lengths (tasks, speeds); the band of
each step uses its own N_k, so the test stays exact, only its power thins at the end.
"""

from __future__ import annotations

import math

import numpy as np

from estimators import nrun
from estimators.consistency import Verdict
from validation.data import EPISODE_GATE_PROBABILITY, CheckResult, CheckStatus, SweepData

NEES_DOF = 3
"""The filter's pose (x, y, theta)."""
MIN_INDEPENDENT_STEPS = 10
"""Fewer thinned steps than this and ``nees_nrun`` does not apply: with so few trials the
binomial can hardly ever reject (at 2 trials, never below alpha = 0.0025), and a check that
cannot fail must not read as a pass. It happens when the NEES stays correlated over most
of a run (a badly mis-tuned filter: the pooled ``nees`` sees that one)."""


def _fmt(x: float) -> str:
    return f"{x:.4g}" if math.isfinite(x) else str(x)


def _side(verdict: Verdict) -> str:
    return {Verdict.ABOVE: " (filter overconfident)", Verdict.BELOW: " (filter pessimistic)"}.get(verdict, "")


# -- pooled NEES ------------------------------------------------------------------------------

def _ok_nees(data: SweepData) -> np.ndarray:
    v = data.runs.mean_nees[data.runs.ok]
    return v[np.isfinite(v)]


def nees_why_not(data: SweepData) -> str | None:
    return None if _ok_nees(data).size else "no run finished with a NEES"


def nees(data: SweepData, alpha: float, rng: np.random.Generator) -> CheckResult:
    """Grand mean of the runs' time-averaged NEES in its two-sided interval.

    With at least :data:`estimators.nrun.MIN_RUNS_FOR_SPREAD` runs the interval is that of
    ``3 chi2(nu) / nu``, nu matched to the spread between runs (:func:`estimators.nrun.pooled_nees_test`);
    with fewer, ``chi2(3N) / N`` (runs as the only independent unit, conservative in time).
    """
    v = _ok_nees(data)
    pooled = nrun.pooled_nees_test(v, NEES_DOF, alpha)
    res = pooled.result
    lo, hi = res.interval
    if pooled.estimated:
        how = (f"interval 3 chi2(nu)/nu, nu = {_fmt(pooled.dof_effective)} matched to the spread between runs "
               f"(as {_fmt(pooled.dof_effective / NEES_DOF)} independent NEES samples)")
    else:
        how = (f"interval chi2({NEES_DOF}N)/N (fewer than {nrun.MIN_RUNS_FOR_SPREAD} runs: the spread "
               f"between runs is not used)")
    detail = (f"mean over {v.size} runs of the time-averaged pose NEES ({NEES_DOF} dof), {how}; "
              f"verdict {res.verdict.value}{_side(res.verdict)}")
    return CheckResult("nees", CheckStatus.PASS if res.passed else CheckStatus.FAIL, _fmt(res.statistic),
                       f"[{_fmt(lo)}, {_fmt(hi)}]", alpha, detail,
                       {"mean_nees": res.statistic, "interval": [lo, hi], "runs": v.size,
                        "run_min": float(v.min()), "run_max": float(v.max()),
                        "dof_effective": pooled.dof_effective, "spread_used": pooled.estimated})


# -- N-run NEES per step --------------------------------------------------------------------------

def _nees_matrix(data: SweepData) -> np.ndarray:
    st = data.steps
    ok = np.isin(st.run, data.runs.run[data.runs.ok]) & np.isfinite(st.nees)
    return nrun.align(st.run[ok], st.step[ok], st.nees[ok])


def nees_nrun_why_not(data: SweepData) -> str | None:
    if data.steps is None and data.steps_mode != "all":
        return (f"not available on a sweep written with --steps {data.steps_mode}: the test thins every "
                "step's NEES by its autocorrelation between steps, so it needs all of them (--steps all)")
    if data.steps is None or not len(data.steps):
        return "the sweep has no per-step table"
    m = _nees_matrix(data)
    if m.shape[0] < 2:
        return "fewer than 2 finished runs with a per-step NEES"
    spacing, _ = nrun.thinning_spacing(nrun.across_run_autocorrelation(m))
    tested = len(range(0, m.shape[1], spacing))
    if tested < MIN_INDEPENDENT_STEPS:
        return (f"the NEES stays correlated over {spacing} steps (autocorrelation across runs above "
                f"{nrun.MAX_THINNED_CORRELATION:g}): at most {tested} effectively independent steps, fewer "
                f"than {MIN_INDEPENDENT_STEPS}")
    return None


def _fraction_result(name: str, res: nrun.FractionResult, what: str, alpha: float) -> CheckResult:
    verdict = "" if res.passed else (" (filter overconfident)" if res.above >= res.below else
                                     " (filter pessimistic)")
    detail = (f"{what}, 95 % band; {res.outside} of {res.trials} outside ({res.above} above, {res.below} "
              f"below), N_k {res.runs_min}-{res.runs_max} runs; one-sided binomial(K, 0.05), p = "
              f"{_fmt(res.p_value)}{verdict}")
    return CheckResult(name, CheckStatus.PASS if res.passed else CheckStatus.FAIL,
                       f"{_fmt(res.fraction)} ({res.outside}/{res.trials})",
                       f"< {res.critical}/{res.trials} outside", alpha, detail,
                       {"outside": res.outside, "above": res.above, "below": res.below, "tested": res.trials,
                        "critical": res.critical, "p_value": res.p_value, "spacing": res.spacing,
                        "correlation_at_spacing": res.correlation, "runs_min": res.runs_min,
                        "runs_max": res.runs_max, "mean": res.mean})


def nees_nrun(data: SweepData, alpha: float, rng: np.random.Generator) -> CheckResult:
    """Bar-Shalom's N-run NEES test: the fraction of thinned steps outside ``chi2(3 N_k) / N_k``.

    The spacing makes the tested steps effectively independent (:func:`estimators.nrun.nees_fraction_test`),
    so the false-alarm probability of the binomial verdict is the stated ``alpha``.
    """
    res = nrun.nees_fraction_test(_nees_matrix(data), NEES_DOF, alpha)
    what = (f"N-run average pose NEES every {res.spacing} steps (the NEES autocorrelation across runs is "
            f"<= {nrun.MAX_THINNED_CORRELATION:g} from that lag on, max {_fmt(res.correlation)}), band "
            f"chi2({NEES_DOF}N_k)/N_k")
    return _fraction_result("nees_nrun", res, what, alpha)


# -- N-run NIS per fix ------------------------------------------------------------------------------

def _fix_sums(data: SweepData) -> tuple[np.ndarray, np.ndarray, int]:
    """Per run and fix index: NIS sum (gated updates at the gate value), its dof, gated count."""
    from scipy import stats


    fx = data.fixes
    per_marker = 2 if data.scenario.sensor.uses_bearing else 1
    attempted = np.sum(fx.markers >= 0, axis=1) * per_marker
    gated = attempted - fx.n_accepted
    total = np.nan_to_num(fx.nis) + gated * float(stats.chi2.ppf(EPISODE_GATE_PROBABILITY, 1))
    use = attempted > 0
    return (nrun.align(fx.run[use], fx.fix[use], total[use]),
            nrun.align(fx.run[use], fx.fix[use], attempted[use]), int(gated.sum()))


def nis_nrun_why_not(data: SweepData) -> str | None:
    if not len(data.fixes) or not np.any(data.fixes.markers >= 0):
        return "the sweep has no filter update"
    return None


def nis_nrun(data: SweepData, alpha: float, rng: np.random.Generator) -> CheckResult:
    """Bar-Shalom's N-run NIS test: the fraction of fix indices whose summed NIS leaves its band.

    At fix index j the NIS sums of the N_j runs are chi2 with the runs' summed scalar updates
    as dof; a gated update enters at the gate value, as in the pooled ``nis`` check. The
    innovations of a consistent filter are white, so fix indices are independent trials.
    """
    sums, dofs, gated = _fix_sums(data)
    res = nrun.fraction_outside_band(sums, dofs, alpha)
    what = f"N-run average NIS at each fix index (gated updates, {gated} in all, at the gate), band chi2(D_j)/N_j"
    return _fraction_result("nis_nrun", res, what, alpha)
