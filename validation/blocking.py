"""The ``blocking`` check: the plan's predicted robot blocking against what a fleet's episodes saw.

Each fix of a fleet sweep carries the plan's probability that another robot hides at least one
of the scheduled fix's markers at its start (fixes column ``p_block_robot``,
:attr:`planner.fleet.exposure.RobotBlocking.p_fix`) and what happened (``blocked_by_robot_count``
> 0: the simulation found a scheduled line of sight hidden by a robot's body).

**The test.** Fixes of one run are not independent (one robot late hides a reflector at several
fixes in a row, and every robot of a run shares the episode's timing draws), but runs are: each
run draws its own timing from its own streams (:mod:`planner.fleet.timing`). So the unit is the
run. Run r's fixes give its observed count O_r of blocked fixes and its expected count
E_r = sum of p over them; under the prediction (each fix blocked with its predicted probability,
whatever the dependence within a run) ``D_r = O_r - E_r`` has mean 0, and the D_r of the R runs
are independent and identically distributed (one plan, one scenario). The statistic is

    z = sum_r D_r / sqrt(V),  V = max(R s^2, sum of p (1 - p) over every fix) (1 + R / N),

s^2 the sample variance of the D_r (the variance of a sum over independent runs, however the
fixes of a run depend on each other). By the central limit theorem over the runs z is standard
normal when the prediction holds (asymptotically in R). The second term of V is the variance the
prediction itself states for fixes independent within a run; it only lowers z (fewer
false alarms) and keeps a sweep of identical runs (a fleet that keeps time like a clock: s^2 = 0)
from failing on a difference of rounding: a prediction within 1e-6 of 0 or 1 at every fix passes,
one that states a spread the runs do not have fails. The factor ``1 + R / N`` is the prediction's
own sampling error: it is the mean over N independent draws of the declared spread
(:data:`planner.fleet.sampled.DRAWS`) of a per-draw expected count whose variance is at most
Var(O_r), so its total over R runs errs with a variance of at most ``R^2 Var(O_r) / N``, ``R / N``
times the runs'.

Fixes the plan states no probability for (``p_block_robot`` NaN: their blocking hinges on the path
followers' tracking errors, the same in every run, :mod:`planner.fleet.sampled`; and the fixes a
robot takes on its final dock, which the schedule does not name) are left out and counted apart.

The runs are independent draws of the timing only when the fleet declares a timing spread: the
simulated robots keep time to about 0.01 s (:data:`planner.fleet.blocking.TIMING`), so without one
every run repeats one timing and its blocking, and most of the spread the prediction states is its
model's error, the same in every run. The check then does not apply (it used to take each
scheduled fix's rows as one dependent trial, which left it a handful of trials: 339.7 predicted
against 0 observed passed).

**Power.** A prediction scaled by k (``--blocking-scale k``) shifts the sum by (1 - k) E, E the
prediction's total, while V stays R Var(O_r) (E_r is the same in every run): its z is about
``(1 - k) E / sqrt(V)``, so the test fails a prediction twice the truth with probability about
``Phi(E / sqrt(V) - z_c)`` and one half the truth with ``Phi(E / (2 sqrt(V)) - z_c)`` (z_c the
critical value below). Fixes of one run hide together (a robot standing in the way hides a
reflector for a stretch of fixes), so V exceeds E by the mean size of such a stretch, and the
power grows with the count of independent blocking events, not of blocked fixes: at 200 runs a
half-size prediction is failed with probability 0.9 once E / sqrt(V) >= 2 (z_c + 1.28). The check
reports both powers and the z a prediction scaled by 1/2 and by 2 would have had on the same runs
(``z_half``, ``z_double``), so that a pass shows what it could have caught. These powers take the
total as normal, which overstates the power against a prediction too low where most runs hide
nothing; the prediction states its own before any run by simulating sweeps from its law of a
run's count (:func:`model_powers`).

A total can hide a prediction that puts its mass on the wrong fixes (the blocked ones predicted
clear and as many clear ones predicted blocked): the same test is made in each bin of the
predicted probability (:data:`EDGES`), and the check fails when the total's or a bin's
``|z|`` exceeds ``Phi^-1(1 - a / (2 m))``, m = 1 + the bins (Bonferroni: false-alarm probability
at most a).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.stats import norm

from planner.fleet.sampled import DRAWS
from validation.data import CheckResult, CheckStatus, SweepData

EDGES = (0.0, 0.02, 0.1, 0.3, 0.7, 0.9, 0.98, 1.0)
"""Bin edges of the predicted probability for the report: fine near 0 and 1, where most fixes are."""
SIMS = 2000
"""Sweeps simulated from the prediction's own law to state the check's power (:func:`model_powers`)."""
POOL = 64
"""Runs drawn per draw of the spread for the law of one run's count (:func:`model_powers`)."""


