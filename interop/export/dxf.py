"""DXF export: the scenario's drawing with the reflectors, the accuracy region and the routes added.

The output is a copy of the scenario's floor-plan drawing (``Scenario.floorplan``), or a new
drawing in metres when the scenario has none (then its obstacles are drawn too), with three
layers of its own:

- ``PEFSIM-MARKERS``: each reflector as an INSERT of block ``PEFSIM_REFLECTOR`` with an
  ``ID`` attribute, rotated by the marker's facing; a floor plan read with
  ``marker_layer = "PEFSIM-MARKERS"`` gives the same markers back;
- ``PEFSIM-REGION``: the contour τ = ε_max as LWPOLYLINEs;
- ``PEFSIM-ROUTES``: each admissible route segment as an LWPOLYLINE (its id in XDATA,
  application ``PEFSIM``) with a TEXT label: its edge ids and its worst τ along it in mm
  (``max tau 12.3 mm``; ``no fix`` where some point has none);
- ``PEFSIM-ROUTES-INADMISSIBLE``: the same for the segments the planner will not drive (τ or
  clearance; drawn in red).

Labels sit beside their segments and do not overlap (:mod:`interop.export.labels`).

Everything is in the drawing's units and frame: a scenario point (x, y) [m] is
(x, y) / unit_factor in the drawing. Entities already on these layers (a drawing exported
before) are replaced.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from ezdxf.enums import TextEntityAlignment

from interop.export.labels import place_labels
from scenarios.errors import output_errors
from scenarios.schema import Scenario

MARKER_LAYER = "PEFSIM-MARKERS"
REGION_LAYER = "PEFSIM-REGION"
ROUTE_LAYER = "PEFSIM-ROUTES"
BAD_ROUTE_LAYER = "PEFSIM-ROUTES-INADMISSIBLE"
OBSTACLE_LAYER = "PEFSIM-OBSTACLES"  # new drawings only: a copy keeps its own obstacles
MARKER_BLOCK = "PEFSIM_REFLECTOR"
APPID = "PEFSIM"
_COLOURS = {MARKER_LAYER: 1, REGION_LAYER: 3, ROUTE_LAYER: 5, BAD_ROUTE_LAYER: 1,
            OBSTACLE_LAYER: 8}  # red, green, blue, red, grey
MARKER_SIZE = 0.1    # reflector symbol diameter [m]
LABEL_HEIGHT = 0.25  # route label height [m]


def _drawing(scenario: Scenario):
    """Return the drawing to add to and its metres per unit: a copy of the floor plan, or a new one."""
    import ezdxf

    plan = scenario.floorplan
    if plan is not None and plan.kind.value == "dxf":
        from scenarios.floorplan.dxf import open_dxf

        where = f"{scenario.source}: floorplan"
        return open_dxf(plan.file, where, str(plan.file)), plan.unit_factor, False
    doc = ezdxf.new("R2013", setup=True)
    doc.header["$INSUNITS"] = 6  # metres
    doc.header["$MEASUREMENT"] = 1
    return doc, 1.0, True


def _clear(doc, layers: Sequence[str]) -> None:
    msp = doc.modelspace()
    names = {n.upper() for n in layers}
    for e in list(msp):
        if e.dxf.get("layer", "0").upper() in names:
            msp.delete_entity(e)


def _marker_block(doc, unit: float) -> None:
    if MARKER_BLOCK in doc.blocks:
        return
    blk = doc.blocks.new(MARKER_BLOCK)
    r = 0.5 * MARKER_SIZE / unit
    blk.add_circle((0, 0), r)
    blk.add_line((0, 0), (2 * r, 0))  # points where the reflector faces (block +x)
    blk.add_attdef("ID", (r, r), dxfattribs={"height": r})


def _open_or_closed(points: np.ndarray) -> tuple[np.ndarray, bool]:
    if len(points) > 2 and np.allclose(points[0], points[-1]):
        return points[:-1], True
    return points, False


def _obstacles(msp, scenario: Scenario, unit: float) -> None:
    """Draw the scenario's obstacles (a new drawing has no others)."""
    attribs = {"layer": OBSTACLE_LAYER}
    for ob in scenario.obstacles:
        if ob.kind == "circle":
            msp.add_circle(np.asarray(ob.center) / unit, ob.radius / unit, dxfattribs=attribs)
            continue
        rings = ob.rings()
        for ring in rings:
            msp.add_lwpolyline((np.asarray(ring) / unit).tolist(), close=True, dxfattribs=attribs)


