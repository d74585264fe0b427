"""The validation checks (`docs/design.md` §6), pure functions of a sweep's tables.

Each check has an applicability test (the reason it does not apply, or None) and an
evaluation at a given false-alarm probability ``alpha``. Checks that cannot fail when the
model holds (``containment``, ``bound``) have alpha 0 and take no share of the family alpha;
the others are statistical and get ``alpha / m`` each (Bonferroni over the m that apply, see
:func:`validation.suite.validate`).

Which noise model applies is the *declared* one (``scenario.sensor.noise``): the checks test
the claims of the model the planner and the filter use, and a simulated sensor that differs
from it (``[sensor.actual]``) is exactly what they must catch.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from estimators.consistency import chi2_interval, clopper_pearson, fraction_test
from estimators.fault.exact import DEFAULT_TOLERANCE_FRACTION
from estimators.fault.linearized import chi2_2dof_ppf
from scenarios.schema import NoiseModel, PefModel
from validation import nrun, null, outcome
from validation.blocking import blocking, blocking_why_not
from validation.data import EPISODE_GATE_PROBABILITY, CheckResult, CheckStatus, SweepData
from validation.promise import promise, promise_why_not

SET_MEMBERSHIP_MODELS = (PefModel.EXACT, PefModel.PARALLELOGRAM, PefModel.STRIPS)
"""PEF models whose tau is the diameter of a fault area (a bound); gdop's is that of a probability ellipse."""


@dataclass(frozen=True)
class Check:
    """One validation check: its name, whether it is statistical, and its two functions."""

    name: str
    statistical: bool
    why_not: Callable[[SweepData], str | None]
    evaluate: Callable[[SweepData, float, np.random.Generator], CheckResult]


def _fmt(x: float) -> str:
    return f"{x:.4g}" if math.isfinite(x) else str(x)


def _ratios(data: SweepData) -> tuple[np.ndarray, np.ndarray]:
    """Return the fixes usable for the bound (all markers measured, finite tau) and their error/tau.

    Fixes improvised beyond the plan's redundancy (blocked lines of sight) are left out, as in the
    promise check: the plan made no prediction for their subsets.
    """
    fx = data.fixes
    use = fx.full & np.isfinite(fx.predicted_tau) & (fx.predicted_tau > 0) & np.isfinite(fx.snapshot_error)
    if fx.beyond is not None:
        use &= ~fx.beyond
    return use, fx.snapshot_error[use] / fx.predicted_tau[use]


# -- containment --------------------------------------------------------------------------

def _containment_why_not(data: SweepData) -> str | None:
    if data.scenario.sensor.noise is not NoiseModel.UNIFORM:
        return "the declared noise is gaussian: unbounded errors make misses possible (see coverage)"
    if len(data.fixes) == 0:
        return "the sweep has no fix"
    return None


def containment(data: SweepData, alpha: float, rng: np.random.Generator) -> CheckResult:
    """Check that the true position lies in the realised exact fault area at every fix.

    The area intersects the annuli ``|r - r_i| <= rho_i + shift bound`` (the odometry bound of
    carrying earlier ranges to the fix time) and, with bearings, the heading-free regions of
    the robot-frame bearings' pairwise differences (bound ``xi`` each, plus for an earlier
    bearing the odometry's turn bound and the angle its shift bound subtends; no filter
    heading enters), polygonised outwards within ``1e-3 * min(rho)``
    (:mod:`estimators.fault.exact`). Under the bounded model a miss is impossible: any miss
    fails (false-alarm probability 0). An empty area (inconsistent measurements) counts as a
    miss.
    """
    fx = data.fixes
    n = len(fx)
    miss = ~fx.contained
    k = int(miss.sum())
    empty = int(np.sum(miss & ~np.isfinite(fx.fault_diameter)))
    bearings = ", heading-free bearing pairs" if data.scenario.sensor.uses_bearing else ""
    detail = (f"truth inside the realised exact fault area (rho + odometry shift bound{bearings}, polygon "
              f"tolerance {DEFAULT_TOLERANCE_FRACTION:g}*min rho); a miss is impossible under bounded noise")
    if k:
        first = int(np.flatnonzero(miss)[0])
        detail += f"; first miss in run {int(fx.run[first])}, {empty} of the misses had an empty area"
    return CheckResult("containment", CheckStatus.FAIL if k else CheckStatus.PASS,
                       f"{k}/{n} missed", "0 misses", 0.0, detail,
                       {"misses": k, "fixes": n, "empty_areas": empty})


