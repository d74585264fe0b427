"""Results back to the user's tools: TUM trajectories (tum)."""