def route_label(rid: str, max_tau: float | None) -> str:
    """Label of a route segment: its ids and worst τ in mm (just the ids when τ is not known)."""
    if max_tau is None:
        return str(rid)
    return f"{rid} max tau {max_tau * 1000:.1f} mm" if math.isfinite(max_tau) else f"{rid} no fix"


def write_dxf(scenario: Scenario, out_path: str | Path, *, region_contours: Sequence[np.ndarray],
              route_lines: Sequence[tuple[str, np.ndarray]], route_reports: Sequence | None = None) -> Path:
    """Write the scenario's drawing with reflectors, accuracy region and routes to ``out_path``.

    Parameters
    ----------
    scenario : Scenario
        Its ``floorplan`` (a DXF) is copied; its markers go to ``PEFSIM-MARKERS``.
    out_path : path
        The DXF file to write (nothing else is written).
    region_contours : sequence of ndarray, each shape (n, 2) [m]
        The contour τ = ε_max in the scenario's (user) frame; a contour whose last point is
        its first is written closed.
    route_lines : sequence of (str, ndarray of shape (n, 2) [m])
        Route id and its polyline in the user frame.
    route_reports : sequence of planner.routes.edges.SegmentReport, optional
        The PEF along each route line (same order): its worst τ labels it and an inadmissible
        one goes to ``PEFSIM-ROUTES-INADMISSIBLE``. Without them every line is labelled with
        its id only, on ``PEFSIM-ROUTES``.

    Returns
    -------
    Path
        ``out_path``.

    Raises
    ------
    OutputError
        The file cannot be written.
    ScenarioError
        The scenario's drawing cannot be read any more.
    """
    out = Path(out_path)
    doc, unit, new = _drawing(scenario)
    if not doc.appids.has_entry(APPID):
        doc.appids.add(APPID)
    for name, colour in _COLOURS.items():
        if name == OBSTACLE_LAYER and not new:
            continue
        if name not in doc.layers:
            doc.layers.add(name, color=colour)
    _clear(doc, (MARKER_LAYER, REGION_LAYER, ROUTE_LAYER, BAD_ROUTE_LAYER))
    msp = doc.modelspace()
    if new:
        _obstacles(msp, scenario, unit)
    _marker_block(doc, unit)
    for m in scenario.markers:
        rot = 0.0 if m.facing is None else math.degrees(m.facing) % 360.0
        ref = msp.add_blockref(MARKER_BLOCK, (m.position[0] / unit, m.position[1] / unit),
                               dxfattribs={"layer": MARKER_LAYER, "rotation": rot})
        ref.add_auto_attribs({"ID": m.id})
    for contour in region_contours:
        pts, closed = _open_or_closed(np.asarray(contour, dtype=float).reshape(-1, 2))
        if len(pts) >= 2:
            msp.add_lwpolyline((pts / unit).tolist(), close=closed, dxfattribs={"layer": REGION_LAYER})
    lines, texts, layers = [], [], []
    for i, (rid, line) in enumerate(route_lines):
        pts = np.asarray(line, dtype=float).reshape(-1, 2) / unit
        if len(pts) < 2:
            continue
        rep = route_reports[i] if route_reports is not None else None
        layer = ROUTE_LAYER if rep is None or rep.admissible else BAD_ROUTE_LAYER
        poly = msp.add_lwpolyline(pts.tolist(), dxfattribs={"layer": layer})
        poly.set_xdata(APPID, [(1000, str(rid))])
        lines.append(pts)
        texts.append(route_label(rid, None if rep is None else rep.max_tau))
        layers.append(layer)
    height = LABEL_HEIGHT / unit
    for text, layer, corner in zip(texts, layers, place_labels(lines, texts, height), strict=True):
        msp.add_text(text, height=height, dxfattribs={"layer": layer}).set_placement(
            corner, align=TextEntityAlignment.BOTTOM_LEFT)
    with output_errors(out, "write the DXF drawing"):
        doc.saveas(out)
    return out
