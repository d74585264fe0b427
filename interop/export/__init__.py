"""Results back to the user's tools.

TUM trajectories (tum), the route graph as Nav2 GeoJSON (routegraph), markers as CSV
(markers), the drawing with reflectors, region and routes (dxf) and its geometry (region).
"""
