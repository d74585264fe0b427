"""Routes between docks.

The route network (network), free-space search (gridsearch),
candidates, smoothing and speeds, criteria, ranking, time along a path (pathtime), and the
plan that ties them together (plan).
"""
