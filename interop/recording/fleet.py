"""Recording of a fleet episode: every robot, its estimate, fault areas and rays, the hidden lines of sight.

Each robot's episode goes under its own entities (:func:`interop.recording.entities.of_robot`:
``world/robots/<name>/...``, ``metrics/<name>/...``), drawn as a single robot's are; on top,
``world/robots/<name>/fix/blocked_rays`` holds, at each fix, the lines of sight to scheduled
markers that another robot's body hid (labelled ``<marker> hidden by <robot>``), and
``world/blocked`` all of them at once (static): the map of where robots hid reflectors.
``world/robots/<name>/reserved`` is the stretch of its path the robot held (zone control), at
:data:`RESERVATION_HZ`.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from interop.recording import close, log_static, open_recording
from interop.recording import entities as E
from interop.recording.episode import _index, _ui, log_result
from scenarios.schema import Scenario

BLOCKED = (255, 60, 60)
"""Colour of a line of sight another robot hid."""
RESERVED = (120, 255, 120)
"""Colour of a robot's reservation."""
RESERVATION_HZ = 5.0
"""Rate at which reservations are drawn [Hz] (each is a stretch of path: at the control rate a
long episode's would be tens of megabytes)."""


def reservation_strips(reserved: np.ndarray, path: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
    """Return the reserved stretches of ``path`` (N, 2) at :data:`RESERVATION_HZ`.

    Returns their times, shape (R',) [s], and the strips, each shape (n_i, 2) [m].
    """
    reserved = np.asarray(reserved, float).reshape(-1, 3)
    if not len(reserved) or len(path) < 2:
        return np.zeros(0), []
    keep = np.flatnonzero(np.diff(np.floor(reserved[:, 0] * RESERVATION_HZ), prepend=-1.0) > 0)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(path, axis=0).T))])
    strips = []
    for _, a, b in reserved[keep]:
        inside = (s > a) & (s < b)
        ends = [np.array([np.interp(v, s, path[:, 0]), np.interp(v, s, path[:, 1])]) for v in (a, max(a, b))]
        strips.append(np.vstack([ends[0], path[inside], ends[1]]))
    return reserved[keep, 0], strips


def blueprint(names: list[str]) -> rrb.Blueprint:
    """Lay out the map on the left; per robot its error plot and its fixes' events on the right."""
    map_view = rrb.Spatial2DView(name="Fleet (workspace, metres)", origin="/", contents=[f"/{E.WORLD}/**"])
    plots = [rrb.TimeSeriesView(name=f"{n}: error vs predicted bound", origin=f"/{E.METRICS}/{n}") for n in names]
    events = [rrb.TextLogView(name=f"{n}: fixes", origin=f"/{E.EVENTS}/{n}") for n in names]
    return rrb.Blueprint(
        rrb.Horizontal(map_view, rrb.Vertical(rrb.Tabs(*plots), rrb.Tabs(*events), row_shares=[3, 2]),
                       column_shares=[3, 2]),
        rrb.BlueprintPanel(state="collapsed"), rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="expanded", timeline=E.TIMELINE))


def hidden_rays(result: Any, scenario: Scenario, names: list[str]) -> tuple[np.ndarray, list[np.ndarray], list[str]]:
    """Return the lines of sight other robots hid at one robot's fixes.

    Returns
    -------
    t : ndarray, shape (F,)
        Fix times [s].
    rays : list of F arrays, shape (h_f, 2, 2)
        From the robot's true position at the fix to each hidden marker [m].
    labels : list of str
        ``<marker> hidden by <robot>``, one per ray, fix after fix.
    """
    fixes = result.fixes
    xy = scenario.marker_positions()
    ids = scenario.marker_ids()
    rays, labels = [], []
    for f, note in enumerate(fixes.notes or [None] * len(fixes.t)):
        items = sorted(note.hidden.items()) if note is not None else []
        start = np.asarray(fixes.true_position[f], float)
        rays.append(np.array([[start, xy[m]] for m, _ in items], dtype=float).reshape(-1, 2, 2))
        labels += [f"{ids[m]} hidden by {names[j]}" for m, j in items]
    return np.asarray(fixes.t, float), rays, labels


def log_fleet(rec: rr.RecordingStream, fleet: Any, scenario: Scenario) -> None:
    """Log every robot of a :class:`~sim.episode.types.FleetResult` and the lines of sight robots hid."""
    names = [r.name for r in fleet.robots]
    every = []
    for r in fleet.robots:
        ent = E.of_robot(r.name)
        log_result(rec, r.result, scenario, ent=ent)
        t, rays, labels = hidden_rays(r.result, scenario, names)
        if len(t):
            rec.log(ent.BLOCKED_RAYS, rr.LineStrips2D.from_fields(colors=[BLOCKED], radii=_ui(E.THICK_LINE_PT)),
                    static=True)
            cols = rr.LineStrips2D.columns(strips=[s for ray in rays for s in ray], labels=labels)
            rec.send_columns(ent.BLOCKED_RAYS, _index(t), cols.partition([len(ray) for ray in rays]))
        every += [s for ray in rays for s in ray]
        t_res, strips = reservation_strips(r.reserved, r.path)
        if len(t_res):
            rec.log(ent.RESERVED, rr.LineStrips2D.from_fields(colors=[RESERVED], radii=_ui(E.THICK_LINE_PT)),
                    static=True)
            rec.send_columns(ent.RESERVED, _index(t_res), rr.LineStrips2D.columns(strips=strips))
    if every:
        rec.log(E.BLOCKED_MAP, rr.LineStrips2D(every, colors=[BLOCKED], radii=_ui(E.LINE_PT)), static=True)


def write_fleet_rrd(path: str | os.PathLike[str], scenario: Scenario, fleet: Any, pef_map: Any = None) -> Path:
    """Write a recording of a fleet episode with its scene and map; returns the path."""
    rec = open_recording(path, layout=blueprint([r.name for r in fleet.robots]))
    try:
        rec.send_recording_name(f"{scenario.name} fleet of {len(fleet.robots)}")
        log_static(rec, scenario, pef_map)
        log_fleet(rec, fleet, scenario)
    finally:
        close(rec)
    return Path(path)
