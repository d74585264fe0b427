"""Static part of a recording: the workspace, markers, docks, PEF map and plan.

Everything here is logged with ``static=True`` (it does not change during an episode), in
metres in the workspace frame. Entity paths come from :mod:`interop.recording.entities`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import rerun as rr

from interop.recording import entities as E
from interop.recording.geometry import closed_ring, heading_vectors, level_contours, rectangle_ring
from scenarios.schema import Scenario

TAU_DISPLAY_CAP = 2.0
"""The heatmap shows τ clipped at this multiple of ε_max (τ = ∞ shows as the cap): the
colours then resolve the range that matters, with ε_max in the middle of the colormap."""

VIEW_FLIP = rr.Transform3D(scale=[1.0, -1.0, 1.0])
"""Transform of ``world`` into the view's root: rerun's 2-D views draw +y downwards (image
convention, rerun-io/rerun#1387), so the workspace (y up) is mirrored once here and all data
under ``world`` stays in workspace coordinates."""


def _ui(points: float) -> float:
    return float(rr.Radius.ui_points(points))


def log_scene(rec: rr.RecordingStream, scenario: Scenario, *, static: bool = True) -> None:
    """Log the view flip, workspace border, obstacles, markers (labelled) and docks.

    Parameters
    ----------
    rec : rerun.RecordingStream
        Target stream.
    scenario : scenarios.schema.Scenario
        The world to draw.
    static : bool
        Log as static data (a recording's scene), or at the stream's current time (a live view's
        update, :mod:`interop.recording.live`).
    """
    rec.log(E.WORLD, VIEW_FLIP, static=static)
    ws = scenario.workspace
    rec.log(E.WORKSPACE, rr.LineStrips2D([rectangle_ring(ws.width, ws.height, ws.origin)], colors=[E.GREY],
                                         radii=_ui(E.THICK_LINE_PT)), static=static)
    rings = [closed_ring(r) for o in scenario.obstacles for r in o.rings()]  # outer faces and holes
    rec.log(E.OBSTACLES, rr.LineStrips2D(rings, colors=[E.OBSTACLE] * len(rings),
                                         radii=_ui(E.THICK_LINE_PT)), static=static)
    rec.log(E.MARKERS, rr.Points2D(scenario.marker_positions(), labels=scenario.marker_ids(),
                                   colors=[E.MARKER], radii=_ui(E.BIG_POINT_PT), show_labels=True),
            static=static)
    flat = [m for m in scenario.markers if m.kind.value == "flat"]
    if flat:
        # the reflector's face across its normal, and the normal as long as the robot is wide
        size = 2.0 * scenario.robot.radius
        xy = np.array([m.position for m in flat], dtype=float)
        n = np.array([m.normal for m in flat], dtype=float)
        across = np.column_stack([-n[:, 1], n[:, 0]]) * (0.5 * size)
        rec.log(E.MARKER_FACING,
                rr.LineStrips2D(np.stack([xy - across, xy + across], axis=1), colors=[E.MARKER],
                                radii=_ui(E.THICK_LINE_PT)),
                rr.Arrows2D(origins=xy, vectors=n * size, colors=[E.MARKER], radii=_ui(E.LINE_PT)),
                static=static)
    docks_xy = np.array([d.position for d in scenario.docks], dtype=float).reshape(-1, 2)
    dock_yaw = np.array([d.pose[2] for d in scenario.docks], dtype=float)
    rec.log(E.DOCKS,
            rr.Points2D(docks_xy, labels=[d.name for d in scenario.docks], colors=[E.DOCK],
                        radii=_ui(E.BIG_POINT_PT), show_labels=True),
            rr.Arrows2D(origins=docks_xy, vectors=heading_vectors(dock_yaw, 2.0 * scenario.robot.radius),
                        colors=[E.DOCK], radii=_ui(E.LINE_PT)),
            static=static)


def pef_image_transform(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return the translation and scale that put image pixel (col, row) on the grid cell (x[col], y[row]).

    An image pixel (col, row) covers [col, col+1) x [row, row+1) in the image's own space,
    so its centre is (col + 0.5, row + 0.5); ``translation + scale * centre`` must equal the
    cell centre. Row 0 of the image is y[0] (the lowest row of the workspace).

    Parameters
    ----------
    x : (nx,) float
        Cell-centre x coordinates [m], evenly spaced.
    y : (ny,) float
        Cell-centre y coordinates [m], evenly spaced.

    Returns
    -------
    translation : (3,) float
        [m].
    scale : (3,) float
        Cell size per pixel [m], z = 1.
    """
    dx = float(x[1] - x[0]) if len(x) > 1 else float(y[1] - y[0]) if len(y) > 1 else 1.0
    dy = float(y[1] - y[0]) if len(y) > 1 else dx
    translation = np.array([x[0] - 0.5 * dx, y[0] - 0.5 * dy, 0.0])
    return translation, np.array([dx, dy, 1.0])


NO_FIX_ORDER = -9.0
"""Draw order of the τ = ∞ layer: above the heatmap (rerun draws images at -10 unless told)."""


def no_fix_layer(tau: np.ndarray) -> np.ndarray:
    """Return the RGBA layer drawn over the heatmap: :data:`~interop.recording.entities.NO_FIX_CELL` where τ = ∞.

    The heatmap caps τ at the top of its colormap, the colour of "bad"; a cell with no fix
    (inside a rack, or seeing no usable subset) is not that, so this layer paints it apart.

    Parameters
    ----------
    tau : (ny, nx) float
        The map [m], inf where no subset is usable.

    Returns
    -------
    (ny, nx, 4) uint8
        RGBA: the no-fix colour where τ is not finite, fully transparent elsewhere.
    """
    tau = np.asarray(tau, dtype=float)
    # one pass: each cell's four bytes as one little-endian uint32 (the 3.84 M cells of the hall
    # at 5 cm in ~20 ms, where a masked assignment of RGBA rows took 0.1 s)
    r, g, b, a = (int(c) for c in E.NO_FIX_CELL)
    packed = np.where(np.isfinite(tau), np.uint32(0), np.uint32(r | g << 8 | b << 16 | a << 24))
    return packed.astype("<u4", copy=False).view(np.uint8).reshape(*tau.shape, 4)


def log_pef_map(rec: rr.RecordingStream, pef_map: Any, eps_max: float, *, static: bool = True,
                contours: dict | None = None) -> None:
    """Log the τ heatmap (``world/pef``), its τ = ∞ cells over it (``world/pef/no_fix``), the ε_max contour.

    The contour is ``world/region``.

    Parameters
    ----------
    rec : rerun.RecordingStream
        Target stream.
    pef_map : planner.pef.result.PefMap or alike
        Needs ``x`` (nx,), ``y`` (ny,) cell centres [m] and ``tau`` (ny, nx) [m], inf where
        too few markers are visible.
    eps_max : float
        Allowed error [m]; the navigation region is ``{tau < eps_max}``.
    static : bool
        As in :func:`log_scene`.
    contours : dict, optional
        The contour's tile cache (:func:`~interop.recording.geometry.level_contours`), kept from
        one call to the next by a live view.
    """
    x = np.asarray(pef_map.x, dtype=float)
    y = np.asarray(pef_map.y, dtype=float)
    tau = np.asarray(pef_map.tau, dtype=float)
    cap = TAU_DISPLAY_CAP * eps_max
    shown = np.fmin(tau, cap).astype(np.float32)  # inf (and NaN) to the cap, in one pass
    translation, scale = pef_image_transform(x, y)
    rec.log(E.PEF,
            rr.DepthImage(shown, meter=1.0, colormap="viridis", depth_range=(0.0, cap),
                          draw_order=NO_FIX_ORDER - 1.0),
            rr.Transform3D(translation=translation, scale=scale),
            static=static)
    rec.log(E.PEF_NO_FIX, rr.Image(no_fix_layer(tau), draw_order=NO_FIX_ORDER), static=static)
    lines = level_contours(x, y, tau, eps_max, cache=contours)
    rec.log(E.REGION, rr.LineStrips2D(lines, colors=[E.REGION_LINE] * len(lines),
                                      radii=_ui(E.THICK_LINE_PT)), static=static)


def plan_markdown(plan: Any) -> str:
    """Markdown of a plan: the reason for the choice and a table of the candidates.

    Parameters
    ----------
    plan : planner.plan.Plan or alike
        Optional attributes (``start``, ``goal``, ``reason``, a candidate's ``length``,
        ``max_tau``, ``why_not``) are shown when present.

    Returns
    -------
    str
        Markdown text.
    """
    rows = [f"# Plan {getattr(plan, 'start', '')} → {getattr(plan, 'goal', '')}", "",
            str(getattr(plan, "reason", "") or ""), "",
            "| route | admissible | length [m] | max τ [mm] | why not |", "|---|---|---|---|---|"]
    for i, c in enumerate(plan.candidates or []):
        name = f"**{c.id} (chosen)**" if i == plan.chosen else str(c.id)
        length, max_tau = getattr(c, "length", float("nan")), getattr(c, "max_tau", float("nan"))
        rows.append(f"| {name} | {'yes' if c.admissible else 'no'} | {length:.2f} | {1000 * max_tau:.2f} "
                    f"| {getattr(c, 'why_not', '') or ''} |")
    return "\n".join(rows) + "\n"


def log_plan(rec: rr.RecordingStream, plan: Any, scenario: Scenario, *, static: bool = True,
             task: int | None = None, candidates: bool = True) -> None:
    """Log candidate routes, the chosen route, the reference path and the fix schedule.

    Parameters
    ----------
    rec : rerun.RecordingStream
        Target stream.
    plan : planner.plan.Plan or alike
        Uses ``candidates`` (each ``.polyline`` (n, 2) [m], ``.admissible``, ``.id``),
        ``chosen`` (index or None), ``path`` (N, 2) [m] or None and ``schedule.fixes``
        (each ``.position`` (x, y) [m], ``.markers`` (marker indices), ``.tau`` [m],
        ``.switch`` bool).
    scenario : scenarios.schema.Scenario
        For marker ids in the schedule's labels.
    static : bool
        As in :func:`log_scene`.
    task : int, optional
        Log under the task's own entities (:func:`interop.recording.entities.of_task`), so that the
        plans of several tasks sit side by side; default the recording's single plan.
    candidates : bool
        Draw every candidate route (a live view of a route network leaves them out: the network
        itself is drawn, coloured by τ, and the candidates' labels would pile up on it).
    """
    at = (lambda entity: entity) if task is None else (lambda entity: E.of_task(entity, task))
    cands = list(plan.candidates or [])
    if candidates:
        rec.log(at(E.CANDIDATES),
                rr.LineStrips2D([np.asarray(c.polyline, float) for c in cands],
                                colors=[E.CANDIDATE_OK if c.admissible else E.CANDIDATE_BAD for c in cands],
                                labels=[f"{c.id}{'' if c.admissible else ' (inadmissible)'}" for c in cands],
                                radii=_ui(E.LINE_PT)),
                static=static)
    if plan.chosen is not None:
        chosen = cands[plan.chosen]
        rec.log(at(E.CHOSEN), rr.LineStrips2D([np.asarray(chosen.polyline, float)], colors=[E.CHOSEN_ROUTE],
                                          labels=[f"chosen: {chosen.id}"], radii=_ui(E.THICK_LINE_PT)),
                static=static)
    if getattr(plan, "path", None) is not None:
        rec.log(at(E.PATH), rr.LineStrips2D([np.asarray(plan.path, float)], colors=[E.PATH_ROUTE],
                                        radii=_ui(E.LINE_PT)), static=static)
    rec.log(at(E.PLAN_TEXT), rr.TextDocument(plan_markdown(plan), media_type="text/markdown"), static=static)
    fixes = list(plan.schedule.fixes) if getattr(plan, "schedule", None) is not None else []
    ids = scenario.marker_ids()
    rec.log(at(E.SCHEDULE),
            rr.Points2D(np.array([f.position for f in fixes], dtype=float).reshape(-1, 2),
                        colors=[E.SWITCH_POINT if f.switch else E.FIX_POINT for f in fixes],
                        radii=[_ui(E.BIG_POINT_PT if f.switch else E.POINT_PT) for f in fixes],
                        labels=["+".join(ids[i] for i in f.markers) + f" τ={1000 * f.tau:.1f} mm"
                                + (" (switch)" if f.switch else "") for f in fixes]),
            static=static)
