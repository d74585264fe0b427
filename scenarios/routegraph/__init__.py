"""Route graphs read into a scenario.

Hand-written ``[routes]`` tables, Nav2 route graphs (GeoJSON) and VDA LIF layouts, and the
check that segments keep clear of obstacles:

- :mod:`~scenarios.routegraph.table`: the ``[routes]`` table (``nodes``/``segments`` or ``file``)
  and docks on graph nodes;
- :mod:`~scenarios.routegraph.nav2`: Nav2 route server GeoJSON (``geojson_graph_file_loader``);
- :mod:`~scenarios.routegraph.lif`: VDA 5050 Layout Interchange Format;
- :mod:`~scenarios.routegraph.graph`: directed edges merged into undirected segments;
- :mod:`~scenarios.routegraph.clearance`: segment-obstacle geometry (shapely).
"""

from scenarios.routegraph.clearance import obstacle_geometry, segment_conflict
from scenarios.routegraph.file import read_graph_file
from scenarios.routegraph.graph import GraphEdge, GraphNode
from scenarios.routegraph.table import place_node_docks, portable_routes_text, read_node_dock, read_routes

__all__ = ["GraphEdge", "GraphNode", "obstacle_geometry", "place_node_docks", "read_graph_file",
           "portable_routes_text", "read_node_dock", "read_routes", "segment_conflict"]