def blocking_why_not(data: SweepData) -> str | None:
    """Return why the check does not apply (no predicted or observed robot blocking), or None."""
    fx = data.fixes
    if fx.p_block_robot is None or fx.robot_blocked is None:
        return ("the fixes table has no predicted robot blocking (p_block_robot) and observed blocking "
                "(blocked_by_robot_count): not a fleet sweep")
    if not np.isfinite(fx.p_block_robot).any():
        return "no fix has a predicted robot blocking probability"
    if not any(r.start_jitter > 0 or r.dwell > 0 or r.speed_spread > 0 for r in data.scenario.robots):
        return ("no robot declares a timing spread ([[robots]] start_jitter, dwell, speed_spread): every run "
                "repeats one timing, so the runs are one draw of who hides what, not independent trials of the "
                "predicted chances (declare the spread the real fleet has)")
    return None


def _bins(p: np.ndarray) -> list[np.ndarray]:
    """Group the fixes by bin of :data:`EDGES` (non-empty bins only)."""
    which = np.clip(np.searchsorted(EDGES, p, side="right") - 1, 0, len(EDGES) - 2)
    groups = [np.flatnonzero(which == b) for b in range(len(EDGES) - 1)]
    return [g for g in groups if len(g)]


def _runs_of(data: SweepData) -> np.ndarray:
    """Return the run of each fix (a fleet's tables number each robot of each run as a unit, ``run * n + robot``)."""
    n = max(len(data.scenario.robots), 1)
    return np.asarray(data.fixes.run, dtype=np.int64) // n


def _floor(p: np.ndarray) -> float:
    """Variance of the count of blocked fixes the prediction ``p`` states for fixes independent of each other."""
    return float(np.sum(p * (1.0 - p)))


def _z(d_run: np.ndarray, floor: float) -> tuple[float, float]:
    """Return z and its variance V for per-run differences ``d_run`` (module docstring)."""
    n_runs = len(d_run)
    v_runs = float(np.sum((d_run - d_run.mean()) ** 2) * n_runs / (n_runs - 1)) if n_runs > 1 else 0.0
    v = max(v_runs, floor) * (1.0 + n_runs / DRAWS)
    total = float(d_run.sum())
    if v <= 0.0:
        return (0.0 if total == 0.0 else math.copysign(math.inf, total)), v
    return total / math.sqrt(v), v


def powers(expected: float, variance: float, z_crit: float) -> tuple[float, float]:
    """Return the test's power against a prediction twice and half the truth (module docstring, **Power**).

    ``expected``: the prediction's total over the runs E; ``variance``: V, the variance of the observed
    total about it (the runs' own times ``1 + R / N``); ``z_crit``: the test's critical |z|.
    """
    reach = expected / math.sqrt(variance) if variance > 0 else math.inf
    return float(norm.cdf(reach - z_crit)), float(norm.cdf(reach / 2.0 - z_crit))


def model_powers(hits: np.ndarray, runs: int, z_crit: float, rng: np.random.Generator,
                 sims: int = SIMS) -> tuple[float, float]:
    """Return the power the prediction itself states for a sweep of ``runs`` runs, twice and half the truth.

    The normal law of :func:`powers` overstates the power against a prediction too low where one
    run's count is skewed (most runs hide nothing, a few a stretch of fixes): a run that hides
    more also raises the runs' variance, so the total's z grows slower than its sum (the synthetic
    fleet of ``tests/validation/test_blocking_check.py`` whose robots hide 5 fixes together in 2 %
    of the runs, 40 runs: the normal law states 0.17 against a prediction half the truth, the
    check fails 0.10 of such sweeps, this simulation states 0.08). So the sweep is simulated from
    the prediction's own law of a run's count (the runs hide fixes as the model says), ``sims``
    times: ``runs`` runs each
    a draw of the spread and each decided fix hidden with its chance in that draw (independent
    within the draw, as the model takes them), tested as :func:`blocking` tests the total against
    the model's prediction scaled by 2 and by 1/2. The bins' tests are left out (they only add
    failures): a lower bound of the check's power when the model is the truth.

    Parameters
    ----------
    hits : ndarray, shape (D, F)
        Per draw of the spread, each decided fix's chance to be hidden
        (:attr:`planner.fleet.sampled.SampledBlocking.hits`).
    runs : int
        Runs of the sweep.
    z_crit : float
        The check's critical |z| (:func:`critical`).
    rng : numpy.random.Generator
    sims : int
        Simulated sweeps: the stated power errs by at most 3 sqrt(0.05 x 0.95 / sims) = 0.015 about
        0.95 at the default (false alarm 0.3 %).

    Returns
    -------
    power_double, power_half : float
        Share of the simulated sweeps failed against a prediction twice and half the truth.
    """
    hits = np.asarray(hits, dtype=float)
    d, n_fix = hits.shape
    p = hits.mean(axis=0)
    # the model's law of one run's count, POOL runs per draw of the spread
    pool = np.concatenate([(rng.random((POOL, n_fix)) < h).sum(axis=1) for h in hits]).astype(float)
    counts = pool[rng.integers(0, len(pool), (sims, runs))]
    total, s2 = counts.sum(axis=1), counts.var(axis=1, ddof=1)
    out = []
    for k in (2.0, 0.5):
        kp = np.clip(k * p, 0.0, 1.0)
        v = np.maximum(runs * s2, runs * _floor(kp)) * (1.0 + runs / DRAWS)
        z = (total - runs * kp.sum()) / np.sqrt(np.where(v > 0, v, np.inf))
        out.append(float(np.mean(np.abs(z) > z_crit)))
    return out[0], out[1]


