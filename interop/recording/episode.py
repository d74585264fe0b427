"""Episode part of a recording: poses, covariance, fixes, metrics and events on ``sim_time``.

Bulk data goes in as columns (one ``send_columns`` per entity, not one ``log`` per step):
that keeps a 5000-step episode in the tens of milliseconds. Styling that does not change
(colours, radii, series names) is logged once as static components next to the columns.
"""

from __future__ import annotations

import numpy as np
import rerun as rr

from interop.recording import entities as E
from interop.recording.geometry import covariance_ellipses, heading_vectors, strip_polygons
from scenarios.schema import Scenario
from sim.episode.types import EpisodeResult, FixLog, StepLog

CHI2_3DOF_975 = 9.348403604496148
"""NEES reference line, scipy.stats.chi2.ppf(0.975, 3) (a constant so recording does not import
scipy): with a consistent filter the single-run NEES of the 3-dof pose exceeds it at 2.5 % of
the steps."""


def _ui(points: float) -> float:
    return float(rr.Radius.ui_points(points))


def _finite_or_nan(a: np.ndarray) -> np.ndarray:
    # rerun plots NaN as a gap; ±inf would wreck the plot's automatic range
    a = np.asarray(a, dtype=float)
    return np.where(np.isfinite(a), a, np.nan)


def _index(t: np.ndarray) -> list[rr.TimeColumn]:
    return [rr.TimeColumn(E.TIMELINE, duration=np.asarray(t, dtype=float))]


def _log_pose(rec: rr.RecordingStream, entity: str, t: np.ndarray, pose: np.ndarray,
              arrow_len: float, color: tuple[int, int, int]) -> None:
    xy = np.ascontiguousarray(pose[:, :2], dtype=float)
    rec.log(entity, rr.Points2D.from_fields(colors=[color], radii=_ui(E.BIG_POINT_PT)),
            rr.Arrows2D.from_fields(colors=[color], radii=_ui(E.LINE_PT)), static=True)
    rec.send_columns(entity, _index(t),
                     [*rr.Points2D.columns(positions=xy),
                      *rr.Arrows2D.columns(origins=xy, vectors=heading_vectors(pose[:, 2], arrow_len))])


def _log_scalar(rec: rr.RecordingStream, entity: str, t: np.ndarray, values: np.ndarray, name: str,
                color: tuple[int, int, int], points: bool = False, visible: bool = True) -> None:
    style = (rr.SeriesPoints(names=name, colors=[color], marker_sizes=3.0, visible_series=visible)
             if points else rr.SeriesLines(names=name, colors=[color], widths=1.5, visible_series=visible))
    rec.log(entity, style, static=True)
    rec.send_columns(entity, _index(t), rr.Scalars.columns(scalars=np.asarray(values, dtype=float)))


