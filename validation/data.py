"""What validation reads and returns: a sweep's tables as named numpy arrays, and check results.

A sweep directory (layout in :mod:`sim.montecarlo.results`) is read once into a :class:`SweepData`; the
checks in :mod:`validation.checks` are pure functions of it.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field, replace
from enum import Enum
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

from scenarios import loads
from scenarios.errors import OutputError, ScenarioWarning
from scenarios.jsonable import json_number
from scenarios.schema import Scenario
from sim.montecarlo import lock, results
from sim.montecarlo.directory import read_settings, stored_steps_mode
from sim.montecarlo.negative_control import read_mark
from sim.montecarlo.results import SweepLayout
from sim.montecarlo.steps import StepsMode

EPISODE_GATE_PROBABILITY = 0.999
"""The episode's ``Localizer`` gate (its default ``gate_probability``): a gated update's NIS is
not stored, only that it exceeded ``chi2.ppf(0.999, 1)``."""


class CheckStatus(str, Enum):
    """Verdict of one check."""

    PASS = "pass"
    FAIL = "FAIL"
    NOT_APPLICABLE = "not applicable"


@dataclass(frozen=True)
class CheckResult:
    """Outcome of one validation check.

    Attributes
    ----------
    name : str
        Check name (``containment``, ``bound``, ...).
    status : CheckStatus
    statistic : str
        The observed statistic, formatted ("" when not applicable).
    acceptance : str
        The acceptance region the statistic is compared with.
    alpha : float or None
        False-alarm probability of the check (0 for a check that cannot fail under the
        model; None when not applicable).
    detail : str
        One line: what was compared, how the threshold was derived, or why not applicable.
    values : dict
        The numbers behind the row, JSON-ready (no NaN: None instead).
    """

    name: str
    status: CheckStatus
    statistic: str = ""
    acceptance: str = ""
    alpha: float | None = None
    detail: str = ""
    values: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "status": self.status.value, "statistic": self.statistic,
                "acceptance": self.acceptance, "alpha": self.alpha, "detail": self.detail,
                "values": {k: json_number(v) for k, v in self.values.items()}}


@dataclass(frozen=True)
class RunTable:
    """Per run of a sweep, N runs (crashed runs included, with ``ok`` False).

    Attributes
    ----------
    run : (N,) int
    ok : (N,) bool
        The episode ran to its end (not crashed; it may have collided, stuck or deadlocked).
    succeeded : (N,) bool
        Ran, reached its goal and never exceeded eps_max (:func:`sim.montecarlo.engine.succeeded`).
    mean_nees : (N,) float
        Time-averaged NEES of the pose (3 dof); NaN for a crashed run.
    untested : int
        Finished runs written before the single-failure test existed (``lost_guarantee`` null).
    outcome : pyarrow.Table or None
        What each run did, N rows (:data:`OUTCOME_COLUMNS` that the table has, ``run`` as above):
        its status, contacts, stalls and waits (:mod:`sim.episode.outcome`); None: not given.
    """

    run: np.ndarray
    ok: np.ndarray
    succeeded: np.ndarray
    mean_nees: np.ndarray
    untested: int = 0
    outcome: pa.Table | None = None

    def __len__(self) -> int:
        return len(self.run)


@dataclass(frozen=True)
class FixTable:
    """Per fix of a sweep, F fixes of k markers.

    Attributes
    ----------
    run : (F,) int
    fix : (F,) int
        Index of the fix in its run, from 0.
    true_xy : (F, 2) float
        True position at the fix [m].
    snapshot_xy : (F, 2) float
        Snapshot least-squares position [m].
    snapshot_cov : (F, 2, 2) float
        Its covariance [m^2].
    snapshot_error : (F,) float
        ``|snapshot - truth|`` [m].
    predicted_tau : (F,) float
        The plan's promise for the fix (moving-fix fault-area diameter at the planned poses) [m]
        (inf: no promise).
    contained : (F,) bool
        Truth inside the realised exact fault area.
    fault_diameter : (F,) float
        Realised fault-area diameter [m] (NaN: empty, inconsistent measurements).
    nis : (F,) float
        Sum of the NIS of the fix's accepted updates.
    n_accepted : (F,) int
        Updates that passed the filter's gate.
    markers : (F, k) int
        Marker indices measured (-1 where a marker dropped out of the fix).
    static_tau : (F,) float or None
        The paper's static PEF of the fix's subset at the truth [m] (None: not in the sweep).
    beyond : (F,) bool or None
        Improvised fixes: blocked lines of sight left neither the scheduled subset nor its
        fallback (the plan promised nothing for them).
    unplanned : (F,) bool or None
        Fixes that measured a subset the plan did not schedule; None where the sweep did not
        record it (written before the column existed).
    p_block_robot : (F,) float or None
        Fleets: the plan's probability that another robot hides at least one of the scheduled
        fix's markers at its start (:attr:`planner.fleet.exposure.RobotBlocking.p_fix`); None
        without the column.
    robot_blocked : (F,) bool or None
        Fleets: another robot hid at least one of the scheduled fix's markers at its start
        (``blocked_by_robot_count`` > 0); None without the column.
    """

    run: np.ndarray
    fix: np.ndarray
    true_xy: np.ndarray
    snapshot_xy: np.ndarray
    snapshot_cov: np.ndarray
    snapshot_error: np.ndarray
    predicted_tau: np.ndarray
    contained: np.ndarray
    fault_diameter: np.ndarray
    nis: np.ndarray
    n_accepted: np.ndarray
    markers: np.ndarray
    static_tau: np.ndarray | None = None
    beyond: np.ndarray | None = None
    unplanned: np.ndarray | None = None
    p_block_robot: np.ndarray | None = None
    robot_blocked: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.run)

    @property
    def full(self) -> np.ndarray:
        """(F,) bool: every scheduled marker of the fix was measured."""
        return np.all(self.markers >= 0, axis=1)


@dataclass(frozen=True)
class StepTable:
    """Per control step of a sweep, only what the checks read (S steps over all runs).

    Attributes
    ----------
    run : (S,) int
    step : (S,) int
        Index of the step in its run, from 0 (control steps are at a fixed rate).
    nees : (S,) float
        Pose NEES (3 dof) at the step.
    """

    run: np.ndarray
    step: np.ndarray
    nees: np.ndarray

    def __len__(self) -> int:
        return len(self.run)


STEP_COLUMNS = ["run", "step", "nees"]
"""The columns of :data:`sim.montecarlo.rows.STEP_SCHEMA` that :func:`load_sweep` reads (steps are many)."""
FIX_COLUMNS = ["run", "fix", "true_x", "true_y", "snapshot_x", "snapshot_y", "snapshot_error",
               "snapshot_x_var", "snapshot_y_var", "snapshot_xy_cov", "fault_diameter", "predicted_tau",
               "nis", "n_accepted", "contained", "markers", "beyond_redundancy", "unplanned"]
"""The columns of :data:`sim.montecarlo.rows.FIX_SCHEMA` that the checks read."""
FLEET_BLOCKING_COLUMNS = ["p_block_robot", "blocked_by_robot_count"]
"""The columns of a fleet's fixes (:data:`sim.montecarlo.rows.FLEET_FIX_SCHEMA`) the ``blocking`` check reads."""


