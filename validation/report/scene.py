"""The scene every figure draws, in one style: the PEF heatmap, the workspace, obstacles, markers, docks.

The map, the plan, the placement and the report figures all draw through here, so a marker or
an obstacle looks the same everywhere. The PEF is drawn on a log colour scale centred on
``eps_max`` (blue navigable, red not, grey where fewer than k markers are visible) with the
navigation region's border ``tau = eps_max``.

Matplotlib with the Agg backend only (no display needed).
"""

from __future__ import annotations

import math

import numpy as np

from scenarios.schema import Scenario

OBSTACLE_STYLE = dict(facecolor="#4a4a4a", edgecolor="black", linewidth=0.8)
UNKNOWN_STYLE = dict(facecolor="#d9d9d9", edgecolor="#9a9a9a", linewidth=0.5, hatch="////")
"""Unknown areas (a map's unknown cells): light and hatched, neither floor nor wall."""
MARKER_STYLE = dict(marker="^", s=70, c="#e8412c", edgecolors="black", linewidths=0.7)
DOCK_STYLE = dict(marker="s", s=60, c="white", edgecolors="black", linewidths=1.0)

#: Colour of cells where fewer than k markers are visible.
NO_FIX_GREY = "#b8b8b8"


def tau_limits(tau_mm: np.ndarray, eps_mm: float) -> tuple[float, float]:
    """Return colour limits [mm]: the finite range, at least a factor 2 around eps_max.

    At most two decades above eps_max: errors that large are all just "far too large".
    """
    finite = tau_mm[np.isfinite(tau_mm)]
    if finite.size == 0:
        return eps_mm / 10.0, eps_mm * 10.0
    lo = min(float(finite.min()), eps_mm / 2.0)
    hi = min(max(float(finite.max()), eps_mm * 2.0), eps_mm * 100.0)
    return lo, hi


def split_colormap(lo: float, hi: float, eps: float, bad: str):
    """Diverging colour map whose middle sits at ``eps`` on a log axis from ``lo`` to ``hi``.

    Blue below eps_max (navigable), yellow at it, red above: the lower and upper halves of
    ``RdYlBu_r`` are stretched over [lo, eps] and [eps, hi] respectively.
    """
    import matplotlib
    from matplotlib.colors import ListedColormap

    base = matplotlib.colormaps["RdYlBu_r"]
    e = (math.log(eps) - math.log(lo)) / (math.log(hi) - math.log(lo))
    t = np.linspace(0.0, 1.0, 512)
    src = np.where(t < e, 0.5 * t / max(e, 1e-9), 0.5 + 0.5 * (t - e) / max(1.0 - e, 1e-9))
    return ListedColormap(base(np.clip(src, 0.0, 1.0))).with_extremes(bad=bad)


def display_field(tau_mm: np.ndarray, lo: float, hi: float) -> np.ma.MaskedArray:
    """Return the field drawn: finite tau clipped to [lo, hi], inf (no fix) masked (drawn grey)."""
    return np.ma.masked_invalid(np.where(np.isfinite(tau_mm), np.clip(tau_mm, lo, hi), np.nan))



def pef_extent(pef_map) -> tuple[float, float, float, float]:
    """Image extent (left, right, bottom, top) [m] of a map's cells."""
    cx, cy = pef_map.cell_size
    return (pef_map.x[0] - cx / 2, pef_map.x[-1] + cx / 2, pef_map.y[0] - cy / 2, pef_map.y[-1] + cy / 2)


def draw_pef(ax, pef_map, eps_max: float, norm=None, cmap=None, contour: str = "black"):
    """Draw a PEF map and its border ``tau = eps_max``; return the image (for a colour bar).

    Parameters
    ----------
    ax : matplotlib Axes
    pef_map : planner.pef.result.PefMap
        ``x`` (nx,), ``y`` (ny,) cell centres, ``tau`` (ny, nx) [m], ``free`` (ny, nx).
    eps_max : float
        Allowed error [m].
    norm, cmap : optional
        Colour scale of ``tau`` in mm; default the log scale centred on eps_max.
    contour : str
        Colour of the border line.
    """
    from matplotlib.colors import LogNorm

    free = getattr(pef_map, "free", np.ones(np.shape(pef_map.tau), bool))
    tau_mm = np.where(free, pef_map.tau, np.inf) * 1e3
    eps_mm = eps_max * 1e3
    lo, hi = tau_limits(tau_mm, eps_mm)
    if norm is None:
        norm, cmap = LogNorm(vmin=lo, vmax=hi), split_colormap(lo, hi, eps_mm, NO_FIX_GREY)
        shown = display_field(tau_mm, lo, hi)
    else:
        shown = np.ma.masked_invalid(np.where(np.isfinite(tau_mm), tau_mm, np.nan))
    im = ax.imshow(shown, origin="lower", extent=pef_extent(pef_map), cmap=cmap, norm=norm,
                   interpolation="nearest")
    finite_field = np.where(np.isfinite(tau_mm), tau_mm, 10.0 * hi)
    if pef_map.x.size > 1 and pef_map.y.size > 1 and finite_field.min() < eps_mm < finite_field.max():
        ax.contour(pef_map.x, pef_map.y, finite_field, levels=[eps_mm], colors=contour, linewidths=1.4)
    return im


