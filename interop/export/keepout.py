"""A Nav2 keepout mask: everything outside the navigation region is occupied.

Nav2's keepout filter reads a map in map_server's conventions: a PGM image (P5, 8 bit) and a
YAML file naming it with ``resolution`` [m/cell], ``origin`` [x, y, yaw] (the lower-left corner
of the image's bottom-left cell, in the map frame), ``negate``, ``occupied_thresh`` and
``free_thresh`` (mode ``trinary``). Pixel 0 (black) is occupied, 254 free; the image's first row
is its top (largest y).

The navigation region is where the robot may drive with the promised accuracy: inside the
workspace, outside every obstacle and unknown area, and τ < ε_max (the PEF at the cell's
centre). For a scenario read from a ROS map the mask is the source map's own grid (its
resolution, origin and size), so that Nav2 lays it over that map; otherwise cells of
``planning.resolution`` are laid from ``workspace.origin``, and a last row or column that passes
the workspace's edge is occupied (its centre may lie outside).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from scenarios.errors import output_errors
from scenarios.schema import Scenario

OCCUPIED, FREE = 0, 254
"""map_server's shades: what map_saver writes for occupied and free cells."""


def keepout_mask(scenario: Scenario, pef) -> tuple[np.ndarray, float, tuple[float, float]]:
    """Compute the keepout image of ``scenario``.

    Parameters
    ----------
    scenario : Scenario
    pef : planner.pef.map.PEF
        The scenario's PEF (``at`` gives τ [m] at points).

    Returns
    -------
    image : ndarray of uint8, shape (H, W)
        Row 0 at the top; :data:`OCCUPIED` outside the navigation region, :data:`FREE` inside.
    resolution : float
        Cell size [m].
    origin : (float, float)
        Lower-left corner of the image [m], the map frame (the scenario's).
    """
    fp = scenario.floorplan
    if fp is not None and fp.resolution > 0.0:
        return _map_grid_mask(scenario, pef, fp.resolution, fp.extent)
    res = scenario.planning.resolution
    (w, h), (x0, y0) = scenario.workspace.size, scenario.workspace.origin
    nx, ny = max(1, math.ceil(w / res - 1e-9)), max(1, math.ceil(h / res - 1e-9))
    xc, yc = x0 + (np.arange(nx) + 0.5) * res, y0 + (np.arange(ny) + 0.5) * res
    pts = np.column_stack([np.tile(xc, ny), np.repeat(yc, nx)])
    inside = (pts[:, 0] <= x0 + w) & (pts[:, 1] <= y0 + h)
    for ob in scenario.obstacles + scenario.unknown:
        inside &= ~ob.contains_points(pts)
    tau = np.full(len(pts), np.inf)
    if inside.any():
        tau[inside] = pef.at(pts[inside]).tau
    region = inside & (tau < scenario.planning.eps_max)
    image = np.where(region, FREE, OCCUPIED).astype(np.uint8).reshape(ny, nx)[::-1]
    return np.ascontiguousarray(image), float(res), (float(x0), float(y0))


def _map_grid_mask(scenario: Scenario, pef, res: float,
                   extent: tuple[float, float, float, float]) -> tuple[np.ndarray, float, tuple[float, float]]:
    """:func:`keepout_mask` on a ROS map's grid: ``res`` [m] cells over ``extent`` (the whole image) [m]."""
    import shapely

    ox, oy = extent[0], extent[1]
    nx, ny = max(1, round((extent[2] - ox) / res)), max(1, round((extent[3] - oy) / res))
    xc, yc = ox + (np.arange(nx) + 0.5) * res, oy + (np.arange(ny) + 0.5) * res
    x0, y0, x1, y1 = scenario.workspace.bounds
    ix = np.flatnonzero((xc >= x0) & (xc <= x1))
    iy = np.flatnonzero((yc >= y0) & (yc <= y1))
    region = np.zeros((ny, nx), dtype=bool)  # row 0 at the bottom here
    if len(ix) and len(iy):
        pts = np.column_stack([np.tile(xc[ix], len(iy)), np.repeat(yc[iy], len(ix))])
        inside = np.ones(len(pts), dtype=bool)
        shapes = [ob.geometry() for ob in scenario.obstacles + scenario.unknown]
        if shapes:  # a map has thousands of cells per obstacle: one tree query, not a loop
            hit, _ = shapely.STRtree(shapes).query(shapely.points(pts), predicate="intersects")
            inside[hit] = False
        tau = np.full(len(pts), np.inf)
        if inside.any():
            tau[inside] = pef.at(pts[inside]).tau
        region[np.ix_(iy, ix)] = (inside & (tau < scenario.planning.eps_max)).reshape(len(iy), len(ix))
    image = np.where(region, FREE, OCCUPIED).astype(np.uint8)[::-1]
    return np.ascontiguousarray(image), float(res), (float(ox), float(oy))


def write_keepout(yaml_path: str | Path, scenario: Scenario, pef) -> tuple[Path, Path]:
    """Write the keepout mask as ``yaml_path`` and the PGM beside it (same name, ``.pgm``).

    Returns the YAML and PGM paths; raises OutputError if they cannot be written.
    """
    import yaml

    image, res, (ox, oy) = keepout_mask(scenario, pef)
    out = Path(yaml_path)
    pgm = out.with_suffix(".pgm")
    header = f"P5\n{image.shape[1]} {image.shape[0]}\n255\n".encode("ascii")
    doc = {"image": pgm.name, "mode": "trinary", "resolution": res, "origin": [ox, oy, 0.0],
           "negate": 0, "occupied_thresh": 0.65, "free_thresh": 0.25}
    with output_errors(pgm, "write the keepout mask"):
        pgm.write_bytes(header + image.tobytes())
    with output_errors(out, "write the keepout mask"):
        out.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    return out, pgm
