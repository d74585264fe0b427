"""What a sweep stores per run, step and fix: the Parquet schemas and the rows built from an episode.

:mod:`sim.montecarlo.results` writes and reads them (and re-exports every name here).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pyarrow as pa

from sim.episode.types import FixLog, StepLog
from sim.montecarlo import parts
from sim.montecarlo.steps import StepsMode

RUN_SCHEMA = pa.schema([
    ("run", pa.int64()),
    ("seed", pa.string()),          # the run's SeedSequence, as Python that rebuilds it
    ("task", pa.int32()),
    ("status", pa.string()),        # ok, collided, stuck, deadlocked (the worst) or "crashed: <error>"
    ("reached", pa.bool_()),
    ("duration", pa.float64()),     # simulated time [s]
    ("steps", pa.int64()),
    ("fixes", pa.int64()),
    ("rmse", pa.float64()),         # [m]
    ("max_error", pa.float64()),    # [m]
    ("max_predicted_tau", pa.float64()),  # [m]
    ("eps_max", pa.float64()),      # [m]
    ("violations", pa.int64()),
    ("mean_nees", pa.float64()),
    ("mean_nis", pa.float64()),
    ("blocked_markers", pa.int64()),   # scheduled markers whose line of sight was blocked
    ("fallback_fixes", pa.int64()),    # fixes that measured the schedule's fallback subset
    ("failed_fixes", pa.int64()),      # scheduled fixes that could not be taken
    ("certified_max", pa.float64()),   # [m] largest certified bound (sim.episode.certify)
    ("lost_guarantee", pa.int64()),    # steps the single-failure test judged lost (blocking only)
    # what the run did (sim.episode.outcome): contact episodes of the body with anything but the floor,
    # the first one's time [s], true position [m], arc length along the plan [m] and what it touched
    ("collisions", pa.int64()),
    ("contact_t", pa.float64()), ("contact_x", pa.float64()), ("contact_y", pa.float64()),
    ("contact_s", pa.float64()), ("contact_with", pa.string()),
    # no progress along the path for longer than stuck_bound [s]; the longest stall [s] and where it began
    ("stuck", pa.bool_()), ("stall_time", pa.float64()), ("stuck_bound", pa.float64()),
    ("stall_t", pa.float64()), ("stall_x", pa.float64()), ("stall_y", pa.float64()), ("stall_s", pa.float64()),
    ("deadlocked", pa.bool_()),        # a fleet robot waited for a zone past its bound (never a lone one)
    ("wall_time", pa.float64()),    # [s] of the episode call
    ("cpu_time", pa.float64()),     # [s] CPU time of the worker process during the episode call
])
"""One row per run. Numeric columns are null for a crashed run."""

TIMING_COLUMNS = ("wall_time", "cpu_time")
"""The columns of :data:`RUN_SCHEMA` that depend on the machine, not on the seed."""

STEP_SCHEMA = pa.schema([
    ("run", pa.int64()), ("step", pa.int32()), ("t", pa.float64()),
    ("true_x", pa.float64()), ("true_y", pa.float64()), ("true_theta", pa.float64()),
    ("est_x", pa.float64()), ("est_y", pa.float64()), ("est_theta", pa.float64()),
    ("error", pa.float64()), ("predicted_tau", pa.float64()), ("pef_tau", pa.float64()),
    ("nees", pa.float64()),
    ("x_var", pa.float64()), ("y_var", pa.float64()), ("theta_var", pa.float64()),
    ("xy_cov", pa.float64()), ("xtheta_cov", pa.float64()), ("ytheta_cov", pa.float64()),
    ("certified", pa.float64()),   # the bound the fixes taken certify [m] (sim.episode.certify)
    ("excused", pa.bool_()),       # not judged by the single-failure test (too many lines of sight lost)
])
"""One row per control step: poses [m, rad], errors and bounds [m], EKF covariance terms (as read)."""
STEP_STORAGE = parts.lean(STEP_SCHEMA)
"""How step parts are stored: the floats of :data:`STEP_SCHEMA` as float32 (:mod:`sim.montecarlo.parts`)."""


FIX_SCHEMA = pa.schema([
    ("run", pa.int64()), ("fix", pa.int32()), ("t", pa.float64()),
    ("true_x", pa.float64()), ("true_y", pa.float64()),
    ("snapshot_x", pa.float64()), ("snapshot_y", pa.float64()),
    ("snapshot_error", pa.float64()),   # |snapshot - true position| [m]
    ("snapshot_x_var", pa.float64()), ("snapshot_y_var", pa.float64()), ("snapshot_xy_cov", pa.float64()),
    ("fault_diameter", pa.float64()), ("predicted_tau", pa.float64()),   # the plan's promise
    ("static_tau", pa.float64()),                                        # the paper's static PEF
    ("nis", pa.float64()), ("n_accepted", pa.int32()), ("contained", pa.bool_()),
    ("markers", pa.list_(pa.int32())),   # marker indices in scenario file order
    ("ranges", pa.list_(pa.float64())), ("rho", pa.list_(pa.float64())),
    ("fallback", pa.bool_()),            # measured the schedule's fallback subset
    ("beyond_redundancy", pa.bool_()),   # improvised: blocks left neither the subset nor its fallback
    ("unplanned", pa.bool_()),           # measured a subset the plan did not schedule (null: not recorded)
])
"""One row per fix: true and snapshot positions [m], realised and predicted bounds [m], NIS."""


FLEET_RUN_SCHEMA = pa.schema([*RUN_SCHEMA, pa.field("robot", pa.string()),
                              pa.field("arrival", pa.float64()),     # [s] when it reached its final dock
                              pa.field("wait_time", pa.float64()),   # [s] waiting for zones
                              pa.field("robot_blocked", pa.int64()),  # scheduled lines of sight robots hid
                              # its longest unbroken wait for a zone [s], the bound it was held to [s],
                              # where and when it began, whom it waited for; the plan's longest wait and
                              # all its planned waits together [s]
                              pa.field("longest_wait", pa.float64()), pa.field("wait_bound", pa.float64()),
                              pa.field("wait_t", pa.float64()), pa.field("wait_x", pa.float64()),
                              pa.field("wait_y", pa.float64()), pa.field("waited_for", pa.string()),
                              pa.field("predicted_wait", pa.float64()),
                              pa.field("predicted_wait_time", pa.float64())])
"""A fleet sweep's runs table: :data:`RUN_SCHEMA` plus the robot, one row per robot per run (its
``duration`` is the fleet's episode, ``arrival`` the robot's own end; NaN if it never arrived)."""
FLEET_STEP_SCHEMA = pa.schema([*STEP_SCHEMA, pa.field("robot", pa.string())])
"""A fleet sweep's steps table: :data:`STEP_SCHEMA` plus the robot."""
FLEET_STEP_STORAGE = parts.lean(FLEET_STEP_SCHEMA)
FLEET_FIX_SCHEMA = pa.schema([*FIX_SCHEMA, pa.field("robot", pa.string()),
                              pa.field("blocked_by_robot", pa.string()),       # scheduled marker ids robots hid
                              pa.field("blocked_by_robot_count", pa.int32()),
                              pa.field("blocking_robots", pa.string()),       # which robot hid each of them
                              pa.field("p_block_robot", pa.float64()),        # the plan's probability of a hidden one
                              pa.field("sight_blocked_by_robot", pa.string()),  # every marker id robots hid
                              pa.field("sight_blocked_by_robot_count", pa.int32())])