@dataclass(frozen=True)
class SweepData:
    """A sweep's scenario and tables, as the checks consume them.

    ``q_scale`` is the filter's process-noise factor the sweep ran with (1 = the declared
    model; anything else is a negative control). ``steps`` is None when the sweep has no
    per-step table (the N-run NEES test then does not apply); ``steps_mode`` is how many
    step rows the sweep kept (``pefsim mc --steps``: all, fixes or none). ``alone``: a fleet's
    schedules were planned as if each robot drove alone (a negative control).
    """

    scenario: Scenario
    runs: RunTable
    fixes: FixTable
    source: str = "<memory>"
    q_scale: float = 1.0
    steps: StepTable | None = None
    steps_mode: str = "all"
    alone: bool = False
    missing: int = 0
    """Runs the sweep was asked for (``sweep.json``) that have not finished: an incomplete sweep."""


def _np(table: pa.Table, name: str, dtype: Any, fill: Any) -> np.ndarray:
    col = table.column(name).fill_null(fill)
    return np.asarray(col.to_numpy(zero_copy_only=False), dtype=dtype)


OUTCOME_COLUMNS = ["run", "task", "robot", "status", "collisions", "contact_t", "contact_x", "contact_y",
                   "contact_s", "contact_with", "stuck", "stall_time", "stuck_bound", "stall_t", "stall_x", "stall_y",
                   "stall_s", "deadlocked", "longest_wait", "wait_bound", "wait_t", "wait_x", "wait_y", "waited_for",
                   "predicted_wait", "predicted_wait_time", "wait_time"]
