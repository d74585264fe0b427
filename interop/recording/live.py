"""A live view of a scenario (``pefsim watch``): a stream to a viewer or a file, re-logged on every edit.

Each update is logged at the next step of the ``edit`` timeline after a recursive clear of
``world`` (so markers, routes and tasks that were deleted disappear), and the viewer follows
the newest step; the earlier steps stay in the recording to look back at. Entity paths are
those of :mod:`interop.recording.entities`, with the plans under ``world/tasks/<i>``.
"""

from __future__ import annotations

import os
import uuid
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from interop.recording import check_writable
from interop.recording import entities as E
from interop.recording.static import log_pef_map, log_plan, log_scene
from scenarios.errors import OutputError
from scenarios.schema import Scenario

EDIT_TIMELINE = "edit"
"""Sequence timeline of a live view: 0 for the first view, one more per update."""


def _ui(points: float) -> float:
    return float(rr.Radius.ui_points(points))


def live_blueprint() -> rrb.Blueprint:
    """Build the live view's layout: the map, beside the summary and the plans as text."""
    map_view = rrb.Spatial2DView(name="Map (workspace, metres)", origin="/", contents=[f"/{E.WORLD}/**"])
    return rrb.Blueprint(
        rrb.Horizontal(map_view,
                       rrb.Tabs(rrb.TextDocumentView(name="View", origin=f"/{E.VIEW_TEXT}"),
                                rrb.TextDocumentView(name="Plans", origin=f"/{E.PLAN_TEXT}")),
                       column_shares=[3, 1]),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed", timeline=EDIT_TIMELINE),
    )


def open_live(name: str, *, save: str | os.PathLike[str] | None = None, connect: str | None = None,
              spawn: bool = True) -> rr.RecordingStream:
    """Open the stream of a live view: into a file, to a running viewer, or to a viewer it starts.

    Parameters
    ----------
    name : str
        Recording name shown in the viewer (the scenario's file name).
    save : str or path-like, optional
        Write the recording to this ``.rrd`` file (checked before anything is logged).
    connect : str, optional
        Stream to the viewer listening at this gRPC URL (``rerun+http://127.0.0.1:9876/proxy``;
        ``""``: rerun's default address).
    spawn : bool
        With neither ``save`` nor ``connect``: start a viewer and stream to it.

    Returns
    -------
    rerun.RecordingStream
        Finish it with :func:`interop.recording.close`.

    Raises
    ------
    scenarios.errors.OutputError
        Both ``save`` and ``connect``, a ``save`` not named ``.rrd``, a file that cannot be
        written, or a viewer that cannot be reached or started.
    """
    if save is not None and connect is not None:
        raise OutputError("watch: give save or connect, not both")
    if save is not None and Path(save).suffix.lower() != ".rrd":
        raise OutputError(f"{save}: save: expected a .rrd file, got {Path(save).suffix or 'no extension'!r}")
    path = check_writable(save) if save is not None else None
    rec = rr.RecordingStream(E.APPLICATION_ID, recording_id=str(uuid.uuid4()))
    bp = live_blueprint()
    try:
        if path is not None:
            rec.save(path, default_blueprint=bp)
        elif connect is not None:
            rec.connect_grpc(connect or None, default_blueprint=bp)
        elif spawn:
            rec.spawn(default_blueprint=bp)
    except Exception as exc:  # rerun raises its own types; the user sees one line
        where = save if path is not None else (connect or "a new viewer")
        raise OutputError(f"{where}: cannot stream the live view: {exc}") from exc
    rec.send_recording_name(name)
    return rec


def tau_colors(tau: np.ndarray, eps_max: float) -> np.ndarray:
    """Colours of route segments by their worst τ: green at 0, yellow at ε_max/2, red at ε_max and above.

    τ = ∞ (a point without a fix) gets :data:`~interop.recording.entities.NO_FIX`, a colour off the
    ramp: it is not "bad but finite".

    Parameters
    ----------
    tau : (n,) float
        Worst τ of each segment [m].
    eps_max : float
        Allowed error [m].

    Returns
    -------
    (n, 3) uint8
        RGB.
    """
    tau = np.asarray(tau, dtype=float)
    s = np.clip(np.where(np.isfinite(tau), tau, 0.0) / eps_max, 0.0, 1.0)[:, None]
    good, mid, limit = (np.array(c, dtype=float) for c in (E.TAU_GOOD, E.TAU_MID, E.TAU_LIMIT))
    low = good + (mid - good) * np.clip(2.0 * s, 0.0, 1.0)
    rgb = np.where(s <= 0.5, low, mid + (limit - mid) * np.clip(2.0 * s - 1.0, 0.0, 1.0))
    rgb[~np.isfinite(tau)] = E.NO_FIX
    return np.rint(rgb).astype(np.uint8)