"""A fleet sweep's fixes table: :data:`FIX_SCHEMA` plus the robot and the scheduled lines of sight other
robots hid at the fix start (``blocked_by_robot``: comma-joined marker ids, ``blocking_robots``: the robots
that hid them, in the same order; ``blocked_by_robot_count``: how many), the plan's probability that a
robot hides at least one scheduled marker at the fix start (NaN: none), and every line of sight, scheduled
or not, that another robot hid at the fix start where the laser would have seen the marker without the
robots (``sight_blocked_by_robot``, ``sight_blocked_by_robot_count``: in range, facing, no wall on the
way; :meth:`sim.physics.laser.LaserSensor.hidden_by_robots`)."""


@dataclass(frozen=True)
class Schemas:
    """The table schemas of a sweep: a single robot's or a fleet's."""

    runs: pa.Schema
    steps: pa.Schema
    step_storage: pa.Schema
    fixes: pa.Schema


SINGLE = Schemas(RUN_SCHEMA, STEP_SCHEMA, STEP_STORAGE, FIX_SCHEMA)
FLEET = Schemas(FLEET_RUN_SCHEMA, FLEET_STEP_SCHEMA, FLEET_STEP_STORAGE, FLEET_FIX_SCHEMA)


def schemas(fleet: bool) -> Schemas:
    """Return the schemas of a fleet sweep (``fleet``) or of a single robot's."""
    return FLEET if fleet else SINGLE


