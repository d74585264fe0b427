"""Figures and the HTML report of a sweep (page, figures), and the map and plan figures of.

The CLI (map_figure, plan_figure).
"""
