"""Bar-Shalom's N-run consistency tests, with false-alarm probabilities that hold in time.

Bar-Shalom, Li, Kirubarajan, *Estimation with Applications to Tracking and Navigation*, 5.4.2:
at each time k the NEES (or NIS) averaged over N independent runs is, for a consistent
filter, ``chi2(d N) / N``; the fraction of times outside its two-sided 95 % band should be
about 5 %.

That fraction is an honest test only if the times are independent. Innovations of a
consistent filter are white, so per-fix NIS averages are; estimation errors are not: the
N-run NEES average at step k is correlated with that at k + l exactly as one run's NEES is
(``Cov(mean_i e_i(k), mean_i e_i(l)) = Cov(e(k), e(l)) / N``), and counting the steps of a
3000-step run as 3000 Bernoulli(0.05) trials gives false alarms far above the stated rate.

:func:`nees_fraction_test` therefore thins the steps to a spacing L chosen from the data: the
autocorrelation of the NEES across runs (:func:`across_run_autocorrelation`, estimated from N
independent runs, so it is precise) must stay at or below ``MAX_THINNED_CORRELATION`` at
every lag from L on. For a bivariate normal pair with correlation rho the indicators of
leaving a two-sided 95 % band have correlation about ``0.55 rho^2`` (the second Hermite term:
``2 (c phi(c))^2 rho^2 / (0.05 * 0.95)`` with c = 1.96), 0.02 at rho = 0.2, so the thinned
count is binomial to within a few per cent in variance. The count is judged one-sided: too
many steps outside is the inconsistency (in either direction of the covariance); the critical
count is the smallest c with ``P(Binomial(K, 0.05) >= c) <= alpha``.

The fraction test sees only the times; its power against a covariance a few per cent off is
small (each step's average moves by a fraction of its band). :func:`pooled_nees_test` uses the
same runs with all their steps: the grand mean of the runs' time-averaged NEES against the
interval of a scaled chi2 whose dof is matched to the spread *between* runs
(Welch-Satterthwaite). Runs are independent, so that spread is an honest estimate of the
variance whatever the correlation in time; a run's time-averaged NEES is a quadratic form in
the (gaussian) error trajectory, which a moment-matched scaled chi2 approximates well.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

from estimators.consistency import ConsistencyResult, Verdict
from scenarios.errors import SimulationError

BAND_PROBABILITY = 0.95
"""Bar-Shalom's two-sided band: a consistent filter's N-run average leaves it 5 % of the time."""
MAX_THINNED_CORRELATION = 0.2
"""Largest |autocorrelation| of the NEES allowed at the thinning spacing and beyond (module docstring)."""
MIN_RUN_FRACTION = 0.5
"""A step (or fix index) is tested only where at least this fraction of the runs reach it."""
MIN_RUNS_FOR_SPREAD = 50
"""Below this many runs the between-run variance is too uncertain to set the pooled NEES
interval (its relative error is ~sqrt(2 / N)); :func:`pooled_nees_test` then uses the
fully-correlated interval ``chi2(d N) / N``, valid at any N."""


@dataclass(frozen=True)
class FractionResult:
    """Outcome of an N-run fraction-outside-band test.

    Attributes
    ----------
    outside, above, below : int
        Times tested whose N-run average left the band (above it: errors larger than the
        covariance says; below it: smaller).
    trials : int
        Times tested (K).
    critical : int
        The test fails when ``outside >= critical``.
    p_value : float
        ``P(Binomial(K, 1 - band) >= outside)``.
    alpha : float
        False-alarm probability (one-sided binomial; at most ``alpha``, the count is discrete).
    spacing : int
        Steps between tested times (1 for fixes: innovations are white).
    correlation : float
        Largest |autocorrelation| at the spacing and beyond (0 when not estimated).
    runs_min, runs_max : int
        Fewest and most runs averaged at a tested time.
    mean : float
        Mean of the tested N-run averages.
    """

    outside: int
    above: int
    below: int
    trials: int
    critical: int
    p_value: float
    alpha: float
    spacing: int
    correlation: float
    runs_min: int
    runs_max: int
    mean: float

    @property
    def fraction(self) -> float:
        return self.outside / self.trials

    @property
    def passed(self) -> bool:
        return self.outside < self.critical


def align(run, index, values) -> np.ndarray:
    """Arrange per-time values of several runs as a runs x times matrix, aligned by index.

    Parameters
    ----------
    run : array_like of int, shape (M,)
        Run of each value.
    index : array_like of int, shape (M,)
        Step (or fix) index of each value from the start of its run (>= 0).
    values : array_like, shape (M,)

    Returns
    -------
    numpy.ndarray, shape (N, K)
        One row per distinct run (sorted), ``K = max(index) + 1``; NaN where a run has no value.
    """
    run, index = np.asarray(run, dtype=np.int64), np.asarray(index, dtype=np.int64)
    values = np.asarray(values, dtype=float)
    if not run.size:
        return np.zeros((0, 0))
    if index.min() < 0:
        raise SimulationError(f"align: indices must be >= 0, got {index.min()}")
    runs, row = np.unique(run, return_inverse=True)
    out = np.full((runs.size, int(index.max()) + 1), math.nan)
    out[row, index] = values
    return out


def across_run_autocorrelation(values, max_lag: int | None = None) -> np.ndarray:
    """Autocorrelation in time of per-step values, estimated across independent runs.

    Each step's values are standardised across the runs that have it (so a mean or variance
    that changes along the route does not count as correlation); rho(l) is the average of
    ``z_i(k) z_i(k + l)`` over runs i and steps k where both exist.

    Parameters
    ----------
    values : array_like, shape (N, K)
        NaN where a run has no value.
    max_lag : int, optional
        Largest lag; default ``K // 2``.

    Returns
    -------
    numpy.ndarray, shape (max_lag + 1,)
        rho(0) = 1, ..., rho(max_lag); NaN at lags with no pair.
    """
    v = np.asarray(values, dtype=float)
    n, k = v.shape
    max_lag = k // 2 if max_lag is None else min(int(max_lag), k - 1)
    mask = np.isfinite(v)
    count = mask.sum(axis=0)
    filled = np.where(mask, v, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = filled.sum(axis=0) / count
        std = np.sqrt(np.where(mask, (filled - mean) ** 2, 0.0).sum(axis=0) / count)
        z = (filled - mean) / std
    use = mask & (count >= 2) & (std > 0)
    z = np.where(use, z, 0.0)
    m = use.astype(float)
    # Sum over runs of each run's lagged products, by FFT (zero padding keeps lags linear).
    nfft = 1 << int(2 * k - 1).bit_length()
    num, den = np.zeros(max_lag + 1), np.zeros(max_lag + 1)
    for lo in range(0, n, 256):  # bounded memory at 1000 runs
        fz, fm = np.fft.rfft(z[lo:lo + 256], nfft, axis=1), np.fft.rfft(m[lo:lo + 256], nfft, axis=1)
        num += np.fft.irfft((fz * fz.conj()).sum(axis=0), nfft)[:max_lag + 1]
        den += np.fft.irfft((fm * fm.conj()).sum(axis=0), nfft)[:max_lag + 1]
    den = np.rint(den)  # pair counts are integers; the FFT leaves rounding noise
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / np.where(den > 0, den, 1.0), math.nan)


def thinning_spacing(rho, max_corr: float = MAX_THINNED_CORRELATION) -> tuple[int, float]:
    """Smallest spacing L >= 1 with ``|rho(l)| <= max_corr`` at every estimated lag l >= L.

    Parameters
    ----------
    rho : array_like, shape (L_max + 1,)
        Autocorrelation from lag 0 (:func:`across_run_autocorrelation`); NaN lags ignored.
    max_corr : float
        Largest correlation tolerated between tested times.

    Returns
    -------
    spacing : int
        ``len(rho)`` when even the largest estimated lag is too correlated.
    correlation : float
        Largest |rho| at lags >= spacing (0 when there is none).
    """
    r = np.abs(np.asarray(rho, dtype=float))
    over = np.flatnonzero(r[1:] > max_corr)
    spacing = 1 if over.size == 0 else int(over[-1]) + 2
    tail = r[spacing:]
    tail = tail[np.isfinite(tail)]
    return spacing, float(tail.max()) if tail.size else 0.0


def binomial_critical(trials: int, p: float, alpha: float) -> int:
    """Smallest count c with ``P(Binomial(trials, p) >= c) <= alpha`` (fail at ``>= c``)."""
    if not 0.0 < alpha < 1.0:
        raise SimulationError(f"alpha: expected a probability in (0, 1), got {alpha}")
    c = int(stats.binom.ppf(1.0 - alpha, trials, p)) + 1
    while c > 0 and stats.binom.sf(c - 2, trials, p) <= alpha:  # guard against ppf rounding
        c -= 1
    return c


def fraction_outside_band(sums, dofs, alpha: float, spacing: int = 1, correlation: float = 0.0,
                          min_run_fraction: float = MIN_RUN_FRACTION) -> FractionResult:
    """Fraction of tested times whose N-run sum leaves its two-sided chi2 band; binomial verdict.

    Parameters
    ----------
    sums : array_like, shape (N, K)
        Per run and time, a chi2 variable of a consistent filter (NEES, or a fix's NIS sum);
        NaN where the run has none.
    dofs : array_like, shape (N, K)
        Its degrees of freedom (ignored where ``sums`` is NaN).
    alpha : float
        False-alarm probability of the binomial verdict.
    spacing : int
        Test times 0, spacing, 2 spacing, ... (the caller makes them independent).
    correlation : float
        Reported only: the residual correlation at that spacing.
    min_run_fraction : float
        Times reached by fewer runs are not tested.

    Returns
    -------
    FractionResult
        At each tested time the band is ``chi2.ppf((1 -+ 0.95) / 2, D) / N_k`` for the N-run
        average, with ``D`` the summed dofs of the ``N_k`` runs present.
    """
    s = np.asarray(sums, dtype=float)
    d = np.where(np.isfinite(s), np.asarray(dofs, dtype=float), 0.0)
    s, d = s[:, ::spacing], d[:, ::spacing]
    present = np.isfinite(s)
    n_k = present.sum(axis=0)
    keep = (n_k >= max(1, math.ceil(min_run_fraction * s.shape[0]))) & (d.sum(axis=0) > 0)
    if not keep.any():
        raise SimulationError("fraction_outside_band: no time reached by enough runs")
    total, dof, n_k = np.nansum(s, axis=0)[keep], d.sum(axis=0)[keep], n_k[keep]
    tail = (1.0 - BAND_PROBABILITY) / 2.0
    above = total > stats.chi2.isf(tail, dof)
    below = total < stats.chi2.ppf(tail, dof)
    outside, trials = int(np.sum(above | below)), int(keep.sum())
    return FractionResult(outside=outside, above=int(above.sum()), below=int(below.sum()), trials=trials,
                          critical=binomial_critical(trials, 1.0 - BAND_PROBABILITY, alpha),
                          p_value=float(stats.binom.sf(outside - 1, trials, 1.0 - BAND_PROBABILITY)),
                          alpha=alpha, spacing=int(spacing), correlation=float(correlation),
                          runs_min=int(n_k.min()), runs_max=int(n_k.max()), mean=float(np.mean(total / n_k)))


def nees_fraction_test(nees_values, dof: int, alpha: float,
                       max_corr: float = MAX_THINNED_CORRELATION) -> FractionResult:
    """Bar-Shalom's N-run NEES test on steps thinned to be effectively independent.

    Parameters
    ----------
    nees_values : array_like, shape (N, K)
        NEES of N runs at K control steps aligned from the start (:func:`align`), NaN past a
        run's end.
    dof : int
        State dimension d.
    alpha : float
        False-alarm probability.
    max_corr : float
        Residual autocorrelation allowed at the thinning spacing (module docstring).

    Returns
    -------
    FractionResult
    """
    v = np.asarray(nees_values, dtype=float)
    if v.ndim != 2 or v.shape[0] < 2:
        raise SimulationError(f"nees_fraction_test: need (N >= 2, K) values, got shape {v.shape}")
    spacing, corr = thinning_spacing(across_run_autocorrelation(v), max_corr)
    return fraction_outside_band(v, np.full(v.shape, float(dof)), alpha, spacing, corr)


@dataclass(frozen=True)
class PooledResult:
    """Outcome of :func:`pooled_nees_test`.

    Attributes
    ----------
    result : ConsistencyResult
        Statistic (grand mean), interval, verdict; ``n`` is the number of runs.
    dof_effective : float
        Total dof of the scaled chi2 the interval uses (``d N`` when not estimated).
    estimated : bool
        Whether the dof came from the between-run spread (N >= ``MIN_RUNS_FOR_SPREAD``).
    """

    result: ConsistencyResult
    dof_effective: float
    estimated: bool


def pooled_nees_test(run_means, dof: int, alpha: float, min_runs: int = MIN_RUNS_FOR_SPREAD) -> PooledResult:
    """Grand mean of the runs' time-averaged NEES against a between-run moment-matched chi2.

    Parameters
    ----------
    run_means : array_like, shape (N,)
        Each run's time-averaged NEES (NaN ignored).
    dof : int
        State dimension d.
    alpha : float
        False-alarm probability (two-sided, ``alpha / 2`` per tail).
    min_runs : int
        Fewest runs for which the spread sets the interval.

    Returns
    -------
    PooledResult
        The grand mean m is taken as ``d chi2(nu) / nu`` with ``nu = 2 m^2 / V``, V the
        variance of the grand mean from the spread of the runs (sample variance / N). A
        consistent filter's per-step NEES has variance 2d, so V <= 2d / N and nu >= d N: nu is
        floored there (the fully-correlated extreme, also used below ``min_runs``). nu does
        not change when all covariances are scaled, so a mis-scaled filter does not widen its
        own interval.
    """
    v = np.asarray(run_means, dtype=float)
    v = v[np.isfinite(v)]
    n = v.size
    if n == 0:
        raise SimulationError("pooled_nees_test: no finite run mean")
    mean = float(v.mean())
    nu, estimated = float(dof * n), False
    if n >= min_runs:
        var = float(v.var(ddof=1)) / n
        if var > 0:
            nu, estimated = max(nu, 2.0 * mean * mean / var), True
    if not 0.0 < alpha < 1.0:
        raise SimulationError(f"alpha: expected a probability in (0, 1), got {alpha}")
    lo = float(dof * stats.chi2.ppf(alpha / 2, nu) / nu)
    hi = float(dof * stats.chi2.isf(alpha / 2, nu) / nu)
    verdict = Verdict.ABOVE if mean > hi else Verdict.BELOW if mean < lo else Verdict.INSIDE
    return PooledResult(ConsistencyResult(mean, (lo, hi), float(dof), verdict, alpha, n), nu, estimated)