def table_schemas(scenario: Any) -> Schemas:
    """Return the schemas of ``scenario``'s sweeps: with a robot column when it names its robots (``[[robots]]``).

    A lone robot's tables are a fleet of one's without the columns it never has (its name, the
    waits and the lines of sight other robots hid).
    """
    return schemas(bool(scenario.robots))


def robot_tables(run: int, seed: str, robot: Any, sch: Schemas, mode: StepsMode, marker_ids: list[str],
                 names: list[str], wall_time: float | None,
                 cpu_time: float | None) -> tuple[dict[str, Any], dict[str, np.ndarray] | None, dict[str, np.ndarray]]:
    """Return one robot's runs row, step columns (None: not kept) and fix columns of run ``run``.

    ``robot`` is a :class:`~sim.episode.types.RobotResult`; a named one (a fleet's) also gets the
    robot columns of ``sch`` (:func:`fleet_fix_columns`), ``names`` being the fleet's robots in order.
    """
    res = robot.result
    row = run_row(run, seed, res.task_index, res.summary, wall_time, cpu_time=cpu_time, schema=sch.runs)
    steps = step_columns(run, res.steps, mode, res.fixes.t)
    if robot.name is None:
        return row, steps, fix_columns(run, res.fixes)
    if steps is not None:
        steps["robot"] = np.array([robot.name] * len(steps["run"]), dtype=object)
    return row, steps, fleet_fix_columns(run, res.fixes, robot.name, marker_ids, names)


# -- building rows ------------------------------------------------------------------------

def run_row(run: int, seed: str, task: int, summary: dict[str, Any] | None, wall_time: float | None,
            status: str = "ok", cpu_time: float | None = None, schema: pa.Schema = RUN_SCHEMA) -> dict[str, Any]:
    """Build the ``runs`` row of one run from an episode summary (``None`` for a crashed run)."""
    row: dict[str, Any] = {name: None for name in schema.names}
    if summary is not None and "status" in summary:
        status = summary["status"]   # what the run did (sim.episode.outcome)
    row.update(run=run, seed=seed, task=task, status=status, wall_time=wall_time, cpu_time=cpu_time)
    if summary is not None:
        for name in schema.names:
            if name in summary and name not in ("run", "seed", "task", "status", *TIMING_COLUMNS):
                row[name] = _scalar(summary[name])
    return row


def _scalar(v: Any) -> Any:
    return v.item() if isinstance(v, np.generic) else v


def fix_steps(step_t: np.ndarray, fix_t: np.ndarray) -> np.ndarray:
    """Return the indices of the steps at or after each fix time (the first step whose filter holds the fix), unique."""
    step_t = np.asarray(step_t, dtype=float)
    idx = np.searchsorted(step_t, np.asarray(fix_t, dtype=float), side="left")
    return np.unique(idx[idx < step_t.size])


