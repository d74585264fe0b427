"""A sweep directory's settings (``sweep.json``), its checks before a sweep, and its repair on resume.

``sweep.json`` holds what must not change when a sweep is resumed (scenario name, task, run
count, :class:`~sim.montecarlo.steps.StepsMode`) and, after every sweep, the bytes per run
of its parts. Directories of format 1 (before ``steps`` existed) kept every step.

:func:`repair` reads every part of every finished run back before a resume. A part that does
not (truncated, zero bytes, garbage: a full disk, a copy gone wrong), or that a finished run
lacks, is reported in one warning line and moved to ``DIR/damaged/``; its run's ``runs`` part
goes too, so the run counts as unfinished and the resume redoes it. Its results equal a clean
sweep's, since a run depends only on its index.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from scenarios.errors import OutputError, output_errors
from scenarios.schema import Scenario
from sim.episode.types import ran as finished
from sim.montecarlo import lock, parts, results
from sim.montecarlo.results import SweepLayout
from sim.montecarlo.rows import FLEET, schemas, table_schemas
from sim.montecarlo.steps import StepsMode

SWEEP_FORMAT = 2
"""2: ``steps`` mode and float32 step parts (far positions float64 since 2026-12-05, read alike); 1: float64."""


def stored_steps_mode(settings: dict[str, Any]) -> StepsMode:
    """Return the steps mode of a directory's settings (format 1 kept every step)."""
    try:
        return StepsMode(settings.get("steps", StepsMode.ALL.value))
    except ValueError:
        raise OutputError(f"sweep.json: steps: expected one of all, fixes, none, got {settings['steps']!r}") from None


def read_settings(root: str | Path) -> dict[str, Any]:
    """Return the parsed ``sweep.json`` of ``root``; raises OutputError when it is missing or unreadable."""
    path = SweepLayout(Path(root)).sweep_json
    try:
        settings = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        raise OutputError(f"{root}: not a pefsim mc directory (no readable sweep.json)") from None
    if not isinstance(settings, dict):
        raise OutputError(f"{path}: expected a JSON object")
    return settings


def _is_ours(name: str) -> bool:
    """Files that do not make a directory "not empty": a lock (maybe stale) and its take-over leftovers."""
    return name == lock.LOCK_NAME or name.startswith(f"{lock.LOCK_NAME}.stale")


def open_sweep_dir(scenario: Scenario, out: Path, resume: bool, task: int | None,
                   steps: StepsMode | None) -> dict[str, Any]:
    """Check that ``out`` may take this sweep; returns the settings of an earlier sweep there ({} if new).

    Writes nothing. Raises OutputError for a file in the way, a directory another live
    process writes, a non-empty directory without ``resume``, or a directory of another
    scenario, task or steps mode (``steps`` None: the earlier sweep's).
    """
    layout = SweepLayout(out)
    if out.exists() and not out.is_dir():
        raise OutputError(f"{out}: exists and is not a directory")
    if out.exists():
        lock.check_free(out)
    if not out.exists() or not any(not _is_ours(p.name) for p in out.iterdir()):
        return {}
    if not resume:
        raise OutputError(f"{out}: output directory is not empty; resume to complete it, or choose another out "
                          "for a new one")
    try:
        previous_text = layout.scenario_toml.read_text(encoding="utf-8")
        settings = json.loads(layout.sweep_json.read_text(encoding="utf-8"))
        if not isinstance(settings, dict):
            raise ValueError("not an object")
    except (OSError, UnicodeDecodeError, ValueError):
        raise OutputError(f"{out}: not a pefsim mc directory (no readable scenario.toml and sweep.json); "
                          "choose another out") from None
    if previous_text != scenario.text:
        raise OutputError(f"{out}: was made from another scenario (its scenario.toml differs from "
                          f"{scenario.source}); choose another out")
    if settings.get("task") != task:
        raise OutputError(f"{out}: was made with task {settings.get('task')}, not {task}; "
                          "resume with the same task or choose another out")
    stored = stored_steps_mode(settings)
    if steps is not None and steps is not stored:
        # Mixed modes would leave some runs without the per-step rows a check aligns across runs.
        raise OutputError(f"{out}: was made with steps {stored.value}, not {steps.value}; "
                          "resume with the same steps (or without them) or choose another out")
    return settings


