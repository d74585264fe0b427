"""The promise check: every realised fix within what the plan promised for it (`docs/design.md` §6).

The plan promises each fix a bound on the fault-area diameter of the moving fix the robot makes
(:mod:`planner.schedule.promise`): the worst over every true pose within the stated bounds of the
planned ones (tracking error, estimate error, start lag, speed; the construction and its
assumptions are that module's docstring). The simulation builds the realised fault area of the
same construction from the measured ranges (:mod:`estimators.fault.carried`). Under bounded
(uniform) noise the realised exact area is within the promise; what remains is

- the polygonisation: the realised polygon reaches up to ``tol = DEFAULT_TOLERANCE_FRACTION *
  min(rho)`` beyond its arcs, so its diameter up to ``2 tol`` beyond the exact one, at most
  ``planner.schedule.promise.POLYGON_TOLERANCE`` times the promise (the margin the planner
  keeps under ``eps_max``);
- the filter's heading std exceeding the one the plan assumed (``planning.heading_std_deg``), or
  the robot beyond the stated bounds: that is a broken promise, and what the check is there
  to catch.

So a fix passes when ``fault_diameter <= (1 + POLYGON_TOLERANCE) * predicted_tau`` and
``fault_diameter < eps_max``. A fix without a finite promise fails. The check is
deterministic (false-alarm probability 0), like containment. Fixes the robot improvised because
blocked lines of sight (``sensor.block_probability``) left neither the scheduled subset nor its
fallback are beyond the plan's redundancy: it promised nothing for them, so they are counted
and left out. A fix that measured a subset the plan did not schedule although no line of sight
was blocked (column ``unplanned``: the laser did not see a marker the plan counted on) did not
keep the plan, whatever its realised area: it counts as broken, and is reported apart. Its
``predicted_tau`` is the promise of what it measured, at the scheduled poses, and is judged
as any other (sweeps written before the column existed read it as null: not judged).
"""

from __future__ import annotations

import math

import numpy as np

from estimators.fault.exact import DEFAULT_TOLERANCE_FRACTION
from planner.schedule.promise import POLYGON_TOLERANCE, START_LAG
from scenarios.jsonable import json_number
from scenarios.schema import NoiseModel, PefModel
from validation.data import CheckResult, CheckStatus, SweepData

SET_MEMBERSHIP_MODELS = (PefModel.EXACT, PefModel.PARALLELOGRAM, PefModel.STRIPS)


def promise_why_not(data: SweepData) -> str | None:
    """Return why the promise check does not apply to ``data``, or None."""
    if data.scenario.sensor.noise is not NoiseModel.UNIFORM:
        return "the declared noise is gaussian: realised fault areas are not bounded by the promise"
    if data.scenario.planning.pef_model not in SET_MEMBERSHIP_MODELS:
        return f"pef_model {data.scenario.planning.pef_model.value} gives a probability region, not a bound"
    if not np.isfinite(data.fixes.fault_diameter).any():
        return "the sweep has no fix with a realised fault area"
    return None


def promise_allowance(data: SweepData) -> np.ndarray:
    """Largest realised diameter each fix may have under its promise, shape (F,) [m]."""
    return (1.0 + POLYGON_TOLERANCE) * data.fixes.predicted_tau


def promise(data: SweepData, alpha: float, rng: np.random.Generator) -> CheckResult:
    """Check every realised fault-area diameter against the fix's promise and eps_max."""
    fx = data.fixes
    eps = data.scenario.planning.eps_max
    beyond = fx.beyond if fx.beyond is not None else np.zeros(len(fx), dtype=bool)
    real = np.isfinite(fx.fault_diameter) & ~beyond
    d, pred = fx.fault_diameter[real], fx.predicted_tau[real]
    # substitutes for a marker the plan counted on and the laser did not see: the plan not kept
    unplanned = (fx.unplanned[real] if fx.unplanned is not None else np.zeros(d.size, dtype=bool))
    no_promise = ~np.isfinite(pred)
    allowed = promise_allowance(data)[real]
    over = ~no_promise & (d > allowed)
    over_eps = d >= eps
    ratio = np.where(no_promise, np.nan, d / np.where(no_promise, 1.0, pred))
    worst = float(np.nanmax(ratio)) if np.isfinite(ratio).any() else math.nan
    broken = no_promise | over | over_eps | unplanned
    bad = int(np.sum(broken))
    detail = (f"realised fault-area diameter <= (1 + {POLYGON_TOLERANCE:g}) x the plan's promise (the worst over the "
              f"poses within the follower's tracking bound, the estimate error the plan certifies at the fix and "
              f"a start up to {START_LAG:.3g} s late; the factor is the polygons' reach "
              f"{DEFAULT_TOLERANCE_FRACTION:g} min rho beyond the arcs), and < eps_max = "
              f"{eps:g} m; {int(no_promise.sum())} fixes without a promise, {int(over.sum())} over it, "
              f"{int(over_eps.sum())} at or over eps_max; "
              + (f"{int(unplanned.sum())} on a subset the plan did not schedule (no line of sight blocked); "
                 if fx.unplanned is not None else "unplanned subsets not recorded in this sweep; ")
              + f"{int(beyond.sum())} improvised beyond the redundancy (blocked lines of sight) left out")
    if bad:
        first = int(np.flatnonzero(real)[np.flatnonzero(broken)[0]])
        detail += f"; first in run {int(fx.run[first])}"
    return CheckResult("promise", CheckStatus.FAIL if bad else CheckStatus.PASS,
                       f"max ratio {worst:.4g}, {bad}/{d.size} broken",
                       f"<= {1 + POLYGON_TOLERANCE:g} x promise and < eps_max", 0.0, detail,
                       {"max_ratio": json_number(worst), "broken": bad, "fixes": int(d.size),
                        "without_promise": int(no_promise.sum()), "over_promise": int(over.sum()),
                        "over_eps_max": int(over_eps.sum()), "max_diameter": float(d.max()) if d.size else None,
                        "unplanned": int(unplanned.sum()) if fx.unplanned is not None else None,
                        "tolerance": POLYGON_TOLERANCE})