def step_columns(run: int, steps: StepLog, mode: StepsMode = StepsMode.ALL,
                 fix_t: np.ndarray | None = None) -> dict[str, np.ndarray] | None:
    """Per-step columns of :data:`STEP_SCHEMA` from an episode's :class:`StepLog`, as ``mode`` keeps them.

    ``fix_t`` (the fix times [s]) selects the rows of :attr:`StepsMode.FIXES`; None for :attr:`StepsMode.NONE`.
    """
    mode = StepsMode(mode)
    if mode is StepsMode.NONE:
        return None
    n = len(steps.t)
    keep = np.arange(n) if mode is StepsMode.ALL else fix_steps(steps.t, np.zeros(0) if fix_t is None else fix_t)
    cols = _all_step_columns(run, steps, n)
    return {k: v[keep] for k, v in cols.items()}


def _all_step_columns(run: int, steps: StepLog, n: int) -> dict[str, np.ndarray]:
    tp, ep, cov = np.asarray(steps.true_pose), np.asarray(steps.est_pose), np.asarray(steps.est_cov)
    tp, ep, cov = tp.reshape(n, 3), ep.reshape(n, 3), cov.reshape(n, 3, 3)
    return {
        "run": np.full(n, run, dtype=np.int64), "step": np.arange(n, dtype=np.int32),
        "t": np.asarray(steps.t, dtype=float),
        "true_x": tp[:, 0], "true_y": tp[:, 1], "true_theta": tp[:, 2],
        "est_x": ep[:, 0], "est_y": ep[:, 1], "est_theta": ep[:, 2],
        "error": np.asarray(steps.error, dtype=float),
        "predicted_tau": np.asarray(steps.predicted_tau, dtype=float),
        "pef_tau": np.asarray(steps.pef_tau, dtype=float),
        "nees": np.asarray(steps.nees, dtype=float),
        "x_var": cov[:, 0, 0], "y_var": cov[:, 1, 1], "theta_var": cov[:, 2, 2],
        "xy_cov": cov[:, 0, 1], "xtheta_cov": cov[:, 0, 2], "ytheta_cov": cov[:, 1, 2],
        "certified": (np.full(n, np.nan) if steps.certified is None
                      else np.asarray(steps.certified, dtype=float).reshape(n)),
        "excused": (np.zeros(n, dtype=bool) if steps.excused is None else np.asarray(steps.excused, bool).reshape(n)),
    }


def fix_columns(run: int, fixes: FixLog) -> dict[str, np.ndarray]:
    """Per-fix columns of :data:`FIX_SCHEMA` from an episode's :class:`FixLog`."""
    n = len(fixes.t)
    truth = np.asarray(fixes.true_position, dtype=float).reshape(n, 2)
    snap = np.asarray(fixes.snapshot, dtype=float).reshape(n, 2)
    scov = np.asarray(fixes.snapshot_cov, dtype=float).reshape(n, 2, 2)
    return {
        "run": np.full(n, run, dtype=np.int64), "fix": np.arange(n, dtype=np.int32),
        "t": np.asarray(fixes.t, dtype=float),
        "true_x": truth[:, 0], "true_y": truth[:, 1],
        "snapshot_x": snap[:, 0], "snapshot_y": snap[:, 1],
        "snapshot_error": np.hypot(snap[:, 0] - truth[:, 0], snap[:, 1] - truth[:, 1]),
        "snapshot_x_var": scov[:, 0, 0], "snapshot_y_var": scov[:, 1, 1], "snapshot_xy_cov": scov[:, 0, 1],
        "fault_diameter": np.asarray(fixes.fault_diameter, dtype=float),
        "predicted_tau": np.asarray(fixes.predicted_tau, dtype=float),
        "static_tau": np.asarray(fixes.static_tau, dtype=float),
        "nis": np.asarray(fixes.nis, dtype=float),
        "n_accepted": np.asarray(fixes.n_accepted, dtype=np.int32),
        "contained": np.asarray(fixes.contained, dtype=bool),
        "markers": _matrix(fixes.markers, n, np.int32),
        "ranges": _matrix(fixes.ranges, n, np.float64),
        "rho": _matrix(fixes.rho, n, np.float64),
        "fallback": (np.zeros(n, dtype=bool) if fixes.fallback is None
                     else np.asarray(fixes.fallback, dtype=bool).reshape(n)),
        "beyond_redundancy": (np.zeros(n, dtype=bool) if fixes.beyond_redundancy is None
                              else np.asarray(fixes.beyond_redundancy, dtype=bool).reshape(n)),
        "unplanned": (np.zeros(n, dtype=bool) if fixes.unplanned is None
                      else np.asarray(fixes.unplanned, dtype=bool).reshape(n)),
    }


