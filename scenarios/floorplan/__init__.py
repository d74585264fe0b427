"""Floor plans read into a scenario: DXF drawings (``dxf``) and ROS occupancy maps (``rosmap``).

:func:`apply` is the loader's one step: it reads the ``[floorplan]`` table, reads the file,
and merges its obstacles, markers and unknown areas into the document's ``obstacles`` /
``markers`` / ``unknown`` lists (after the hand-written ones, so those keep their indices in
error messages) before the document is validated; ``workspace.size`` and ``workspace.origin``
default to the plan's extent (a ROS map: its known cells' bounding box) and ``workspace.walls``
to false for a ROS map (its edge is no wall). The readers import ezdxf and Pillow only when a scenario has a floor plan.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from scenarios.errors import ScenarioError
from scenarios.fields import Table, show, show_path
from scenarios.files import unreadable_because
from scenarios.floorplan.spec import UNITS, FloorPlan, FloorPlanData, FloorPlanKind

__all__ = ["FloorPlan", "FloorPlanData", "FloorPlanKind", "apply", "portable_text", "read"]

_SUFFIX = {".dxf": FloorPlanKind.DXF, ".yaml": FloorPlanKind.ROSMAP, ".yml": FloorPlanKind.ROSMAP}
_DXF_ONLY = ("units", "obstacle_layers", "marker_layer", "wall_thickness")
DEFAULT_WALL_THICKNESS = 0.2  # [m]
DEFAULT_SIMPLIFY = 0.02       # [m]


def _file(t: Table, base: Path | None) -> tuple[Path, str, FloorPlanKind]:
    shown = t.string("file")
    path = Path(shown).expanduser()
    if not path.is_absolute():
        path = (base if base is not None else Path.cwd()) / path
    kind = _SUFFIX.get(path.suffix.lower())
    if kind is None:
        t.fail(t.key("file"), "expected a DXF drawing (.dxf) or a ROS map_server YAML (.yaml)", shown)
    why = unreadable_because(path)  # a FIFO or a device is not a floor plan (reading it could block)
    if why is not None:  # the file system's own reason (a name too long) is said without the path
        t.fail(t.key("file"), f"cannot read {show_path(path)}: {why}" if why[0].islower() else f"cannot read: {why}",
               shown)
    return path.resolve(), shown, kind


def read(t: Table, base: Path | None) -> tuple[FloorPlan, FloorPlanData]:
    """Read the ``[floorplan]`` table ``t`` and the file it names.

    Parameters
    ----------
    t : Table
        The ``floorplan`` table of a scenario document.
    base : Path or None
        Folder that a relative ``file`` is relative to (the scenario file's); None: the
        working directory.
    """
    path, shown, kind = _file(t, base)
    where = f"{t.file}: {t.path}"
    if t.has("simplify"):
        simplify = t.number("simplify", low=0.0)
    else:  # a ROS map's default is its resolution, known once it is read
        simplify = DEFAULT_SIMPLIFY if kind is FloorPlanKind.DXF else None
    if kind is FloorPlanKind.ROSMAP:
        for k in _DXF_ONLY:
            if t.has(k):
                t.fail(t.key(k), "expected no such key for a ROS map (it is for DXF drawings)", t.data[k])
        t.done()
        from scenarios.floorplan.rosmap import read_rosmap

        data = read_rosmap(path, simplify=simplify, where=where, shown=shown)
        layers: tuple[str, ...] = ()
        marker_layer = None
        wall = 0.0
    else:
        units = t.string("units", None, choices=tuple(UNITS)) if t.has("units") else None
        raw_layers = t.raw("obstacle_layers")
        if not (isinstance(raw_layers, list) and raw_layers and all(isinstance(x, str) for x in raw_layers)):
            t.fail(t.key("obstacle_layers"), "expected a non-empty list of layer names", raw_layers)
        layers = tuple(raw_layers)
        marker_layer = t.string("marker_layer", None) if t.has("marker_layer") else None
        wall = t.number("wall_thickness", DEFAULT_WALL_THICKNESS, low=0.0, low_open=True)
        t.done()
        from scenarios.floorplan.dxf import read_dxf

        data = read_dxf(path, obstacle_layers=layers, marker_layer=marker_layer, units=units,
                        wall_thickness=wall, simplify=simplify, where=where, shown=shown)
    plan = FloorPlan(file=path, kind=kind, units=data.units, unit_factor=data.unit_factor,
                     obstacle_layers=layers, marker_layer=marker_layer, wall_thickness=wall,
                     simplify=data.simplify, extent=data.extent, files=(path, *data.images),
                     resolution=data.resolution)
    return plan, data


def apply(data: dict[str, Any], source: str, base: Path | None) -> tuple[dict[str, Any], FloorPlan | None]:
    """Merge a document's floor plan into its ``obstacles``, ``markers`` and ``workspace``.

    Parameters
    ----------
    data : dict
        A parsed scenario document (not modified).
    source : str
        The scenario's name in error messages.
    base : Path or None
        Folder of the scenario file (relative floor-plan paths start there).

    Returns
    -------
    data : dict
        The document without ``floorplan``, with the plan's obstacles and markers appended
        and the workspace defaulted to the plan's extent (given values override).
    plan : FloorPlan or None
        None when the document has no ``[floorplan]``.
    """
    if "floorplan" not in data:
        return data, None
    t = Table(data["floorplan"], source, "floorplan")
    plan, found = read(t, base)
    out = dict(data)
    del out["floorplan"]
    _check_ids(out.get("markers"), found, source, plan)
    for key, items in (("obstacles", found.obstacles), ("markers", found.markers), ("unknown", found.unknown)):
        if key == "unknown" and not items and key not in out:
            continue  # a drawing knows everything: the document stays as it was
        given = out.get(key, [])
        if isinstance(given, list):  # anything else: the loader names the bad value
            out[key] = given + items
    _check_markers(found, source, plan)
    ws = out.get("workspace", {})
    if isinstance(ws, dict):
        ws = dict(ws)
        xmin, ymin, xmax, ymax = found.known or found.extent
        ws.setdefault("origin", [xmin, ymin])
        if not found.walls:
            ws.setdefault("walls", False)
        o = ws["origin"]
        if "size" not in ws and isinstance(o, list) and len(o) == 2 and all(isinstance(v, (int, float)) for v in o):
            # The far corner of the plan stays the far corner when only the origin is given.
            ws["size"] = [round(xmax - o[0], 9), round(ymax - o[1], 9)]  # no float noise in the file
        out["workspace"] = ws
    return out, plan


def _check_ids(given: Any, found: FloorPlanData, source: str, plan: FloorPlan) -> None:
    """Name both sides when a hand-written marker's id is also a reflector's of the drawing.

    The drawing's reflectors are appended after the ``[[markers]]`` tables, so the loader's
    own check would name an index the file does not have.
    """
    if not isinstance(given, list) or not found.markers:
        return
    drawn = {m["id"]: m for m in found.markers}
    for i, t in enumerate(given):
        mid = t.get("id") if isinstance(t, dict) else None
        if isinstance(mid, str) and mid in drawn:
            how = ("the id generated for the drawing's reflector without an ID attribute" if mid in found.generated_ids
                   else "the ID of the drawing's reflector")
            raise ScenarioError(f"{source}: markers[{i}].id: expected a unique marker id, {show(mid)} is also {how} "
                                f"at {show(drawn[mid]['position'])} in {plan.file.name} "
                                f"(layer {show(plan.marker_layer)}): rename one")


def _check_markers(found: FloorPlanData, source: str, plan: FloorPlan) -> None:
    """Name the drawing when one of its reflectors lies inside one of its obstacles."""
    import shapely

    if not found.markers:
        return
    shapes = []
    for ob in found.obstacles:
        if "polygon" in ob:
            shapes.append(shapely.Polygon(ob["polygon"], ob.get("holes", [])))
        else:
            shapes.append(shapely.Point(ob["center"]).buffer(ob["radius"]))
    tree = shapely.STRtree(shapes)
    for m in found.markers:
        p = shapely.Point(m["position"])
        for j in tree.query(p, predicate="within"):
            if shapes[j].boundary.distance(p) > 1e-6:
                raise ScenarioError(
                    f"{source}: floorplan.marker_layer: expected reflectors outside obstacles (on a face is "
                    f"fine); {plan.file.name}: {show(m['id'])} at {show(m['position'])} is inside one")


def portable_text(text: str, data: dict[str, Any], base: Path | None) -> str:
    """Return the scenario text with a relative ``floorplan.file`` made absolute.

    ``Scenario.text`` is stored beside results (``pefsim mc``) and loaded again from there;
    a path relative to the original scenario file would not resolve. Texts without a
    relative floor-plan path are returned unchanged (comments kept); otherwise the text is
    re-serialised (comments lost).
    """
    fp = data.get("floorplan")
    if base is None or not isinstance(fp, dict) or not isinstance(fp.get("file"), str):
        return text
    if Path(fp["file"]).expanduser().is_absolute():
        return text
    import tomli_w

    out = dict(data)
    try:
        absolute = (base / fp["file"]).resolve()
    except (OSError, RuntimeError):  # a link loop, a name too long: the reader names the cause
        return text
    out["floorplan"] = {**fp, "file": str(absolute)}
    return tomli_w.dumps(out)