def log_steps(rec: rr.RecordingStream, steps: StepLog, scenario: Scenario, eps_max: float, ent=E) -> None:
    """Log per-step poses, trails, covariance ellipses and metrics.

    Parameters
    ----------
    rec : rerun.RecordingStream
        Target stream.
    steps : sim.episode.types.StepLog
        T control steps.
    scenario : scenarios.schema.Scenario
        For the robot size (arrow length) and the ellipse probability (``gdop_level``).
    eps_max : float
        Allowed error [m], drawn as a constant series.
    ent : module or namespace
        Where the entities go: :mod:`interop.recording.entities`, or a fleet robot's
        (:func:`interop.recording.entities.of_robot`).
    """
    t = np.asarray(steps.t, dtype=float)
    if len(t) == 0:
        return
    arrow = 1.5 * scenario.robot.radius
    _log_pose(rec, ent.ROBOT_TRUE, t, steps.true_pose, arrow, E.TRUE)
    _log_pose(rec, ent.ROBOT_ESTIMATE, t, steps.est_pose, arrow, E.ESTIMATE)
    # The trails are static full paths: the moving points show "now", the trails show the
    # whole run at once (a growing strip would cost O(T^2) points).
    rec.log(ent.TRUE_TRAIL, rr.LineStrips2D([steps.true_pose[:, :2]], colors=[E.TRUE], radii=_ui(E.LINE_PT)),
            static=True)
    rec.log(ent.ESTIMATE_TRAIL, rr.LineStrips2D([steps.est_pose[:, :2]], colors=[E.ESTIMATE],
                                              radii=_ui(E.LINE_PT)), static=True)
    rings = covariance_ellipses(steps.est_pose[:, :2], steps.est_cov[:, :2, :2], scenario.planning.gdop_level)
    rec.log(ent.COVARIANCE, rr.LineStrips2D.from_fields(colors=[E.ESTIMATE], radii=_ui(E.LINE_PT)), static=True)
    rec.send_columns(ent.COVARIANCE, _index(t), rr.LineStrips2D.columns(strips=rings))

    _log_scalar(rec, ent.ERROR, t, steps.error, "error |true - estimate|", E.TRUE)
    _log_scalar(rec, ent.PREDICTED_TAU, t, _finite_or_nan(steps.predicted_tau), "predicted τ (schedule)",
                E.CHOSEN_ROUTE)
    _log_scalar(rec, ent.PEF_TAU, t, _finite_or_nan(steps.pef_tau), "PEF τ (best subset)", E.GREY,
                visible=False)
    ends = np.array([t[0], t[-1]])
    _log_scalar(rec, ent.EPS_MAX, ends, np.full(2, eps_max), "ε_max", E.EPS_LINE)
    _log_scalar(rec, ent.NEES, t, _finite_or_nan(steps.nees), "NEES (3 dof)", E.ESTIMATE)
    _log_scalar(rec, ent.NEES_UPPER, ends, np.full(2, CHI2_3DOF_975), "χ²₃ 97.5 %", E.EPS_LINE)

    exceed = np.asarray(steps.error, dtype=float) > eps_max
    starts = np.flatnonzero(exceed & ~np.concatenate([[False], exceed[:-1]]))
    if len(starts):
        err = np.asarray(steps.error, dtype=float)
        rec.send_columns(ent.EVENTS, _index(t[starts]), rr.TextLog.columns(
            text=[f"error {1000 * err[i]:.2f} mm exceeds ε_max {1000 * eps_max:.2f} mm" for i in starts],
            level=["WARN"] * len(starts)))


