"""What a sweep directory holds, counted: :class:`SweepSummary` (``pefsim mc`` prints it)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

from sim.montecarlo import results


@dataclass
class SweepSummary:
    """What a sweep directory holds, as ``pefsim mc --json`` prints it.

    A run succeeds when it ran (status ok), reached its goal and never exceeded ε_max;
    crashed runs count as failures, and so do runs that collided, stuck or deadlocked (their status
    says so; ``ok`` counts the runs that did none of that). ``success_ci`` is the 95 % Clopper-Pearson
    interval.
    """

    out: str
    runs: int
    ok: int
    crashed: int
    reached: int
    violation_runs: int
    successes: int
    success_fraction: float | None
    success_ci: list[float] | None
    success_target: float
    executed: int
    wall_time: float
    runs_per_minute: float | None
    steps: str = "all"
    """The sweep's steps mode (:class:`~sim.montecarlo.steps.StepsMode`)."""
    bytes_per_run: dict[str, int] = field(default_factory=dict)
    """Mean bytes per finished run of its ``runs``, ``steps`` and ``fixes`` parts, and ``total``."""
    report: str | None = None
    """The HTML report written into ``out`` (``pefsim mc``, :func:`pefsim.sweep`), None without one."""
    robots: int = 0
    """A fleet sweep's robots per run (its counts above are of robot rows, one per robot per run);
    0 for a single robot."""
    collisions: int = 0
    """Contact episodes summed over the rows (a fleet's robot-robot contact counts for both robots)."""
    collided: int = 0
    """Rows whose status is ``collided`` (touched something, :mod:`sim.episode.outcome`)."""
    stuck: int = 0
    """Rows whose status is ``stuck``."""
    deadlocked: int = 0
    """Rows whose status is ``deadlocked``."""

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        if not self.robots:
            del d["robots"]
        return d


def succeeded(runs: pa.Table) -> np.ndarray:
    """Per row of a runs table: ran (status ok), reached its goal and never exceeded ε_max.

    With lines of sight blocked (``sensor.block_probability`` > 0) a run must also pass the
    single-failure test: its certified bound stayed under ε_max wherever no more lines of sight
    were lost at a fix than one (column ``lost_guarantee``,
    :func:`sim.episode.certify.single_failure_excused`; 0 without blocking). A run that touched
    anything but the floor (``collisions``), stuck or deadlocked has another status than ``ok`` and
    fails (:mod:`sim.episode.outcome`).
    """
    status = np.asarray(runs.column("status").to_pylist(), dtype=object)
    reached = np.asarray(runs.column("reached").fill_null(False).to_numpy(zero_copy_only=False), dtype=bool)
    violations = np.asarray(runs.column("violations").fill_null(0).to_numpy(zero_copy_only=False))
    lost = (np.asarray(runs.column("lost_guarantee").fill_null(0).to_numpy(zero_copy_only=False))
            if "lost_guarantee" in runs.column_names else np.zeros(len(status), dtype=np.int64))
    hit = (np.asarray(runs.column("collisions").fill_null(0).to_numpy(zero_copy_only=False))
           if "collisions" in runs.column_names else np.zeros(len(status), dtype=np.int64))
    return (status == "ok") & reached & (violations == 0) & (lost == 0) & (hit == 0)


def summarize(out: str | Path, success_target: float, executed: int = 0,
              wall_time: float = 0.0, steps: str = "all", bytes_per_run: dict[str, int] | None = None) -> SweepSummary:
    """Count the finished runs of sweep directory ``out``."""
    from scipy.stats import binomtest

    from sim.episode.types import ran

    table = results.read_runs(out)
    status = np.asarray(table.column("status").to_pylist(), dtype=object)
    ok = np.array([ran(s) for s in status], dtype=bool).reshape(-1)
    reached = np.asarray(table.column("reached").fill_null(False).to_numpy(zero_copy_only=False), dtype=bool)
    violations = np.asarray(table.column("violations").fill_null(0).to_numpy(zero_copy_only=False))
    n = len(status)
    k = int(succeeded(table).sum())
    fraction = ci = None
    if n:
        fraction = k / n
        interval = binomtest(k, n).proportion_ci(confidence_level=0.95, method="exact")
        ci = [float(interval.low), float(interval.high)]
    rate = 60.0 * executed / wall_time if executed and wall_time > 0 else None
    hits = table.column("collisions").fill_null(0).to_numpy(zero_copy_only=False) if n else np.zeros(0)
    return SweepSummary(out=str(out), runs=n, ok=int(np.sum(status == "ok")), crashed=int(np.sum(~ok)),
                        reached=int((reached & ok).sum()), violation_runs=int(np.sum(ok & (violations > 0))),
                        successes=k, success_fraction=fraction, success_ci=ci, success_target=success_target,
                        executed=executed, wall_time=wall_time, runs_per_minute=rate, steps=steps,
                        bytes_per_run=dict(bytes_per_run or {}), collisions=int(np.sum(hits)),
                        collided=int(np.sum(status == "collided")), stuck=int(np.sum(status == "stuck")),
                        deadlocked=int(np.sum(status == "deadlocked")), **_fleet_counts(table))


def _fleet_counts(table: pa.Table) -> dict[str, int]:
    """Robots per run of a fleet's runs table (nothing for a single robot's)."""
    if "robot" not in table.column_names or table.num_rows == 0:
        return {}
    names = {n for n in table.column("robot").to_pylist() if n is not None}
    return {"robots": len(names)}
