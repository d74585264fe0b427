"""Monte-Carlo results on disk: the Parquet schema, atomic per-run parts, and reading them back.

Layout of a sweep directory ``DIR``::

    DIR/scenario.toml        the exact scenario text the sweep ran (``--resume`` checks it)
    DIR/sweep.json           sweep settings that must not change on resume (task, runs, steps),
                             and the bytes per run of the parts
    DIR/.lock                while a process writes the directory (:mod:`sim.montecarlo.lock`)
    DIR/damaged/             parts that did not read back, moved aside on --resume
    DIR/runs/run-NNNNNN.parquet    one row per finished run: the commit log of the sweep
    DIR/steps/run-NNNNNN.parquet   per-step rows of that run
    DIR/fixes/run-NNNNNN.parquet   per-fix rows of that run
    DIR/recordings/run-NNNNNN.rrd  optional rerun recordings
    DIR/runs.parquet         all rows of runs/ in one file, rewritten at the end of every sweep
    DIR/report.html, DIR/figures/*.png

A run counts as finished when its ``runs/`` part exists. That part is written last (after its
steps, fixes and recording), each file through a temporary name and ``os.replace``, so a sweep
killed at any instant leaves only whole files, never a half-written run counted as done, and
never a run twice (parts are named by run index). Step and fix parts of unfinished runs are
ignored by the readers here and deleted by :func:`clean_unfinished` before a resume.

How much of the per-step log a sweep keeps is its :class:`StepsMode` (``--steps``), recorded
in ``sweep.json``: every control step (``all``, the default), the step at or after each fix
(``fixes``: what the report and most checks need, ~8 % of the rows), or none. The on-disk
encoding (float32 steps, zstd) and what it gives up are in :mod:`sim.montecarlo.parts`.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

from scenarios.errors import OutputError, output_errors
from sim.episode.types import FixLog, StepLog
from sim.montecarlo import parts
from sim.montecarlo.steps import StepsMode, steps_mode  # noqa: F401  (re-exported)

RUN_SCHEMA = pa.schema([
    ("run", pa.int64()),
    ("seed", pa.string()),          # the run's SeedSequence, as Python that rebuilds it
    ("task", pa.int32()),
    ("status", pa.string()),        # "ok" or "crashed: <error>"
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
])
"""One row per fix: true and snapshot positions [m], realised and predicted bounds [m], NIS."""

_PART = re.compile(r"^run-(\d+)\.parquet$")


@dataclass(frozen=True)
class SweepLayout:
    """The paths of one sweep directory (see the module docstring)."""

    root: Path

    @property
    def scenario_toml(self) -> Path:
        return self.root / "scenario.toml"

    @property
    def sweep_json(self) -> Path:
        return self.root / "sweep.json"

    @property
    def runs_dir(self) -> Path:
        return self.root / "runs"

    @property
    def steps_dir(self) -> Path:
        return self.root / "steps"

    @property
    def fixes_dir(self) -> Path:
        return self.root / "fixes"

    @property
    def recordings_dir(self) -> Path:
        return self.root / "recordings"

    @property
    def damaged_dir(self) -> Path:
        return self.root / "damaged"

    @property
    def runs_parquet(self) -> Path:
        return self.root / "runs.parquet"

    @property
    def report_html(self) -> Path:
        return self.root / "report.html"

    @property
    def figures_dir(self) -> Path:
        return self.root / "figures"

    def part(self, folder: Path, run: int, suffix: str = ".parquet") -> Path:
        """Path of run ``run``'s part in ``folder``."""
        return folder / f"run-{run:06d}{suffix}"

    def check_writable(self) -> None:
        """Create the directory itself (not its tree) and write a probe; raises OutputError if impossible."""
        probe = self.root / f".probe{os.getpid()}"
        with output_errors(self.root, "create the output directory"):
            self.root.mkdir(parents=True, exist_ok=True)
            probe.write_bytes(b"")
            probe.unlink()

    def make_dirs(self) -> None:
        """Create the directory tree; raises OutputError when that is impossible."""
        with output_errors(self.root, "create the output directory"):
            for d in (self.root, self.runs_dir, self.steps_dir, self.fixes_dir):
                d.mkdir(parents=True, exist_ok=True)


@dataclass
class RunRecord:
    """What one run hands back for writing: its summary row, step and fix columns, a recording.

    ``fatal`` carries a PefsimError raised by the episode (bad input): the sweep stops on it.
    ``warning`` is a one-line note for the user (a recording that could not be written).
    """

    run: int
    row: dict[str, Any]
    steps: dict[str, np.ndarray] | None = None
    fixes: dict[str, np.ndarray] | None = None
    recording: bytes | None = None
    fatal: Exception | None = None
    warning: str | None = None


# -- building rows ------------------------------------------------------------------------