"""The columns of a runs table that say what each run did (:mod:`validation.outcome` reads them)."""


def run_table(runs: pa.Table) -> RunTable:
    """Convert a ``runs`` table (:data:`sim.montecarlo.rows.RUN_SCHEMA`) to a :class:`RunTable`."""
    from sim.episode.types import ran
    from sim.montecarlo.engine import succeeded

    status = runs.column("status").to_pylist()
    ok = np.array([ran(s) for s in status], dtype=bool)
    return RunTable(run=_np(runs, "run", np.int64, -1), ok=ok,
                    succeeded=np.asarray(succeeded(runs), dtype=bool),
                    mean_nees=_np(runs, "mean_nees", float, math.nan),
                    untested=int(np.sum(ok & np.asarray(runs.column("lost_guarantee").is_null())))
                    if "lost_guarantee" in runs.column_names else 0,
                    outcome=runs.select([c for c in OUTCOME_COLUMNS if c in runs.column_names]))


def fix_table(fixes: pa.Table, k: int) -> FixTable:
    """Convert a ``fixes`` table (:data:`sim.montecarlo.rows.FIX_SCHEMA`) to a :class:`FixTable`."""
    n = fixes.num_rows

    def col(name, dtype=float, fill=math.nan):
        return _np(fixes, name, dtype, fill)

    flat = np.asarray(fixes.column("markers").combine_chunks().flatten().to_numpy(zero_copy_only=False))
    width = flat.size // n if n else k
    cov = np.empty((n, 2, 2))
    cov[:, 0, 0], cov[:, 1, 1] = col("snapshot_x_var"), col("snapshot_y_var")
    cov[:, 0, 1] = cov[:, 1, 0] = col("snapshot_xy_cov")
    return FixTable(
        run=col("run", np.int64, -1), fix=col("fix", np.int64, -1),
        true_xy=np.column_stack([col("true_x"), col("true_y")]).reshape(n, 2),
        snapshot_xy=np.column_stack([col("snapshot_x"), col("snapshot_y")]).reshape(n, 2),
        snapshot_cov=cov, snapshot_error=col("snapshot_error"), predicted_tau=col("predicted_tau"),
        contained=col("contained", bool, False), fault_diameter=col("fault_diameter"),
        nis=col("nis"), n_accepted=col("n_accepted", np.int64, 0),
        markers=flat.astype(np.int64).reshape(n, width),
        static_tau=col("static_tau") if "static_tau" in fixes.column_names else None,
        beyond=(col("beyond_redundancy", bool, False) if "beyond_redundancy" in fixes.column_names
                else np.zeros(n, dtype=bool)),
        unplanned=(None if "unplanned" not in fixes.column_names or fixes.column("unplanned").null_count == n
                   else col("unplanned", bool, False)),
        p_block_robot=col("p_block_robot") if "p_block_robot" in fixes.column_names else None,
        robot_blocked=(col("blocked_by_robot_count", np.int64, 0) > 0
                       if "blocked_by_robot_count" in fixes.column_names else None))


def step_table(steps: pa.Table) -> StepTable:
    """Convert a ``steps`` table (at least :data:`STEP_COLUMNS` of :data:`sim.montecarlo.rows.STEP_SCHEMA`)."""
    return StepTable(run=_np(steps, "run", np.int64, -1), step=_np(steps, "step", np.int64, -1),
                     nees=_np(steps, "nees", float, math.nan))