# -- bound and tightness ------------------------------------------------------------------

def _bound_why_not(data: SweepData) -> str | None:
    if data.scenario.sensor.noise is not NoiseModel.UNIFORM:
        return "the declared noise is gaussian: the PEF bound holds only for bounded noise"
    if data.scenario.planning.pef_model not in SET_MEMBERSHIP_MODELS:
        return (f"pef_model {data.scenario.planning.pef_model.value} gives the diameter of a probability "
                "ellipse, not a bound")
    if not _ratios(data)[0].any():
        return "no fix with all its markers measured and a finite predicted tau"
    return None


def _null_maps(data: SweepData, use: np.ndarray) -> np.ndarray:
    fx = data.fixes
    marker_xy = data.scenario.marker_positions()[fx.markers[use]]
    return null.error_maps(marker_xy, fx.true_xy[use], data.scenario.sensor)


def bound(data: SweepData, alpha: float, rng: np.random.Generator) -> CheckResult:
    """Check that the snapshot error never exceeds the predicted tau (false alarm probability 0).

    tau is the model's fault-area diameter at the true position; the least-squares point of
    two ranges lies in the (centrally symmetric) linearised area, so its error is at most
    tau / 2 (:mod:`validation.null`; the model's worst case per fix is reported). With
    bearings the least-squares fix estimates the heading with the position and has more rows
    than unknowns, so it need not lie in the area: the null model's worst case (reported)
    states how far it may go.
    """
    use, ratio = _ratios(data)
    over = int(np.sum(ratio > 1.0))
    worst = null.worst_case_ratio(_null_maps(data, use), data.fixes.predicted_tau[use])
    worst_max = float(np.nanmax(worst)) if np.isfinite(worst).any() else math.nan
    model = data.scenario.planning.pef_model.value
    detail = (f"snapshot LS error / PEF tau ({model}) of the fix's subset at the truth; the bounded "
              f"model allows at most {_fmt(worst_max)} (odometry shift error not included)")
    return CheckResult("bound", CheckStatus.FAIL if over else CheckStatus.PASS,
                       f"max {_fmt(float(ratio.max()))}, {over}/{ratio.size} over", "<= 1 at every fix", 0.0,
                       detail, {"max_ratio": float(ratio.max()), "exceedances": over,
                                "fixes": int(ratio.size), "model_worst_ratio": worst_max,
                                "skipped_fixes": int(np.sum(~use))})


def tightness(data: SweepData, alpha: float, rng: np.random.Generator) -> CheckResult:
    """Check that the largest observed error / tau reaches the fraction f the model reaches.

    f is derived from ``alpha``: the null ratio of every fix is simulated at its own geometry
    (uniform errors in ``+-rho``, and ``+-xi`` with the heading estimated alongside when the
    sensor measures bearings, linearised LS, :mod:`validation.null`), and f is the
    largest value with ``P(max over the fixes < f) <= alpha``. A bound that is far from tight
    (real errors much smaller than declared) fails.
    """
    use, ratio = _ratios(data)
    tau = data.fixes.predicted_tau[use]
    sims = null.simulate_ratios(_null_maps(data, use), tau, rng)
    f = null.tightness_threshold(sims, alpha)
    typical = float(np.median(sims.max(axis=0)))
    observed = float(ratio.max())
    detail = (f"f chosen so that P(max of {ratio.size} null ratios < f) <= alpha ({sims.shape[1]} draws "
              f"per fix, uniform errors in +-rho at each fix's truth); null median of the max "
              f"{_fmt(typical)}")
    return CheckResult("tightness", CheckStatus.PASS if observed >= f else CheckStatus.FAIL,
                       f"max {_fmt(observed)}", f">= f = {_fmt(f)}", alpha, detail,
                       {"max_ratio": observed, "threshold": f, "null_median_max": typical,
                        "fixes": int(ratio.size), "draws_per_fix": int(sims.shape[1])})


