"""Geometry for drawings: the navigation region's contour and the route lines.

:func:`region_contours` traces τ = ε_max on the PEF map with contourpy (matplotlib's contour
generator). Cells without a fix (τ = inf: hidden markers, inside obstacles) count as far above
ε_max, and the map is framed by such cells along the workspace border, so every contour is a
closed ring around a part of the region τ < ε_max (or around a hole in it).
"""

from __future__ import annotations

import contourpy
import numpy as np

from scenarios.schema import Scenario


def region_contours(pef_map, eps_max: float, bounds: tuple[float, float, float, float]) -> list[np.ndarray]:
    """Trace the closed contours of τ = ε_max.

    Parameters
    ----------
    pef_map : planner.pef.result.PefMap
        The PEF on cell centres ``x`` (nx,), ``y`` (ny,) with ``tau`` (ny, nx) [m].
    eps_max : float
        Allowed error [m], the contour level.
    bounds : (float, float, float, float)
        Workspace (x0, y0, x1, y1) [m] (``Workspace.bounds``): where the frame of no-fix cells goes.

    Returns
    -------
    list of ndarray, each shape (n, 2)
        Rings [m] in the scenario's frame, first point repeated at the end; empty when no cell
        has τ < ε_max.
    """
    tau = np.asarray(pef_map.tau, float)
    # Far above the level but finite (contourpy needs finite values): where there is no fix.
    high = 10.0 * eps_max
    z = np.where(np.isfinite(tau) & pef_map.free, np.minimum(tau, high), high)
    x = np.concatenate([[bounds[0]], np.asarray(pef_map.x, float), [bounds[2]]])
    y = np.concatenate([[bounds[1]], np.asarray(pef_map.y, float), [bounds[3]]])
    z = np.pad(z, 1, constant_values=high)
    lines = contourpy.contour_generator(x, y, z, line_type=contourpy.LineType.Separate).lines(eps_max)
    return [np.asarray(seg, float) for seg in lines if len(seg) >= 3]


def route_lines(scenario: Scenario) -> list[tuple[str, np.ndarray]]:
    """One line per route-network segment: (its edge ids joined by "/", (2, 2) end points [m]).

    In the scenario's frame; empty without a route network.
    """
    net = scenario.routes
    if net is None:
        return []
    out = []
    for i, (a, b) in enumerate(net.segments):
        label = "/".join(net.edges[i].ids) if net.edges else f"{a}-{b}"
        out.append((label, np.array([net.nodes[a], net.nodes[b]], float)))
    return out