def critical(alpha: float, p: np.ndarray) -> float:
    """Return the check's critical |z| at false-alarm probability ``alpha`` on predictions ``p`` (its bins' count)."""
    return float(norm.ppf(1.0 - alpha / (1 + len(_bins(np.clip(p, 0.0, 1.0)))) / 2.0))


def blocking(data: SweepData, alpha: float, rng: np.random.Generator) -> CheckResult:
    """Compare the observed count of robot-blocked fixes with the predicted, runs as the unit (module docstring)."""
    fx = data.fixes
    ok = np.isfinite(fx.p_block_robot)
    p = np.clip(fx.p_block_robot[ok], 0.0, 1.0)
    obs = np.asarray(fx.robot_blocked, bool)[ok].astype(float)
    runs = np.unique(_runs_of(data)[ok], return_inverse=True)[1].reshape(-1)
    n_runs = int(runs.max(initial=-1)) + 1
    o_run = np.bincount(runs, weights=obs, minlength=n_runs)
    e_run = np.bincount(runs, weights=p, minlength=n_runs)
    floor = _floor(p)
    z, v = _z(o_run - e_run, floor)
    groups = _bins(p)
    m = 1 + len(groups)
    z_crit = critical(alpha, p)
    rows = []
    for g in groups:
        d = np.bincount(runs[g], weights=obs[g] - p[g], minlength=n_runs)
        z_b = _z(d, _floor(p[g]))[0]
        rows.append({"p_from": float(p[g].min()), "p_to": float(p[g].max()), "fixes": int(len(g)),
                     "expected": float(p[g].sum()), "observed": int(obs[g].sum()), "z": z_b,
                     "failed": not abs(z_b) <= z_crit})
    failed = not abs(z) <= z_crit
    bins_off = sum(r["failed"] for r in rows)
    # what the same runs say of a prediction half and twice as large (the check's power, shown)
    z_half, z_double = (_z(o_run - k * e_run, _floor(np.clip(k * p, 0.0, 1.0)))[0] for k in (0.5, 2.0))
    total_e, total_s = float(p.sum()), int(obs.sum())
    power_double, power_half = powers(total_e, v, z_crit)
    apart = ~ok
    n_apart, hid_apart = int(apart.sum()), int(np.asarray(fx.robot_blocked, bool)[apart].sum())
    per_bin = "; ".join(f"p {r['p_from']:.3g}..{r['p_to']:.3g}: {r['observed']}/{r['expected']:.1f} "
                        f"(z {_fmt(r['z'])})" for r in rows)
    side = "" if not failed else (" (more blocked than predicted)" if z > 0 else " (fewer blocked than predicted)")
    detail = (f"fixes with a scheduled line of sight hidden by a robot, observed against expected, the {n_runs} runs "
              f"as independent units: z = (sum O_r - sum E_r) / sqrt(V), V the larger of the runs' variance x R "
              f"({_fmt(v)}) and the prediction's for independent fixes ({_fmt(floor)}){side}; the same runs against "
              f"a prediction half as large give z {_fmt(z_half)}, twice as large {_fmt(z_double)}; power against a "
              f"prediction twice the truth {power_double:.2f}, half the truth {power_half:.2f}; {n_apart} fixes "
              f"without a prediction (undecided or on the final dock; {hid_apart} hidden) left out; the same test per "
              f"bin of the predicted probability, observed/expected: {per_bin}; a = alpha / {m} tests")
    return CheckResult("blocking", CheckStatus.FAIL if failed or bins_off else CheckStatus.PASS,
                       f"{total_s} blocked, {total_e:.1f} expected, z {_fmt(z)}, {bins_off}/{len(rows)} bins off",
                       f"|z| <= {z_crit:.3g}", alpha, detail,
                       {"z": z, "z_crit": z_crit, "tests": m, "variance": v, "variance_floor": floor,
                        "observed": total_s, "expected": total_e, "fixes": int(ok.sum()), "runs": n_runs,
                        "z_half": z_half, "z_double": z_double, "power_double": power_double,
                        "power_half": power_half, "fixes_apart": n_apart, "hidden_apart": hid_apart,
                        "draws": DRAWS, "failed_bins": bins_off, "per_bin": rows})


def _fmt(x: float) -> str:
    return f"{x:+.3g}" if math.isfinite(x) else str(x)
