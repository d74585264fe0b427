"""Routes between docks.

The route network (network), free-space search (gridsearch), candidates, smoothing and
speeds, criteria and ranking. :mod:`planner.plan` ties a route to its measurement schedule.
"""
