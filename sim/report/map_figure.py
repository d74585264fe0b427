"""The PEF map figure.

Predicted error tau on a log colour scale centred on eps_max, the navigation region (the
``tau = eps_max`` contour), obstacles, labelled markers and docks.

Matplotlib with the Agg backend only (no display needed).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from planner.pef.map import PefMap
from scenarios.schema import Scenario

#: Colour of cells where fewer than k markers are visible.
NO_FIX_GREY = "#b8b8b8"


def _tau_limits(tau_mm: np.ndarray, eps_mm: float) -> tuple[float, float]:
    """Return colour limits [mm]: the finite range, at least a factor 2 around eps_max.

    At most two decades above eps_max: errors that large are all just "far too large".
    """
    finite = tau_mm[np.isfinite(tau_mm)]
    if finite.size == 0:
        return eps_mm / 10.0, eps_mm * 10.0
    lo = min(float(finite.min()), eps_mm / 2.0)
    hi = min(max(float(finite.max()), eps_mm * 2.0), eps_mm * 100.0)
    return lo, hi


def _split_colormap(lo: float, hi: float, eps: float, bad: str):
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


def plot_map(scenario: Scenario, pef_map: PefMap, eps_max: float, path: str | Path, k: int,
             dpi: int = 150) -> Path:
    """Write the PEF map of ``scenario`` as a PNG.

    Parameters
    ----------
    scenario : Scenario
        Workspace, obstacles, markers and docks to draw.
    pef_map : PefMap
        The map (tau in metres, inf where no fix is possible).
    eps_max : float
        Allowed error [m]; its contour bounds the navigation region.
    path : str or Path
        Output file (PNG).
    k : int
        Markers per fix (for the title).
    dpi : int
        Resolution of the PNG.

    Returns
    -------
    Path
        ``path``. Raises ``OSError`` when it cannot be written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch, Polygon

    width, height = scenario.workspace.size
    tau_mm = np.where(pef_map.free, pef_map.tau, np.inf) * 1e3
    eps_mm = eps_max * 1e3
    lo, hi = _tau_limits(tau_mm, eps_mm)

    aspect = height / width
    fig_w = 10.0
    # The map's axes get the width left by the colour bar; the height follows the aspect ratio.
    fig, ax = plt.subplots(figsize=(fig_w, max(3.5, min((fig_w - 2.0) * aspect + 1.5, 11.0))),
                           layout="constrained")
    cmap = _split_colormap(lo, hi, eps_mm, NO_FIX_GREY)
    shown = display_field(tau_mm, lo, hi)
    cx, cy = pef_map.cell_size
    extent = (pef_map.x[0] - cx / 2, pef_map.x[-1] + cx / 2, pef_map.y[0] - cy / 2, pef_map.y[-1] + cy / 2)
    im = ax.imshow(shown, origin="lower", extent=extent, cmap=cmap, norm=LogNorm(vmin=lo, vmax=hi),
                   interpolation="nearest")

    # Navigation region boundary: contour of tau at eps_max (inf counts as above).
    finite_field = np.where(np.isfinite(tau_mm), tau_mm, 10.0 * hi)
    if pef_map.x.size > 1 and pef_map.y.size > 1 and finite_field.min() < eps_mm < finite_field.max():
        ax.contour(pef_map.x, pef_map.y, finite_field, levels=[eps_mm], colors="black", linewidths=1.4)

    for ob in scenario.obstacles:
        ax.add_patch(Polygon(ob.corners(), closed=True, facecolor="#4a4a4a", edgecolor="black",
                             linewidth=0.8, zorder=3))
    ax.add_patch(Polygon([(0, 0), (width, 0), (width, height), (0, height)], closed=True, fill=False,
                         edgecolor="black", linewidth=1.5, zorder=3))

    mk = scenario.marker_positions()
    ax.scatter(mk[:, 0], mk[:, 1], marker="^", s=70, c="#e8412c", edgecolors="black", linewidths=0.7,
               zorder=5, clip_on=False)
    label_off = 0.012 * max(width, height)
    for m in scenario.markers:
        x, y = m.position
        ax.annotate(m.id, (x, y), xytext=(x + label_off, y + label_off), fontsize=8, fontweight="bold",
                    color="black", zorder=6, annotation_clip=False,
                    bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.75))
    for d in scenario.docks:
        x, y, yaw = d.pose
        ax.scatter([x], [y], marker="s", s=60, c="white", edgecolors="black", linewidths=1.0, zorder=5)
        ax.annotate("", xy=(x + 2.5 * label_off * math.cos(yaw), y + 2.5 * label_off * math.sin(yaw)),
                    xytext=(x, y), arrowprops=dict(arrowstyle="->", color="black", lw=1.0), zorder=6)
        ax.annotate(d.name, (x, y), xytext=(x - 2.2 * label_off, y - 2.8 * label_off), fontsize=9,
                    fontweight="bold", color="black", zorder=6,
                    bbox=dict(boxstyle="round,pad=0.15", fc="#fff6c2", ec="black", lw=0.5))

    cbar = fig.colorbar(im, ax=ax, shrink=0.8, fraction=0.04, pad=0.02)
    cbar.set_label("predicted position error τ [mm] (log scale)")
    cbar.ax.axhline(eps_mm, color="black", linewidth=1.4)
    cbar.ax.annotate("ε_max", (0.0, eps_mm), xycoords=("axes fraction", "data"), xytext=(-4, 0),
                     textcoords="offset points", ha="right", va="center", fontsize=8)

    free = pef_map.free
    nav = pef_map.navigable(eps_max)
    frac = float(nav.sum() / free.sum()) if free.any() else 0.0
    ax.set_title(f"{scenario.name}: PEF, {pef_map.model.value} model (k = {k}), ε_max = {eps_mm:g} mm\n"
                 f"navigation region τ < ε_max: {100 * frac:.0f} % of free space", fontsize=11, pad=16)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_xlim(-0.02 * width, 1.02 * width)
    ax.set_ylim(-0.02 * height, 1.02 * height)
    ax.set_aspect("equal")
    handles = [
        Line2D([], [], color="black", linewidth=1.4, label=f"τ = ε_max ({eps_mm:g} mm)"),
        Patch(facecolor=NO_FIX_GREY, edgecolor="none", label=f"fewer than {k} markers visible"),
        Patch(facecolor="#4a4a4a", edgecolor="black", label="obstacle"),
        Line2D([], [], marker="^", linestyle="", markerfacecolor="#e8412c", markeredgecolor="black",
               markersize=8, label="marker"),
        Line2D([], [], marker="s", linestyle="", markerfacecolor="white", markeredgecolor="black",
               markersize=7, label="dock"),
    ]
    fig.legend(handles=handles, loc="outside lower center", ncols=5, fontsize=8, frameon=False)
    path = Path(path)
    try:
        fig.savefig(path, dpi=dpi)
    finally:
        plt.close(fig)
    return path