def fleet_fix_columns(run: int, fixes: FixLog, robot: str, marker_ids: list[str],
                      robot_names: list[str]) -> dict[str, np.ndarray]:
    """Per-fix columns of :data:`FLEET_FIX_SCHEMA`: :func:`fix_columns` plus the robot and what robots hid.

    ``fixes.notes[f]`` (a :class:`~sim.episode.types.FixNote`) maps each scheduled marker another
    robot hid at fix f's start to that robot's index, likewise every marker in sight a robot hid,
    and carries the plan's blocking probability (:mod:`sim.episode.fleet`).
    """
    cols = fix_columns(run, fixes)
    n = len(fixes.t)
    notes = fixes.notes if fixes.notes is not None else [None] * n
    hidden = [sorted(note.hidden.items()) if note is not None else [] for note in notes]
    cols["p_block_robot"] = np.array([note.p_block_robot if note is not None else np.nan for note in notes],
                                     dtype=float)
    cols["robot"] = np.array([robot] * n, dtype=object)
    cols["blocked_by_robot"] = np.array([",".join(marker_ids[m] for m, _ in h) for h in hidden], dtype=object)
    cols["blocked_by_robot_count"] = np.array([len(h) for h in hidden], dtype=np.int32)
    cols["blocking_robots"] = np.array([",".join(robot_names[j] for _, j in h) for h in hidden], dtype=object)
    sight = [sorted(note.sight_hidden) if note is not None else [] for note in notes]
    cols["sight_blocked_by_robot"] = np.array([",".join(marker_ids[m] for m in h) for h in sight], dtype=object)
    cols["sight_blocked_by_robot_count"] = np.array([len(h) for h in sight], dtype=np.int32)
    return cols


def concat_columns(parts_: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """Concatenate column dicts of the same keys (the robots of one fleet run)."""
    return {k: np.concatenate([p[k] for p in parts_]) for k in parts_[0]}


def _table(columns: dict[str, np.ndarray], schema: pa.Schema) -> pa.Table:
    arrays = []
    for f in schema:
        col = columns[f.name]
        if pa.types.is_list(f.type):
            n, k = col.shape
            offsets = pa.array(np.arange(n + 1, dtype=np.int32) * k)
            values = pa.array(col.reshape(-1), type=f.type.value_type)
            arrays.append(pa.ListArray.from_arrays(offsets, values))
        else:
            arrays.append(pa.array(col, type=f.type))
    return pa.Table.from_arrays(arrays, schema=schema)


def _matrix(a: Any, n: int, dtype: type) -> np.ndarray:
    """Return ``a`` as an (n, k) array, also when a fix log is empty and came as a flat array."""
    a = np.asarray(a, dtype=dtype)
    return a.reshape(n, -1) if a.size else np.zeros((n, a.shape[1] if a.ndim == 2 else 0), dtype)