def log_network(rec: rr.RecordingStream, scenario: Scenario, reports: list[Any]) -> None:
    """Log the route network's segments coloured by their worst τ, in three entities.

    Admissible segments (``world/routes/network/admissible``) carry their τ as a hover label;
    inadmissible ones with finite τ (``.../inadmissible``) are thicker and labelled with why;
    segments with a point of τ = ∞ (``.../no_fix``) are drawn in their own colour.

    Parameters
    ----------
    rec : rerun.RecordingStream
        Target stream (at the update's time).
    scenario : scenarios.schema.Scenario
        Its ``routes`` (nodes, segments, edge ids).
    reports : list of planner.routes.edges.SegmentReport
        One per segment: ``index``, ``max_tau`` [m], ``why_not``.
    """
    net = scenario.routes
    if net is None or not reports:
        return
    eps = scenario.planning.eps_max
    lines = np.array([[net.nodes[a], net.nodes[b]] for a, b in net.segments], dtype=float)  # (S, 2, 2)
    tau = np.array([r.max_tau for r in reports], dtype=float)
    ok = np.array([not r.why_not for r in reports])
    no_fix = ~np.isfinite(tau)
    colors = tau_colors(tau, eps)
    labels = [f"{net.edge_label(r.index)}: τ ≤ {1000 * r.max_tau:.1f} mm" if np.isfinite(r.max_tau)
              else f"{net.edge_label(r.index)}: τ = ∞ (no fix)" for r in reports]
    bad_labels = [f"{lab} - {r.why_not}" if r.why_not else lab for lab, r in zip(labels, reports, strict=True)]
    for entity, sel, width, texts, shown in (
            (E.NETWORK_OK, ok & ~no_fix, E.THICK_LINE_PT, labels, False),
            (E.NETWORK_BAD, ~ok & ~no_fix, 2.0 * E.THICK_LINE_PT, bad_labels, True),
            (E.NETWORK_NO_FIX, no_fix, 2.0 * E.THICK_LINE_PT, bad_labels, True)):
        idx = np.flatnonzero(sel)
        rec.log(entity, rr.LineStrips2D(lines[idx], colors=colors[idx], labels=[texts[i] for i in idx],
                                        radii=_ui(width), show_labels=shown))


def view_markdown(scenario: Scenario, summary: str, plans: list[Any], unplanned: dict[int, str]) -> str:
    """Markdown of a live view: the summary line, and each task's plan or why it has none."""
    rows = [f"# {scenario.name}", "", summary, "", "| task | route | worst τ [mm] | fixes |", "|---|---|---|---|"]
    for i, task in enumerate(scenario.tasks):
        plan = plans[i] if i < len(plans) else None
        if plan is None:
            rows.append(f"| {i}: {task.start} → {task.goal} | none: {unplanned.get(i, '')} | | |")
            continue
        cand = plan.candidates[plan.chosen]
        fixes = len(plan.schedule.fixes) if plan.schedule is not None else 0
        rows.append(f"| {i}: {task.start} → {task.goal} | {cand.id} | {1000 * cand.max_tau:.2f} | {fixes} |")
    return "\n".join(rows) + "\n"


def log_view(rec: rr.RecordingStream, step: int, scenario: Scenario, pef_map: Any, reports: list[Any],
             plans: list[Any] | None, unplanned: dict[int, str], summary: str, contours: dict | None = None) -> None:
    """Log one update of the live view at step ``step`` of the ``edit`` timeline.

    Parameters
    ----------
    rec : rerun.RecordingStream
        From :func:`open_live`.
    step : int
        Update number (0 for the first view).
    scenario : scenarios.schema.Scenario
        The scene: workspace, obstacles, markers (flat ones with their facing), docks.
    pef_map : planner.pef.result.PefMap
        ``x``, ``y`` [m], ``tau`` (ny, nx) [m]: the heatmap and the navigation region's border.
    reports : list of planner.routes.edges.SegmentReport
        The route network's segments (empty without a network).
    plans : list of planner.plan.Plan or None, or None
        One per task; None where the task has no admissible route. None as a whole: the plans
        follow (:func:`log_plans` at the same step); until then the text says they are coming.
    unplanned : dict of int to str
        Why a task has no plan.
    summary : str
        One line on what this update read.
    contours : dict, optional
        A cache of the region's contour kept between updates (:func:`interop.recording.static.log_pef_map`):
        only the tiles of the map that changed are traced again.
    """
    rec.set_time(EDIT_TIMELINE, sequence=step)
    rec.log(E.WORLD, rr.Clear(recursive=True))
    rec.log(E.PLAN_TEXT, rr.Clear(recursive=True))
    log_scene(rec, scenario, static=False)
    log_pef_map(rec, pef_map, scenario.planning.eps_max, static=False, contours=contours)
    log_network(rec, scenario, reports)
    if plans is None:
        rec.log(E.VIEW_TEXT, rr.TextDocument(f"# {scenario.name}\n\n{summary}\n", media_type="text/markdown"))
    else:
        log_plans(rec, step, scenario, plans, unplanned, summary)


def log_plans(rec: rr.RecordingStream, step: int, scenario: Scenario, plans: list[Any], unplanned: dict[int, str],
              summary: str) -> None:
    """Log the plans of an update whose map :func:`log_view` logged without them, at the same step.

    Parameters
    ----------
    rec : rerun.RecordingStream
        From :func:`open_live`.
    step : int
        The update's step.
    scenario : scenarios.schema.Scenario
        Its tasks and routes.
    plans : list of planner.plan.Plan or None
        One per task; None where the task has no admissible route.
    unplanned : dict of int to str
        Why a task has no plan.
    summary : str
        One line on what this update read.
    """
    rec.set_time(EDIT_TIMELINE, sequence=step)
    for i, plan in enumerate(plans):
        if plan is not None:
            log_plan(rec, plan, scenario, static=False, task=i, candidates=scenario.routes is None)
    rec.log(E.VIEW_TEXT, rr.TextDocument(view_markdown(scenario, summary, plans, unplanned),
                                         media_type="text/markdown"))
