"""Results back to the user's tools: TUM trajectories (tum), the drawing with reflectors, region and routes (dxf)."""