def run_row(run: int, seed: str, task: int, summary: dict[str, Any] | None, wall_time: float | None,
            status: str = "ok", cpu_time: float | None = None) -> dict[str, Any]:
    """Build the ``runs`` row of one run from an episode summary (``None`` for a crashed run)."""
    row: dict[str, Any] = {name: None for name in RUN_SCHEMA.names}
    row.update(run=run, seed=seed, task=task, status=status, wall_time=wall_time, cpu_time=cpu_time)
    if summary is not None:
        for name in RUN_SCHEMA.names:
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
    }


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


# -- writing ----------------------------------------------------------------------------

def write_atomic(path: Path, data: bytes | pa.Table) -> None:
    """Write ``data`` (bytes, or a table as Parquet, :func:`sim.montecarlo.parts.write_parquet`) to ``path``.

    Through a temporary file and a rename, so ``path`` is whole or absent.
    """
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        if isinstance(data, pa.Table):
            parts.write_parquet(data, tmp)
        else:
            tmp.write_bytes(data)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise OutputError(f"{path}: cannot write: {exc.strerror or exc}") from None


def write_record(layout: SweepLayout, record: RunRecord) -> None:
    """Write one finished run: steps, fixes and recording first, its ``runs`` row last (the commit)."""
    if record.steps is not None:
        write_atomic(layout.part(layout.steps_dir, record.run), _table(record.steps, STEP_STORAGE))
    if record.fixes is not None:
        write_atomic(layout.part(layout.fixes_dir, record.run), _table(record.fixes, FIX_SCHEMA))
    if record.recording is not None:
        layout.recordings_dir.mkdir(exist_ok=True)
        write_atomic(layout.part(layout.recordings_dir, record.run, ".rrd"), record.recording)
    row = pa.Table.from_pylist([record.row], schema=RUN_SCHEMA)
    write_atomic(layout.part(layout.runs_dir, record.run), row)


def finished_runs(layout: SweepLayout) -> set[int]:
    """Return the indices of the runs whose ``runs`` part exists (read from file names, no Parquet opened)."""
    return set(part_files(layout.runs_dir))


def part_files(folder: Path) -> dict[int, Path]:
    """Return the parts in ``folder`` by run index (file names only; none if the folder is missing)."""
    if not folder.is_dir():
        return {}
    out = {}
    for p in folder.iterdir():
        m = _PART.match(p.name)
        if m:
            out[int(m.group(1))] = p
    return out


def clean_unfinished(layout: SweepLayout) -> int:
    """Delete temporary files and the parts of unfinished runs; returns how many files went."""
    done = finished_runs(layout)
    removed = 0
    for folder in (layout.runs_dir, layout.steps_dir, layout.fixes_dir, layout.recordings_dir):
        if not folder.is_dir():
            continue
        for p in folder.iterdir():
            m = re.match(r"^run-(\d+)\.", p.name)
            stale = p.name.startswith(".") and ".tmp" in p.name
            orphan = m is not None and folder != layout.runs_dir and int(m.group(1)) not in done
            if stale or orphan:
                p.unlink(missing_ok=True)
                removed += 1
    return removed


def compact_runs(layout: SweepLayout) -> pa.Table:
    """Write all finished runs, sorted by run, to ``runs.parquet``; returns the table."""
    table = read_runs(layout.root)
    write_atomic(layout.runs_parquet, table)
    return table


# -- reading ----------------------------------------------------------------------------

def read_runs(root: str | Path) -> pa.Table:
    """All finished runs of sweep directory ``root`` (from its parts), sorted by ``run``."""
    layout = SweepLayout(Path(root))
    return _read(layout, [p for _, p in sorted(part_files(layout.runs_dir).items())], RUN_SCHEMA, None)


def read_steps(root: str | Path, columns: list[str] | None = None) -> pa.Table:
    """Per-step rows of the finished runs of ``root``, ordered by run then step."""
    return _read_per_run(Path(root), "steps_dir", STEP_SCHEMA, columns)


def read_fixes(root: str | Path, columns: list[str] | None = None) -> pa.Table:
    """Per-fix rows of the finished runs of ``root``, ordered by run then fix."""
    return _read_per_run(Path(root), "fixes_dir", FIX_SCHEMA, columns)


def _read_per_run(root: Path, folder: str, schema: pa.Schema, columns: list[str] | None) -> pa.Table:
    layout = SweepLayout(root)
    done = finished_runs(layout)
    found = [p for r, p in sorted(part_files(getattr(layout, folder)).items()) if r in done]
    return _read(layout, found, schema, columns)


def _read(layout: SweepLayout, found: list[Path], schema: pa.Schema, columns: list[str] | None) -> pa.Table:
    try:
        return parts.read_parts(found, schema, columns)
    except parts.DamagedPartError as exc:
        # Skipping the run instead would change every count and N-run statistic without a trace.
        raise OutputError(f"{exc}; pefsim mc SCENARIO --out {layout.root} --resume moves it aside and redoes "
                          "its run") from None
