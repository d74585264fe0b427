"""Rerun recordings of scenarios, plans and episodes (the one bridge to rerun-sdk 0.41).

A recording answers "why did this run go wrong?": where the robot truly was, what it
believed (estimate and covariance), which markers each fix used, and whether the realised
fault area stayed inside what the PEF predicted. Open one with ``rerun FILE.rrd``.

Every function takes an explicit :class:`rerun.RecordingStream` (never the global stream).
The file layout (entity paths, timeline) is defined in :mod:`interop.recording.entities`; the
static and per-episode logging live in :mod:`interop.recording.static` and
:mod:`interop.recording.episode`.

Examples
--------
>>> write_episode_rrd("run.rrd", scenario, result, pef_map=pef_map)    # doctest: +SKIP
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from interop.recording import entities as E
from interop.recording.episode import log_result
from interop.recording.static import log_pef_map, log_plan, log_scene
from scenarios.errors import OutputError, output_errors
from scenarios.schema import Scenario
from sim.episode.types import EpisodeResult


def blueprint() -> rrb.Blueprint:
    """Build the stored layout: the map on the left, error and consistency plots on the right.

    The map view's root is ``/`` (not ``/world``) because the y-flip that turns rerun's
    y-down 2-D view into the workspace's y-up frame is the transform of ``world`` itself.
    """
    map_view = rrb.Spatial2DView(name="Map (workspace, metres)", origin="/", contents=[f"/{E.WORLD}/**"])
    error_view = rrb.TimeSeriesView(
        name="Error vs predicted bound", origin=f"/{E.METRICS}",
        contents=[f"/{p}" for p in (E.ERROR, E.PREDICTED_TAU, E.EPS_MAX, E.PEF_TAU, E.FAULT_DIAMETER,
                                     E.FIX_PREDICTED_TAU)],
        plot_legend=rrb.PlotLegend(corner="LeftTop"))
    consistency_view = rrb.TimeSeriesView(
        name="Filter consistency (NEES, NIS)", origin=f"/{E.METRICS}",
        contents=[f"/{p}" for p in (E.NEES, E.NEES_UPPER, E.NIS)])
    events_view = rrb.TextLogView(name="Fixes and violations", origin=f"/{E.EVENTS}")
    summary_view = rrb.TextDocumentView(name="Summary", origin=f"/{E.SUMMARY}")
    plan_view = rrb.TextDocumentView(name="Plan", origin=f"/{E.PLAN_TEXT}")
    return rrb.Blueprint(
        rrb.Horizontal(
            map_view,
            rrb.Vertical(error_view, rrb.Tabs(consistency_view, events_view, summary_view, plan_view),
                         row_shares=[3, 2]),
            column_shares=[3, 2]),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="expanded", timeline=E.TIMELINE),
    )


def check_writable(path: str | os.PathLike[str]) -> Path:
    """Make sure a file can be written at ``path`` before any work, leaving the path as it was.

    The recording is written after the work: until then an existing file keeps its content and a
    new one is not left behind, so work that fails (a task that does not plan) costs no file.

    Parameters
    ----------
    path : str or path-like
        Target file.

    Returns
    -------
    pathlib.Path
        The path.

    Raises
    ------
    scenarios.errors.OutputError
        ``"<path>: cannot write recording: <reason>"`` if it is a directory, its directory is
        missing or not writable, or the file system refuses the file.
    """
    p = Path(path)
    if p.is_dir():
        raise OutputError(f"{path}: cannot write recording: it is a directory")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise OutputError(f"{path}: cannot write recording: directory {parent} does not exist")
    existed = p.exists()
    with output_errors(path, "write recording"), open(p, "ab"):
        pass  # an actual open, so that read-only mounts and ACLs are caught too (also as root)
    if not existed:
        p.unlink(missing_ok=True)
    return p


def open_recording(path: str | os.PathLike[str], *, recording_id: str | None = None,
                   layout: rrb.Blueprint | None = None) -> rr.RecordingStream:
    """Start a headless recording that streams to ``path``, with the blueprint stored in it.

    Parameters
    ----------
    path : str or path-like
        ``.rrd`` file to write (created or overwritten).
    recording_id : str, optional
        Rerun recording id; recordings with the same id merge in the viewer. Default: random.
    layout : rerun.blueprint.Blueprint, optional
        Default: :func:`blueprint`.

    Returns
    -------
    rerun.RecordingStream
        Application id ``"pefsim"``; call :func:`close` to finish the file.

    Raises
    ------
    scenarios.errors.OutputError
        When the file cannot be written (checked before anything is logged).
    """
    p = check_writable(path)
    rec = rr.RecordingStream(E.APPLICATION_ID, recording_id=recording_id)
    try:
        rec.save(p, default_blueprint=layout if layout is not None else blueprint())
    except Exception as exc:  # rerun raises its own types; the user sees one line
        raise OutputError(f"{path}: cannot write recording: {exc}") from exc
    return rec


def close(rec: rr.RecordingStream) -> None:
    """Flush everything and finish the file (footer included); ``rec`` is unusable afterwards."""
    rec.flush()
    rec.disconnect()


def log_static(rec: rr.RecordingStream, scenario: Scenario, pef_map: Any = None, plan: Any = None) -> None:
    """Log what does not change during an episode.

    Parameters
    ----------
    rec : rerun.RecordingStream
        Target stream.
    scenario : scenarios.schema.Scenario
        Workspace, obstacles, markers (labelled with their ids) and docks.
    pef_map : planner.pef.result.PefMap, optional
        ``x`` (nx,), ``y`` (ny,) cell centres [m] and ``tau`` (ny, nx) [m]: logged as the
        heatmap ``world/pef`` and the ε_max contour ``world/region``.
    plan : planner.plan.Plan, optional
        Candidate routes, chosen route, reference path and fix schedule.
    """
    log_scene(rec, scenario)
    if pef_map is not None:
        log_pef_map(rec, pef_map, scenario.planning.eps_max)
    if plan is not None:
        log_plan(rec, plan, scenario)


def log_episode(rec: rr.RecordingStream, result: EpisodeResult, scenario: Scenario, *,
                predicted_polygons: list[np.ndarray] | None = None) -> None:
    """Log one episode on the ``sim_time`` timeline (static scene not included: see :func:`log_static`).

    Parameters
    ----------
    rec : rerun.RecordingStream
        Target stream.
    result : sim.episode.types.EpisodeResult
        Steps (T) and fixes (F) of the episode.
    scenario : scenarios.schema.Scenario
        The scenario the episode ran in.
    predicted_polygons : list of F (n, 2) arrays, optional
        Predicted fault area of each fix at its true position [m]; default: the linearised
        strip polygon of the fix's markers and bounds.
    """
    log_result(rec, result, scenario, predicted_polygons)


def write_static_rrd(path: str | os.PathLike[str], scenario: Scenario, pef_map: Any = None,
                     plan: Any = None) -> Path:
    """Write a recording of the scenario, its PEF map and a plan (no episode); returns the path."""
    rec = open_recording(path)
    try:
        rec.send_recording_name(scenario.name)
        log_static(rec, scenario, pef_map, plan)
    finally:
        close(rec)
    return Path(path)


def write_episode_rrd(path: str | os.PathLike[str], scenario: Scenario, result: EpisodeResult,
                      pef_map: Any = None) -> Path:
    """Write a recording of one episode with its scene, map and plan (``result.plan``); returns the path.

    The path is checked first, so a bad path fails before any logging work.
    """
    rec = open_recording(path)
    try:
        log_static(rec, scenario, pef_map, result.plan)
        log_episode(rec, result, scenario)
    finally:
        close(rec)
    return Path(path)
