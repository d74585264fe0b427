"""Marker placement.

Candidate sites and cover points (sites), the cover problem and its
solvers (cover), and the fewest markers that keep routes under eps_max (placement).
"""