def draw_facing(ax, scenario: Scenario, size: float) -> None:
    """Draw each flat reflector's face (across its normal) and its incidence wedge, ``size`` [m] long.

    Parameters
    ----------
    ax : matplotlib Axes
    scenario : Scenario
        Its flat markers and ``sensor.max_incidence``.
    size : float
        Length of the face and of the wedge's edges [m].
    """
    lim = scenario.sensor.max_incidence
    for m in scenario.markers:
        if m.kind.value != "flat":
            continue
        x, y = m.position
        f = m.facing
        ax.plot([x - 0.5 * size * math.sin(f), x + 0.5 * size * math.sin(f)],
                [y + 0.5 * size * math.cos(f), y - 0.5 * size * math.cos(f)], color="black", lw=2.0, zorder=5,
                solid_capstyle="butt")
        for side in (-1.0, 1.0):  # the wedge it is seen from
            a = f + side * lim
            ax.plot([x, x + size * math.cos(a)], [y, y + size * math.sin(a)], color="#e8412c", lw=0.8,
                    ls="--", zorder=5)


def draw_scene(ax, scenario: Scenario, labels: bool = True, docks: bool = True) -> None:
    """Draw the workspace border, unknown areas, obstacles, markers and docks, and set limits and axis labels.

    Parameters
    ----------
    ax : matplotlib Axes
    scenario : Scenario
    labels : bool
        Write the marker ids.
    docks : bool
        Draw the docks with their heading and name.
    """
    from matplotlib.patches import PathPatch, Polygon
    from matplotlib.path import Path as MplPath

    x0, y0, x1, y1 = scenario.workspace.bounds
    width, height = scenario.workspace.size
    for area in scenario.unknown:
        path = MplPath.make_compound_path(*[MplPath(np.vstack([r, r[:1]]), closed=True) for r in area.rings()])
        ax.add_patch(PathPatch(path, zorder=2, **UNKNOWN_STYLE))
    for ob in scenario.obstacles:
        # One compound path per obstacle: its outer ring and its holes run opposite ways
        # (shapely's normalised orientation), so the holes stay unfilled.
        path = MplPath.make_compound_path(*[MplPath(np.vstack([r, r[:1]]), closed=True) for r in ob.rings()])
        ax.add_patch(PathPatch(path, zorder=3, **OBSTACLE_STYLE))
    # the border: a wall drawn solid, a map's edge (no wall) thin and dashed
    ax.add_patch(Polygon([(x0, y0), (x1, y0), (x1, y1), (x0, y1)], closed=True, fill=False,
                         edgecolor="black", zorder=3,
                         **(dict(linewidth=1.5) if scenario.workspace.walls else dict(linewidth=0.8, linestyle="--"))))
    mk = scenario.marker_positions()
    if len(mk):
        ax.scatter(mk[:, 0], mk[:, 1], zorder=5, clip_on=False, **MARKER_STYLE)
    off = 0.012 * max(width, height)
    draw_facing(ax, scenario, 2.5 * off)
    if labels:
        for m in scenario.markers:
            x, y = m.position
            ax.annotate(m.id, (x, y), xytext=(x + off, y + off), fontsize=8, fontweight="bold",
                        color="black", zorder=6, annotation_clip=False,
                        bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.75))
    if docks:
        for d in scenario.docks:
            x, y, yaw = d.pose
            ax.scatter([x], [y], zorder=5, **DOCK_STYLE)
            ax.annotate("", xy=(x + 2.5 * off * math.cos(yaw), y + 2.5 * off * math.sin(yaw)),
                        xytext=(x, y), arrowprops=dict(arrowstyle="->", color="black", lw=1.0), zorder=6)
            ax.annotate(d.name, (x, y), xytext=(x - 2.2 * off, y - 2.8 * off), fontsize=9,
                        fontweight="bold", color="black", zorder=6,
                        bbox=dict(boxstyle="round,pad=0.15", fc="#fff6c2", ec="black", lw=0.5))
    ax.set_xlim(x0 - 0.02 * width, x1 + 0.02 * width)
    ax.set_ylim(y0 - 0.02 * height, y1 + 0.02 * height)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
