"""Monte-Carlo results on disk: atomic per-run parts, and reading them back (schemas: :mod:`sim.montecarlo.rows`).

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

import json
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

from scenarios.errors import OutputError, output_errors
from sim.montecarlo import parts
from sim.montecarlo.rows import (
    SINGLE,
    Schemas,
    _table,
    schemas,
)

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
    row: dict[str, Any] | list[dict[str, Any]]
    """The run's row; a fleet's run has a list of rows, one per robot (:data:`~sim.montecarlo.rows.FLEET`)."""
    steps: dict[str, np.ndarray] | None = None
    fixes: dict[str, np.ndarray] | None = None
    recording: bytes | None = None
    fatal: Exception | None = None
    warning: str | None = None


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


def write_record(layout: SweepLayout, record: RunRecord, sch: Schemas = SINGLE) -> None:
    """Write one finished run: steps, fixes and recording first, its ``runs`` row(s) last (the commit).

    ``sch``: the sweep's tables (:func:`~sim.montecarlo.rows.table_schemas`).
    """
    if record.steps is not None:
        storage = parts.positions_kept(sch.step_storage, record.steps)
        write_atomic(layout.part(layout.steps_dir, record.run), _table(record.steps, storage))
    if record.fixes is not None:
        write_atomic(layout.part(layout.fixes_dir, record.run), _table(record.fixes, sch.fixes))
    if record.recording is not None:
        layout.recordings_dir.mkdir(exist_ok=True)
        write_atomic(layout.part(layout.recordings_dir, record.run, ".rrd"), record.recording)
    # a crashed run has one row, without the robot columns
    rows = [{**{n: None for n in sch.runs.names}, **r} for r in (record.row if isinstance(record.row, list)
                                                                 else [record.row])]
    write_atomic(layout.part(layout.runs_dir, record.run), pa.Table.from_pylist(rows, schema=sch.runs))


def sweep_schemas(root: str | Path) -> Schemas:
    """Return the schemas of the sweep in ``root``: a fleet's when its ``sweep.json`` says ``"fleet": true``."""
    try:
        settings = json.loads((Path(root) / "sweep.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return SINGLE
    return schemas(isinstance(settings, dict) and settings.get("fleet") is True)


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
    return _read(layout, [p for _, p in sorted(part_files(layout.runs_dir).items())], sweep_schemas(root).runs, None)


def read_steps(root: str | Path, columns: list[str] | None = None) -> pa.Table:
    """Per-step rows of the finished runs of ``root``, ordered by run then step."""
    return _read_per_run(Path(root), "steps_dir", sweep_schemas(root).steps, columns)


def read_fixes(root: str | Path, columns: list[str] | None = None) -> pa.Table:
    """Per-fix rows of the finished runs of ``root``, ordered by run then fix."""
    return _read_per_run(Path(root), "fixes_dir", sweep_schemas(root).fixes, columns)


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
        raise OutputError(f"{exc}; resuming the sweep in {layout.root} moves it aside and redoes "
                          "its run") from None