# -- coverage -----------------------------------------------------------------------------

def _coverage_rows(data: SweepData) -> np.ndarray:
    fx = data.fixes
    return (np.isfinite(fx.snapshot_cov).all(axis=(1, 2)) & np.isfinite(fx.snapshot_xy).all(axis=1)
            & (np.linalg.det(np.where(np.isfinite(fx.snapshot_cov), fx.snapshot_cov, 0.0)) > 0))


def _coverage_why_not(data: SweepData) -> str | None:
    if data.scenario.sensor.noise is not NoiseModel.GAUSSIAN:
        return "the declared noise is uniform: no gaussian fixes (see containment and bound)"
    if not _coverage_rows(data).any():
        return "no fix with a finite snapshot covariance"
    return None


def coverage(data: SweepData, alpha: float, rng: np.random.Generator) -> CheckResult:
    """Check that the fraction of fixes inside their p-level snapshot ellipse matches p.

    Inside: ``d^T C^-1 d <= chi2.ppf(p, 2)`` with d the snapshot error and C its covariance
    (with bearings, the position block of the pose fix's, :mod:`estimators.snapshot`),
    ``p = planning.gdop_level``; two-sided Clopper-Pearson interval at ``alpha`` must hold p.
    """
    fx = data.fixes
    rows = _coverage_rows(data)
    p = data.scenario.planning.gdop_level
    d = (fx.snapshot_xy - fx.true_xy)[rows]
    m2 = np.einsum("fi,fi->f", d, np.linalg.solve(fx.snapshot_cov[rows], d[..., None])[..., 0])
    k, n = int(np.sum(m2 <= chi2_2dof_ppf(p))), int(rows.sum())
    res = fraction_test(k, n, p, alpha)
    lo, hi = res.interval
    detail = (f"snapshot error inside its {p:g} ellipse (d^T C^-1 d <= {_fmt(chi2_2dof_ppf(p))}); "
              f"fixes are independent, exact binomial interval; verdict {res.verdict.value}")
    return CheckResult("coverage", CheckStatus.PASS if res.passed else CheckStatus.FAIL,
                       f"{_fmt(k / n)} ({k}/{n})", f"CI [{_fmt(lo)}, {_fmt(hi)}] holds p = {p:g}", alpha,
                       detail, {"inside": k, "fixes": n, "p": p, "ci": [lo, hi],
                                "skipped_fixes": int(np.sum(~rows))})


# -- filter consistency ---------------------------------------------------------------------

def _updates(data: SweepData) -> tuple[int, int]:
    """Count the updates attempted and gated over all fixes.

    Each measured marker is one range update (plus one bearing update with bearings).
    """
    per_marker = 2 if data.scenario.sensor.uses_bearing else 1
    attempted = int(np.sum(data.fixes.markers >= 0)) * per_marker
    return attempted, attempted - int(np.sum(data.fixes.n_accepted))


def _nis_why_not(data: SweepData) -> str | None:
    return None if _updates(data)[0] else "the sweep has no filter update"


