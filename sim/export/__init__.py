"""Results back to the user's tools.

TUM trajectories (tum), the route graph as Nav2 GeoJSON (routegraph), markers as CSV
(markers), geometry for drawings (region; the DXF writer is dxf).
"""