def fleet_units(scenario: Scenario, table: pa.Table) -> pa.Table:
    """Return a fleet's table with ``run`` replaced by the robot's unit: ``run * n_robots + robot index``.

    The checks group by run (a run's steps and fixes, N-run averages over runs): in a fleet each
    robot of each run is such a unit, with its own filter and its own fixes. A row without a
    robot (a crashed run) counts as the first robot's. Tables without a ``robot`` column are
    returned as they are.
    """
    if "robot" not in table.column_names or not scenario.robots:
        return table
    index = {r.name: j for j, r in enumerate(scenario.robots)}
    robot = np.array([index.get(name, 0) for name in table.column("robot").to_pylist()], dtype=np.int64)
    run = _np(table, "run", np.int64, -1)
    unit = np.where(run >= 0, run * len(scenario.robots) + robot, -1)
    return table.set_column(table.column_names.index("run"), "run", pa.array(unit, type=pa.int64()))


def from_tables(scenario: Scenario, runs: pa.Table, fixes: pa.Table, source: str = "<memory>",
                q_scale: float = 1.0, steps: pa.Table | None = None) -> SweepData:
    """Build :class:`SweepData` from Arrow tables of the :mod:`sim.montecarlo.results` schemas (``steps`` optional).

    A fleet's tables (a ``robot`` column) are judged per robot and run (:func:`fleet_units`).
    """
    runs, fixes = fleet_units(scenario, runs), fleet_units(scenario, fixes)
    steps = None if steps is None else fleet_units(scenario, steps)
    return SweepData(scenario=scenario, runs=run_table(runs),
                     fixes=fix_table(fixes, scenario.sensor.markers_per_fix), source=source, q_scale=q_scale,
                     steps=None if steps is None or steps.num_rows == 0 else step_table(steps))


def load_sweep(directory: str | Path, scenario: Scenario | None = None) -> SweepData:
    """Read sweep directory ``directory`` (written by :func:`sim.montecarlo.engine.sweep`).

    Parameters
    ----------
    directory : path
        The sweep directory.
    scenario : Scenario, optional
        When given, the directory must have been made from exactly this scenario text.

    Returns
    -------
    SweepData
        With the scenario parsed from ``directory/scenario.toml``.

    Raises
    ------
    OutputError
        Not a sweep directory, locked by a live writer, no finished run, or made from another
        scenario.
    """
    layout = SweepLayout(Path(directory))
    try:
        lock.check_free(layout.root)  # a sweep still being written is not yet the tables it will be
    except OutputError as exc:
        raise OutputError(f"{exc}: validate it once that sweep has finished") from None
    try:
        text = layout.scenario_toml.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        raise OutputError(f"{directory}: not a pefsim mc directory (no readable scenario.toml)") from None
    if scenario is not None and text != scenario.text:
        raise OutputError(f"{directory}: was made from another scenario (its scenario.toml differs from "
                          f"{scenario.source})")
    with warnings.catch_warnings():
        if scenario is not None:  # its own text: its warnings were said when it was loaded
            warnings.simplefilter("ignore", ScenarioWarning)
        stored = loads(text, source=str(layout.scenario_toml))
    runs = results.read_runs(layout.root)
    if runs.num_rows == 0:
        raise OutputError(f"{directory}: holds no finished run")
    q_scale, alone = read_mark(layout.root)
    # A directory assembled by hand may lack sweep.json: it then holds whatever steps it has.
    settings = read_settings(layout.root) if layout.sweep_json.exists() else {}
    mode = stored_steps_mode(settings)
    missing = max(int(settings.get("runs", 0)) - len(results.finished_runs(layout)), 0)
    # Only a sweep of every step feeds the N-run NEES test (the only reader of steps here), so
    # the others' step rows are not read at all.
    # the robot columns the tables have (a fleet's; a lone robot's have none)
    sch = results.sweep_schemas(layout.root)
    robot = [c for c in ("robot",) if c in sch.steps.names]
    blocking = [c for c in FLEET_BLOCKING_COLUMNS if c in sch.fixes.names]
    steps = results.read_steps(layout.root, columns=STEP_COLUMNS + robot) if mode is StepsMode.ALL else None
    data = from_tables(stored, runs, results.read_fixes(layout.root, columns=FIX_COLUMNS + robot + blocking),
                       source=str(directory), q_scale=q_scale, steps=steps)
    return replace(data, steps_mode=mode.value, alone=alone, missing=missing)
