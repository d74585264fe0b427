"""What a floor plan is: the ``[floorplan]`` spec a scenario keeps, and what a reader returns."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path


class FloorPlanKind(str, Enum):
    """The kind of file a floor plan is read from (chosen by its suffix)."""

    DXF = "dxf"
    """A CAD drawing (``.dxf``), read with ezdxf."""
    ROSMAP = "rosmap"
    """A ROS map_server occupancy map: a YAML file (``.yaml``/``.yml``) and the image it names."""


@dataclass(frozen=True)
class FloorPlan:
    """The floor plan a scenario was built from (``Scenario.floorplan``).

    Attributes
    ----------
    file : Path
        Absolute path of the drawing or the map YAML.
    kind : FloorPlanKind
        DXF drawing or ROS map.
    units : str
        Name of the drawing unit ("mm", "m", ...; "m" for a ROS map).
    unit_factor : float
        Metres per drawing unit [m/unit]; a point (x, y) of the drawing is
        (x, y) * unit_factor in the scenario (same frame, no offset).
    obstacle_layers : tuple of str
        DXF layers read as obstacles (empty for a ROS map).
    marker_layer : str or None
        DXF layer read as markers (reflectors).
    wall_thickness : float
        Thickness of walls made of open lines [m].
    simplify : float
        Polygon simplification tolerance [m].
    extent : tuple of float
        (xmin, ymin, xmax, ymax) of what was read [m], in the scenario's (user) frame.
    """

    file: Path
    kind: FloorPlanKind
    units: str
    unit_factor: float
    obstacle_layers: tuple[str, ...]
    marker_layer: str | None
    wall_thickness: float
    simplify: float
    extent: tuple[float, float, float, float]
    files: tuple[Path, ...] = ()
    """Every file read, absolute: the drawing, or the map YAML and its image."""
    resolution: float = 0.0
    """A ROS map's cell size [m] (its grid is ``extent`` in cells of this size); 0 for a drawing."""


@dataclass(frozen=True)
class FloorPlanData:
    """What a floor-plan reader returns, in the scenario's TOML form and in metres.

    Attributes
    ----------
    obstacles : list of dict
        ``{"polygon": [[x, y], ...], "holes": [[[x, y], ...], ...]}`` (holes optional) or
        ``{"center": [x, y], "radius": r}``.
    markers : list of dict
        ``{"id": str, "position": [x, y]}`` plus ``"facing_deg": float`` when the drawing
        gives a direction (an INSERT's rotation).
    extent : tuple of float
        (xmin, ymin, xmax, ymax) [m] of the obstacles and markers read (a ROS map: the
        whole image).
    unit_factor : float
        Metres per drawing unit.
    units : str
        Name of the drawing unit.
    simplify : float
        The simplification tolerance the reader used [m].
    """

    obstacles: list[dict] = field(default_factory=list)
    markers: list[dict] = field(default_factory=list)
    extent: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    unit_factor: float = 1.0
    units: str = "m"
    simplify: float = 0.0
    images: tuple[Path, ...] = ()
    """Files read besides the one named (a ROS map's image), absolute."""
    unknown: list[dict] = field(default_factory=list)
    """Areas the plan does not know (a ROS map's unknown cells), in the obstacles' form."""
    known: tuple[float, float, float, float] | None = None
    """(xmin, ymin, xmax, ymax) [m] of what the plan knows (a ROS map's free and occupied cells),
    the default workspace; None: ``extent``."""
    walls: bool = True
    """Whether the workspace border is a wall (False for a ROS map: its edge is none)."""
    resolution: float = 0.0
    """A ROS map's cell size [m]; 0 for a drawing."""
    generated_ids: frozenset[str] = frozenset()
    """Ids of ``markers`` the reader generated (``R1``, ... for reflectors without an ``ID``)."""


# Unit names accepted by ``floorplan.units``, in metres per unit.
UNITS: dict[str, float] = {
    "m": 1.0, "mm": 1e-3, "cm": 1e-2, "dm": 0.1, "dam": 10.0, "hm": 100.0, "km": 1e3, "um": 1e-6,
    "in": 0.0254, "ft": 0.3048, "yd": 0.9144, "mi": 1609.344, "mil": 2.54e-5, "us_ft": 1200.0 / 3937.0,
}

# DXF header $INSUNITS codes (AutoCAD's table) of the units above; 0 means unitless.
INSUNITS: dict[int, str] = {
    1: "in", 2: "ft", 3: "mi", 4: "mm", 5: "cm", 6: "m", 7: "km", 9: "mil", 10: "yd", 13: "um",
    14: "dm", 15: "dam", 16: "hm", 21: "us_ft",
}
