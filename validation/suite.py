"""Statistical validation of the PEF predictions against a Monte-Carlo sweep (`docs/design.md` §6).

:func:`validate` runs every check of :mod:`validation.checks` on a :class:`SweepData`
(:func:`load_sweep` reads one from a sweep directory) and returns a :class:`ValidationReport`.

Thresholds come from false-alarm probabilities, never from tuning: the family ``alpha`` (the
probability that a sweep of a correct model fails *some* check) is split evenly over the m
statistical checks that apply (Bonferroni: ``alpha / m`` each, so the family's false-alarm
probability is at most ``alpha`` whatever their dependence). ``containment`` and ``bound``
cannot fail when the bounded model holds and take no share. A check whose input is missing
is "not applicable", never a pass.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from scenarios.errors import SimulationError
from validation import outcome
from validation.checks import CHECKS, Check
from validation.data import CheckResult, CheckStatus, SweepData, from_tables, load_sweep

__all__ = ["CHECKS", "CheckResult", "CheckStatus", "SweepData", "ValidationReport", "check_alpha", "from_tables",
           "load_sweep", "validate", "validation_rng"]

DEFAULT_ALPHA = 0.01
"""Family false-alarm probability of ``pefsim validate``."""
NULL_STREAM = 2**32 - 1
"""Spawn key of the null-model stream: run i of a sweep uses ``(i,)``, so this one is apart."""


@dataclass(frozen=True)
class ValidationReport:
    """The checks of one sweep.

    Attributes
    ----------
    scenario : str
        Scenario name.
    source : str
        The sweep directory (or ``<memory>``).
    runs, fixes : int
        Rows in the sweep's tables.
    alpha : float
        Family false-alarm probability.
    statistical : int
        Statistical checks that applied (m).
    alpha_per_check : float or None
        ``alpha / m`` (None when no statistical check applied).
    q_scale : float
        The filter's process-noise factor of the sweep (1 unless a negative control).
    checks : list of CheckResult
    alone : bool
        A fleet sweep whose schedules were planned as if each robot drove alone (a negative control).
    causes : list of str
        One line per cause that made runs fail (contact, stall, deadlock, crash), printed before the
        checks (:func:`validation.outcome.causes`).
    waits : list of str
        A fleet's robots: the plan's longest predicted wait against the simulated ones.
    missing : int
        Runs the sweep was asked for that have not finished (an interrupted sweep).
    blocking_scale : float
        Factor the plan's predicted robot blocking was multiplied by before the checks (1 unless a
        negative control of the ``blocking`` check).
    sweep : str or None
        The sweep directory judged, None when it was a temporary one, deleted since
        (``pefsim.validate_scenario`` without ``out``).
    wall_time : float or None
        Seconds the sweep (if one was run) and the validation took; None: not measured.
    """

    scenario: str
    source: str
    runs: int
    fixes: int
    alpha: float
    statistical: int
    alpha_per_check: float | None
    q_scale: float
    checks: list[CheckResult]
    alone: bool = False
    causes: list[str] = field(default_factory=list)
    waits: list[str] = field(default_factory=list)
    missing: int = 0
    blocking_scale: float = 1.0
    sweep: str | None = None
    wall_time: float | None = None

    @property
    def failed(self) -> list[str]:
        """Names of the failed checks."""
        return [c.name for c in self.checks if c.status is CheckStatus.FAIL]

    @property
    def passed(self) -> bool:
        """No check failed (passes and not-applicable ones only)."""
        return not self.failed

    def check(self, name: str) -> CheckResult:
        """Return the result of check ``name``; raises KeyError when there is none."""
        for c in self.checks:
            if c.name == name:
                return c
        raise KeyError(name)

    def to_dict(self) -> dict[str, Any]:
        return {"scenario": self.scenario, "source": self.source, "runs": self.runs, "fixes": self.fixes,
                "alpha": self.alpha, "statistical_checks": self.statistical,
                "alpha_per_check": self.alpha_per_check, "q_scale": self.q_scale, "alone": self.alone,
                "causes": list(self.causes), "waits": list(self.waits), "missing_runs": self.missing,
                "blocking_scale": self.blocking_scale,
                "passed": self.passed,
                "failed": self.failed, "checks": [c.to_dict() for c in self.checks], "sweep": self.sweep,
                "wall_time": self.wall_time}


def validation_rng(data: SweepData) -> np.random.Generator:
    """Return the null-model generator of a sweep: seeded from its scenario, apart from the runs' streams."""
    return np.random.default_rng(np.random.SeedSequence(data.scenario.seed, spawn_key=(NULL_STREAM,)))


def check_alpha(alpha: float) -> None:
    """Raise a one-line SimulationError unless ``alpha`` is a probability in (0, 1)."""
    if isinstance(alpha, bool) or not (isinstance(alpha, float | int) and 0.0 < alpha < 1.0):
        raise SimulationError(f"alpha: expected a family false-alarm probability in (0, 1), got {alpha!r}")


def validate(data: SweepData, alpha: float = DEFAULT_ALPHA, rng: np.random.Generator | None = None,
             checks: tuple[Check, ...] = CHECKS, blocking_scale: float = 1.0) -> ValidationReport:
    """Run the checks on a sweep.

    Parameters
    ----------
    data : SweepData
        The sweep's scenario and tables.
    alpha : float
        Family false-alarm probability in (0, 1), split Bonferroni over the statistical
        checks that apply.
    rng : numpy.random.Generator, optional
        For the null-model simulation of the tightness check; default :func:`validation_rng`
        (so a sweep always gets the same verdict).
    checks : tuple of Check
        Which checks to run (default all, in report order).
    blocking_scale : float
        NEGATIVE CONTROL ONLY: multiply the plan's predicted robot blocking of every fix by this
        (clipped to 1) before the checks, to see the ``blocking`` check fail on a prediction that
        is off.

    Returns
    -------
    ValidationReport
    """
    if not (isinstance(alpha, float | int) and 0.0 < alpha < 1.0):
        raise SimulationError(f"alpha: expected a family false-alarm probability in (0, 1), got {alpha!r}")
    if not (isinstance(blocking_scale, float | int) and 0.0 < blocking_scale < 1e6):
        raise SimulationError(f"blocking_scale: expected a positive factor, got {blocking_scale!r}")
    check_alpha(alpha)
    rng = rng if rng is not None else validation_rng(data)
    if blocking_scale != 1.0 and data.fixes.p_block_robot is not None:
        fixes = replace(data.fixes, p_block_robot=np.minimum(data.fixes.p_block_robot * blocking_scale, 1.0))
        data = replace(data, fixes=fixes)
    why_not = {c.name: c.why_not(data) for c in checks}
    m = sum(1 for c in checks if c.statistical and why_not[c.name] is None)
    per_check = alpha / m if m else None
    out = []
    for c in checks:
        if why_not[c.name] is not None:
            out.append(CheckResult(c.name, CheckStatus.NOT_APPLICABLE, detail=why_not[c.name]))
        else:
            out.append(c.evaluate(data, per_check if c.statistical else 0.0, rng))
    return ValidationReport(scenario=data.scenario.name, source=data.source, runs=len(data.runs),
                            fixes=len(data.fixes), alpha=float(alpha), statistical=m,
                            alpha_per_check=per_check, q_scale=data.q_scale, checks=out, alone=data.alone,
                            causes=outcome.causes(data), waits=outcome.waits(data), missing=data.missing,
                            blocking_scale=float(blocking_scale))