def nis(data: SweepData, alpha: float, rng: np.random.Generator) -> CheckResult:
    """Average NIS over every update of every run in its two-sided chi2(1) interval.

    A consistent filter's innovations are white, so each update counts. The stored NIS sums
    only accepted updates; a gated update enters at the gate value (its NIS was at least
    that), so the statistic is a lower bound of the true average (the gap is ~0.002 for a
    consistent filter at a 0.999 gate).
    """
    from scipy import stats

    n, gated = _updates(data)
    gate = float(stats.chi2.ppf(EPISODE_GATE_PROBABILITY, 1))
    stat = (float(np.nansum(data.fixes.nis)) + gated * gate) / n
    lo, hi = chi2_interval(1, n, alpha)
    passed = lo <= stat <= hi
    side = "" if passed else (" (innovations larger than predicted)" if stat > hi else
                              " (innovations smaller than predicted)")
    detail = (f"{n} scalar updates, {gated} gated (counted at the gate {_fmt(gate)}); interval "
              f"chi2(n)/n{side}")
    return CheckResult("nis", CheckStatus.PASS if passed else CheckStatus.FAIL, _fmt(stat),
                       f"[{_fmt(lo)}, {_fmt(hi)}]", alpha, detail,
                       {"mean_nis": stat, "interval": [lo, hi], "updates": n, "gated": gated})


# -- the plan ---------------------------------------------------------------------------------

def _plan_why_not(data: SweepData) -> str | None:
    return None if len(data.runs) else "the sweep has no run"


def plan(data: SweepData, alpha: float, rng: np.random.Generator) -> CheckResult:
    """Check the fraction of runs that reach the goal with the error under eps_max all along.

    With lines of sight blocked, a run must also keep its certified bound under eps_max through
    every fix that lost at most one of the markers the plan counted
    on (the single-failure test, :func:`sim.montecarlo.summary.succeeded`): what a layout placed
    for redundancy promises, and what a redundancy-0 layout does not. A fleet's robots hide each
    other's reflectors: the same test, whoever blocked the line of sight.
    Crashed runs count as failures. Fails when the upper end of the two-sided Clopper-Pearson
    interval at ``alpha`` is below ``montecarlo.success_target`` (false alarm <= alpha / 2).
    """
    runs = data.runs
    k, n = int(runs.succeeded.sum()), len(runs)
    lo, hi = clopper_pearson(k, n, alpha)
    target = data.scenario.montecarlo.success_target
    crashed = int(np.sum(~runs.ok))
    sc = data.scenario
    single = ""
    if sc.sensor_actual.block_probability > 0 or len(sc.robots) > 1:   # lines of sight lost at random or to robots
        single = (" and kept the certified bound under it through every fix that lost at most "
                  "one line of sight")
        if runs.untested:
            single += f" ({runs.untested} runs from an older pefsim without that test)"
    detail = (f"runs that reached the goal and never exceeded eps_max = {sc.planning.eps_max:g} m{single} "
              f"({crashed} crashed, counted as failures); Clopper-Pearson [{_fmt(lo)}, {_fmt(hi)}]")
    return CheckResult("plan", CheckStatus.PASS if hi >= target else CheckStatus.FAIL,
                       f"{_fmt(k / n)} ({k}/{n})", f"CI upper >= target {target:g}", alpha, detail,
                       {"successes": k, "runs": n, "ci": [lo, hi], "target": target, "crashed": crashed})


CHECKS: tuple[Check, ...] = (
    Check("runs", False, outcome.runs_why_not, outcome.runs),
    Check("containment", False, _containment_why_not, containment),
    Check("promise", False, promise_why_not, promise),
    Check("bound", False, _bound_why_not, bound),
    Check("tightness", True, _bound_why_not, tightness),
    Check("coverage", True, _coverage_why_not, coverage),
    Check("nees", True, nrun.nees_why_not, nrun.nees),
    Check("nis", True, _nis_why_not, nis),
    Check("nees_nrun", True, nrun.nees_nrun_why_not, nrun.nees_nrun),
    Check("nis_nrun", True, nrun.nis_nrun_why_not, nrun.nis_nrun),
    Check("plan", True, _plan_why_not, plan),
    Check("blocking", True, blocking_why_not, blocking),
)
"""Every check, in the order they are reported."""