def init_sweep_dir(layout: SweepLayout, scenario: Scenario, task: int | None, runs: int,
                   steps: StepsMode) -> None:
    """Create the tree and write ``scenario.toml`` and ``sweep.json`` (keeping its recorded sizes)."""
    layout.make_dirs()
    results.write_atomic(layout.scenario_toml, scenario.text.encode("utf-8"))
    settings = {"format": SWEEP_FORMAT, "scenario": scenario.name, "task": task, "runs": runs,
                "steps": steps.value}
    if table_schemas(scenario) is FLEET:  # its tables have a row per robot
        settings["fleet"] = True
    write_settings(layout, settings)


def write_settings(layout: SweepLayout, settings: dict[str, Any]) -> None:
    results.write_atomic(layout.sweep_json, (json.dumps(settings, indent=2) + "\n").encode("utf-8"))


def bytes_per_run(layout: SweepLayout) -> dict[str, int]:
    """Mean bytes on disk per finished run of its ``runs``, ``steps`` and ``fixes`` parts, and their ``total``."""
    done = results.finished_runs(layout)
    out = {}
    for name in ("runs", "steps", "fixes"):
        found = [p for r, p in results.part_files(getattr(layout, f"{name}_dir")).items() if r in done]
        out[name] = round(sum(p.stat().st_size for p in found) / len(done)) if done else 0
    out["total"] = out["runs"] + out["steps"] + out["fixes"]
    return out


def record_sizes(layout: SweepLayout) -> dict[str, int]:
    """Put the bytes per run of the finished runs' parts into ``sweep.json``; returns them."""
    sizes = bytes_per_run(layout)
    settings = read_settings(layout.root)
    settings["bytes_per_run"] = sizes
    write_settings(layout, settings)
    return sizes


def _move_aside(layout: SweepLayout, path: Path) -> Path:
    with output_errors(layout.damaged_dir, "create"):
        layout.damaged_dir.mkdir(exist_ok=True)
    base = f"{path.parent.name}-{path.name}"
    dest = layout.damaged_dir / base
    n = 1
    while dest.exists():  # an earlier resume moved one of the same name: keep both
        dest, n = layout.damaged_dir / f"{base}.{n}", n + 1
    try:
        os.replace(path, dest)
    except OSError as exc:
        raise OutputError(f"{path}: cannot move it aside to {dest}: {exc.strerror or exc}") from None
    return dest


def repair(layout: SweepLayout, steps: StepsMode, warn: Callable[[str], None]) -> list[int]:
    """Move aside the parts of finished runs that do not read back; returns the runs to redo (sorted).

    A finished run must have a ``runs`` part of one row and, when it ran (not crashed), a fixes
    part and (unless ``steps`` is none) a steps part. Each damaged or missing part is one warning.
    """
    redo = []
    sch = results.sweep_schemas(layout.root)
    fleet = sch is schemas(True)
    for run, path in sorted(results.part_files(layout.runs_dir).items()):
        problems: list[tuple[Path, str]] = []
        try:
            parts.check_part(path, sch.runs, run, rows=None if fleet else 1)   # a fleet's: a row per robot
            ran = finished(parts.read_part(path, sch.runs, ["status"]).column("status")[0].as_py())
        except parts.DamagedPartError as exc:
            problems.append((path, exc.reason))
            ran = False
        expected = [(layout.fixes_dir, sch.fixes)] if ran else []
        if ran and steps is not StepsMode.NONE:
            expected.append((layout.steps_dir, sch.steps))
        for folder, schema in expected:
            part = layout.part(folder, run)
            try:
                parts.check_part(part, schema, run)
            except parts.DamagedPartError as exc:
                problems.append((part, exc.reason))
        for part, reason in problems:
            if part.exists():
                dest = _move_aside(layout, part)
                warn(f"pefsim: warning: {part}: does not read back ({reason}); moved to {dest}, "
                     f"run {run} is redone")
            else:
                warn(f"pefsim: warning: {part}: missing for finished run {run}; run {run} is redone")
        if problems:
            path.unlink(missing_ok=True)  # un-finish the run: its other parts are orphans now
            redo.append(run)
    if redo:
        results.clean_unfinished(layout)
    return redo
