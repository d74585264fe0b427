"""Filter consistency statistics (NEES, NIS) and their acceptance regions.

A filter is consistent when its errors are as large as its covariance says (Bar-Shalom, Li,
Kirubarajan, *Estimation with Applications to Tracking and Navigation*, ch. 5.4):

- NEES ``e^T P^-1 e`` of a d-dimensional state error is chi2 with d degrees of freedom, so
  the average over n independent samples, times n, is chi2 with n*d dof;
- NIS ``nu^T S^-1 nu`` of an m-dimensional innovation is chi2 with m dof, and the innovations
  of a consistent filter are white, so the average over all updates of all runs is again
  (n*m-dof chi2) / n.

Estimation errors, unlike innovations, are correlated in time within a run. Averaging K
correlated NEES samples of one run keeps the mean d but gives a variance between that of n = 1
(fully correlated) and n = K (independent). :func:`nees_test` therefore counts only the N
independent runs (n = N), the widest of the possible intervals; its false-alarm probability
is then at most about ``alpha`` whatever the correlation in time.

Invalid arguments (alpha outside (0, 1), no samples) raise ``SimulationError``.

A test's verdict is ``INSIDE`` (consistent), ``ABOVE`` (errors larger than claimed: the filter
is overconfident) or ``BELOW`` (errors smaller than claimed: pessimistic).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np
from scipy import stats

from estimators.measurements import wrap_angle
from scenarios.errors import SimulationError


class Verdict(str, Enum):
    """Where a test statistic lies relative to its acceptance region."""

    INSIDE = "inside"
    ABOVE = "above"
    BELOW = "below"


@dataclass(frozen=True)
class ConsistencyResult:
    """Outcome of one two-sided consistency test.

    Attributes
    ----------
    statistic : float
        The observed statistic (average NEES/NIS, or an observed fraction).
    interval : tuple of float
        ``(lo, hi)``: for chi2 tests the acceptance region of ``statistic``; for
        :func:`fraction_test` the Clopper-Pearson confidence interval of the true fraction.
    expected : float
        The value a consistent model gives (the dof, or the nominal fraction).
    verdict : Verdict
        ``INSIDE``, ``ABOVE`` (statistic significantly above ``expected``) or ``BELOW``.
    alpha : float
        False-alarm probability of the test (two-sided).
    n : int
        Number of independent samples the interval assumes.
    """

    statistic: float
    interval: tuple[float, float]
    expected: float
    verdict: Verdict
    alpha: float
    n: int

    @property
    def passed(self) -> bool:
        return self.verdict is Verdict.INSIDE


def _check_alpha(alpha: float) -> None:
    if not 0.0 < alpha < 1.0:
        raise SimulationError(f"alpha: expected a probability in (0, 1), got {alpha}")


def chi2_interval(dof: int, n: int = 1, alpha: float = 0.05) -> tuple[float, float]:
    """Two-sided acceptance interval of the average of ``n`` independent chi2(``dof``) variables.

    Parameters
    ----------
    dof : int
        Degrees of freedom of each sample (the state or measurement dimension).
    n : int
        Number of independent samples averaged.
    alpha : float
        False-alarm probability; each tail gets ``alpha / 2``.

    Returns
    -------
    lo, hi : float
        ``chi2.ppf(alpha/2, n*dof) / n`` and ``chi2.ppf(1 - alpha/2, n*dof) / n``.
    """
    _check_alpha(alpha)
    if dof < 1 or n < 1:
        raise SimulationError(f"chi2_interval: dof and n must be >= 1, got dof={dof}, n={n}")
    total = n * dof
    return float(stats.chi2.ppf(alpha / 2, total) / n), float(stats.chi2.isf(alpha / 2, total) / n)


def nees(errors, covs) -> np.ndarray:
    """Normalised estimation error squared, ``e^T P^-1 e``.

    Parameters
    ----------
    errors : array_like, shape (..., d)
        Estimate minus truth (angles already wrapped, see :func:`pose_errors`).
    covs : array_like, shape (..., d, d)
        The filter's covariances.

    Returns
    -------
    numpy.ndarray, shape (...)
        NEES per sample.
    """
    e = np.asarray(errors, dtype=float)
    sol = np.linalg.solve(np.asarray(covs, dtype=float), e[..., None])[..., 0]
    return np.einsum("...i,...i->...", e, sol)


def nis(innovations, innovation_covs) -> np.ndarray:
    """Normalised innovation squared, ``nu^T S^-1 nu``.

    Parameters
    ----------
    innovations : array_like, shape (...) or (..., m)
        Innovations; a trailing measurement axis may be omitted for scalar measurements.
    innovation_covs : array_like, shape (...) or (..., m, m)
        Innovation variances (scalar case, same shape as ``innovations``) or covariances.

    Returns
    -------
    numpy.ndarray, shape (...)
        NIS per sample.
    """
    y = np.asarray(innovations, dtype=float)
    s = np.asarray(innovation_covs, dtype=float)
    if s.shape == y.shape:
        return y * y / s
    return nees(y, s)


def pose_errors(estimates, truths) -> np.ndarray:
    """Pose estimate minus truth with the heading difference wrapped to (-pi, pi].

    Parameters
    ----------
    estimates, truths : array_like, shape (..., 3)
        Poses (x [m], y [m], theta [rad]).

    Returns
    -------
    numpy.ndarray, shape (..., 3)
        Errors [m, m, rad].
    """
    e = np.asarray(estimates, dtype=float) - np.asarray(truths, dtype=float)
    e[..., 2] = wrap_angle(e[..., 2])
    return e


def _verdict(statistic: float, lo: float, hi: float) -> Verdict:
    if statistic > hi:
        return Verdict.ABOVE
    if statistic < lo:
        return Verdict.BELOW
    return Verdict.INSIDE


def average_test(values, dof: int, alpha: float, n_independent: int | None = None) -> ConsistencyResult:
    """Test the mean of chi2-distributed values against its two-sided chi2 interval.

    Parameters
    ----------
    values : array_like
        NEES or NIS samples, any shape; NaN entries are ignored.
    dof : int
        Degrees of freedom of each sample.
    alpha : float
        False-alarm probability.
    n_independent : int, optional
        Number of independent samples the mean stands for; default: every finite value.

    Returns
    -------
    ConsistencyResult
    """
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        raise SimulationError("average_test: no finite values")
    n = v.size if n_independent is None else int(n_independent)
    lo, hi = chi2_interval(dof, n, alpha)
    stat = float(v.mean())
    return ConsistencyResult(stat, (lo, hi), float(dof), _verdict(stat, lo, hi), alpha, n)


def nees_test(nees_values, dof: int, alpha: float) -> ConsistencyResult:
    """Run- and time-averaged NEES against the interval of N independent runs.

    Parameters
    ----------
    nees_values : array_like, shape (N,) or (N, K)
        NEES of N independent runs at K times (NaN where a run has no sample).
    dof : int
        State dimension d.
    alpha : float
        False-alarm probability.

    Returns
    -------
    ConsistencyResult
        The statistic is the mean over runs of each run's time average; the interval is that
        of N chi2(d) samples, exact for K = 1 and conservative for K > 1 (module docstring).
    """
    v = np.asarray(nees_values, dtype=float)
    per_run = v if v.ndim == 1 else np.nanmean(v.reshape(v.shape[0], -1), axis=1)
    return average_test(per_run, dof, alpha, n_independent=int(np.isfinite(per_run).sum()))


def nis_test(nis_values, dof: int, alpha: float) -> ConsistencyResult:
    """Average NIS over all updates of all runs against its chi2 interval.

    Parameters
    ----------
    nis_values : array_like
        NIS of every update (gated ones included: leaving out the largest values would bias
        the average low); any shape, NaN ignored.
    dof : int
        Measurement dimension m.
    alpha : float
        False-alarm probability.

    Returns
    -------
    ConsistencyResult
        Innovations of a consistent filter are white, so every finite value counts as an
        independent sample.
    """
    return average_test(nis_values, dof, alpha)


def clopper_pearson(k, n, alpha: float):
    """Exact two-sided (1 - alpha) confidence interval of a binomial fraction, elementwise.

    Parameters
    ----------
    k : int or array_like of int
        Successes.
    n : int or array_like of int
        Trials, broadcast against ``k``.
    alpha : float
        One minus the confidence level; each tail gets ``alpha / 2``.

    Returns
    -------
    lo, hi : float, or numpy.ndarray for array input
        Bounds of the true success probability; ``lo = 0`` where ``k = 0`` and ``hi = 1``
        where ``k = n``.
    """
    _check_alpha(alpha)
    k_arr, n_arr = np.asarray(k), np.asarray(n)
    if np.any(n_arr < 1) or np.any(k_arr < 0) or np.any(k_arr > n_arr):
        raise SimulationError(f"clopper_pearson: need 0 <= k <= n and n >= 1, got k={k}, n={n}")
    kf, nf = k_arr.astype(float), n_arr.astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        lo = np.where(kf > 0, stats.beta.ppf(alpha / 2, kf, nf - kf + 1), 0.0)
        hi = np.where(kf < nf, stats.beta.isf(alpha / 2, kf + 1, nf - kf), 1.0)
    if lo.ndim == 0:
        return float(lo), float(hi)
    return lo, hi


def fraction_test(k: int, n: int, expected: float, alpha: float) -> ConsistencyResult:
    """Test whether an observed fraction ``k/n`` matches a nominal probability (e.g. coverage p).

    Parameters
    ----------
    k, n : int
        Successes and trials.
    expected : float
        The nominal success probability.
    alpha : float
        False-alarm probability.

    Returns
    -------
    ConsistencyResult
        ``interval`` is the Clopper-Pearson interval of the true fraction; the verdict is
        ``ABOVE`` when it lies wholly above ``expected``, ``BELOW`` when wholly below.
    """
    lo, hi = clopper_pearson(k, n, alpha)
    if lo > expected:
        verdict = Verdict.ABOVE
    elif hi < expected:
        verdict = Verdict.BELOW
    else:
        verdict = Verdict.INSIDE
    return ConsistencyResult(k / n, (lo, hi), float(expected), verdict, alpha, int(n))
