"""The route network of a scenario: named nodes, undirected segments, their ids and provenance.

Built by :mod:`scenarios.routegraph` from a hand-written ``[routes]`` table or a graph file
(Nav2 GeoJSON, VDA LIF); re-exported by :mod:`scenarios.schema`. Imports nothing from pefsim.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path


@dataclass(frozen=True)
class RouteEdge:
    """Identity and provenance of one undirected segment of a route network.

    An imported graph's directed edges between the same two nodes (usually a pair of opposite
    edges) become one segment that keeps every edge's id, direction and properties.

    Attributes
    ----------
    ids : tuple of str
        Edge ids, one per directed edge merged into the segment (file order); a hand-written
        segment gets two generated ids, one per direction (see :attr:`RouteNetwork.node_ids`).
    ends : tuple of (str, str)
        (start node, end node) of each id, node names.
    properties : tuple of dict
        The other properties of each directed edge (everything but ``id``, ``startid``,
        ``endid``), as read from the file; empty dicts for hand-written segments.
    why_not : str
        Why the segment may not be driven ("" if it may): an imported edge that crosses an
        obstacle or passes closer than the robot radius is kept but marked, e.g.
        ``"crosses obstacles[0]"``.
    """

    ids: tuple[str, ...]
    ends: tuple[tuple[str, str], ...]
    properties: tuple[dict, ...] = ()
    why_not: str = ""

    @property
    def admissible(self) -> bool:
        return not self.why_not


@dataclass(frozen=True)
class RouteNetwork:
    """A route network (paper fig. 7): named nodes, undirected segments, traffic per segment.

    ``traffic`` maps a segment key ``"a-b"`` (either order) to a density in [0, 1].

    Attributes
    ----------
    nodes : dict[str, (float, float)]
        Node name -> position (x, y) [m]. An imported graph's nodes are named by their id.
    segments : tuple of (str, str)
        Undirected segments, node names.
    traffic : dict[str, float]
    edges : tuple of RouteEdge
        One per segment (same order): ids, directions, properties, admissibility; empty only
        for a network built in code without them.
    node_ids : dict[str, str]
        Node name -> id. An imported graph's node ids are its names; hand-written nodes get
        ``"0", "1", ...`` in file order and segment i the directed edges ``n + 2i`` (a -> b) and
        ``n + 2i + 1`` (b -> a) (n nodes), so ids are unique across nodes and edges, as Nav2's
        route server requires.
    node_properties : dict[str, dict]
        Node name -> the other properties read from the file (``frame``, ``metadata``, ...).
    source : str
        The graph file as named in errors ("" for a hand-written network).
    layout : str
        The LIF layout read (``routes.layout``), "" if none was named.
    """

    nodes: dict[str, tuple[float, float]]
    segments: tuple[tuple[str, str], ...]
    traffic: dict[str, float] = field(default_factory=dict)
    edges: tuple[RouteEdge, ...] = ()
    node_ids: dict[str, str] = field(default_factory=dict)
    node_properties: dict[str, dict] = field(default_factory=dict)
    # how the file is named, not what it holds: the same graph read as "g.geojson" and as
    # "/abs/g.geojson" (a scenario's portable text) is the same network
    source: str = field(default="", compare=False)
    layout: str = ""
    file: Path | None = field(default=None, compare=False)
    """The graph file read, absolute (None for a hand-written network)."""

    def traffic_of(self, a: str, b: str) -> float:
        """Traffic density of segment a–b (0 when not listed)."""
        return self.traffic.get(f"{a}-{b}", self.traffic.get(f"{b}-{a}", 0.0))

    def why_not(self, i: int) -> str:
        """Why segment ``i`` may not be driven ("" if it may, or without edge data)."""
        return self.edges[i].why_not if self.edges else ""

    def edge_label(self, i: int) -> str:
        """``"7 (3-4)"``: segment ``i``'s edge ids and its nodes, for messages."""
        a, b = self.segments[i]
        ids = "/".join(self.edges[i].ids) if self.edges else ""
        return f"{ids} ({a}-{b})" if ids else f"{a}-{b}"