def log_fixes(rec: rr.RecordingStream, fixes: FixLog, scenario: Scenario,
              predicted_polygons: list[np.ndarray] | None = None, ent=E) -> None:
    """Log per-fix rays, realised and predicted fault areas, snapshot fixes and fix metrics.

    Parameters
    ----------
    rec : rerun.RecordingStream
        Target stream.
    fixes : sim.episode.types.FixLog
        F fixes of k markers.
    scenario : scenarios.schema.Scenario
        For marker positions and ids.
    predicted_polygons : list of F (n, 2) arrays, optional
        Predicted fault areas at the true positions [m]. Default: the linearised strip
        polygon of each fix's markers and bounds ``rho`` at its true position.
    ent : module or namespace
        Where the entities go (see :func:`log_steps`).
    """
    t = np.asarray(fixes.t, dtype=float)
    n_fix = len(t)
    if n_fix == 0:
        return
    markers = np.asarray(fixes.markers, dtype=int).reshape(n_fix, -1)
    k = markers.shape[1]
    marker_xy = scenario.marker_positions()[markers]                         # (F, k, 2)
    true_xy = np.asarray(fixes.true_position, dtype=float)
    ids = np.array(scenario.marker_ids(), dtype=object)
    idx = _index(t)

    rays = np.stack([np.repeat(true_xy, k, axis=0), marker_xy.reshape(-1, 2)], axis=1)  # (F*k, 2, 2)
    rec.log(ent.FIX_RAYS, rr.LineStrips2D.from_fields(colors=[E.RAY], radii=_ui(E.LINE_PT)), static=True)
    ray_cols = rr.LineStrips2D.columns(strips=rays, labels=list(ids[markers.ravel()]))
    rec.send_columns(ent.FIX_RAYS, idx, ray_cols.partition([k] * n_fix))  # k rays per fix

    contained = np.asarray(fixes.contained, dtype=bool)
    rec.log(ent.FIX_FAULT_AREA, rr.LineStrips2D.from_fields(radii=_ui(E.THICK_LINE_PT)), static=True)
    rec.send_columns(ent.FIX_FAULT_AREA, idx, rr.LineStrips2D.columns(
        strips=[np.asarray(p, dtype=float).reshape(-1, 2) for p in fixes.fault_polygons],
        colors=[E.CONTAINED if c else E.NOT_CONTAINED for c in contained]))

    if predicted_polygons is None:
        predicted_polygons = strip_polygons(true_xy, marker_xy, np.asarray(fixes.rho, dtype=float))
    rec.log(ent.FIX_PREDICTED, rr.LineStrips2D.from_fields(colors=[E.PREDICTED], radii=_ui(E.LINE_PT)),
            static=True)
    rec.send_columns(ent.FIX_PREDICTED, idx, rr.LineStrips2D.columns(
        strips=[np.asarray(p, dtype=float).reshape(-1, 2) for p in predicted_polygons]))

    for entity, xy, color in ((ent.FIX_SNAPSHOT, fixes.snapshot, E.SNAPSHOT), (ent.FIX_TRUE, true_xy, E.TRUE)):
        rec.log(entity, rr.Points2D.from_fields(colors=[color], radii=_ui(E.POINT_PT)), static=True)
        rec.send_columns(entity, idx, rr.Points2D.columns(positions=np.asarray(xy, dtype=float)))

    _log_scalar(rec, ent.FAULT_DIAMETER, t, _finite_or_nan(fixes.fault_diameter), "fault-area diameter (fix)",
                E.CONTAINED, points=True)
    _log_scalar(rec, ent.FIX_PREDICTED_TAU, t, _finite_or_nan(fixes.predicted_tau), "PEF τ of the fix's subset",
                E.PREDICTED, points=True)
    _log_scalar(rec, ent.NIS, t, _finite_or_nan(fixes.nis), "NIS (per fix)", E.NIS_POINT, points=True)

    diam, pred = np.asarray(fixes.fault_diameter, float), np.asarray(fixes.predicted_tau, float)
    ok = contained & (diam <= pred)
    text = [f"fix {i}: {'+'.join(ids[markers[i]])}, fault diameter {1000 * diam[i]:.2f} mm vs predicted "
            f"{1000 * pred[i]:.2f} mm, true position {'inside' if contained[i] else 'OUTSIDE'} the fault area"
            for i in range(n_fix)]
    levels = np.where(ok, "INFO", "WARN").tolist()
    rec.send_columns(ent.EVENTS, idx, rr.TextLog.columns(text=text, level=levels))


def summary_markdown(result: EpisodeResult) -> str:
    """Markdown table of ``result.summary`` (plus scenario, task and seed)."""
    rows = [f"# {result.scenario_name}, task {result.task_index}, seed {result.seed}", "",
            "| key | value |", "|---|---|"]
    for key, value in result.summary.items():
        shown = f"{value:.6g}" if isinstance(value, float) else str(value)
        rows.append(f"| {key} | {shown} |")
    return "\n".join(rows) + "\n"


def log_result(rec: rr.RecordingStream, result: EpisodeResult, scenario: Scenario,
               predicted_polygons: list[np.ndarray] | None = None, ent=E) -> None:
    """Log a whole episode (steps, fixes, summary); see :func:`interop.recording.log_episode`.

    ``ent``: where its entities go (:func:`log_steps`); a fleet's robot is not the recording's name.
    """
    if ent is E:
        rec.send_recording_name(f"{result.scenario_name} task {result.task_index} seed {result.seed}")
    log_steps(rec, result.steps, scenario, result.eps_max, ent)
    log_fixes(rec, result.fixes, scenario, predicted_polygons, ent)
    rec.log(ent.SUMMARY, rr.TextDocument(summary_markdown(result), media_type="text/markdown"), static=True)
