"""The PEF map figure.

Predicted error tau on a log colour scale centred on eps_max, the navigation region (the
``tau = eps_max`` contour), obstacles, labelled markers and docks.

Matplotlib with the Agg backend only (no display needed).
"""

from __future__ import annotations

from pathlib import Path

from planner.pef.result import PefMap
from scenarios.schema import Scenario
from validation.report.figure_format import figure_format
from validation.report.scene import NO_FIX_GREY, OBSTACLE_STYLE, draw_pef, draw_scene


def plot_map(scenario: Scenario, pef_map: PefMap, eps_max: float, path: str | Path, k: int,
             dpi: int = 150) -> Path:
    """Write the PEF map of ``scenario`` as a figure (PNG, PDF or SVG by the extension of ``path``).

    Parameters
    ----------
    scenario : Scenario
        Workspace, obstacles, markers and docks to draw.
    pef_map : PefMap
        The map (tau in metres, inf where no fix is possible).
    eps_max : float
        Allowed error [m]; its contour bounds the navigation region.
    path : str or Path
        Output file, written at exactly this path (:func:`~validation.report.figure_format.figure_format`).
    k : int
        Markers per fix (for the title).
    dpi : int
        Resolution of the PNG.

    Returns
    -------
    Path
        ``path``. Raises ``OSError`` when it cannot be written, ``OutputError`` on an unknown
        extension (before drawing).
    """
    fmt = figure_format(path)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    width, height = scenario.workspace.size
    eps_mm = eps_max * 1e3
    aspect = height / width
    fig_w = 10.0
    # The map's axes get the width left by the colour bar; the height follows the aspect ratio.
    fig, ax = plt.subplots(figsize=(fig_w, max(3.5, min((fig_w - 2.0) * aspect + 1.5, 11.0))),
                           layout="constrained")
    im = draw_pef(ax, pef_map, eps_max)
    draw_scene(ax, scenario)

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
    handles = [
        Line2D([], [], color="black", linewidth=1.4, label=f"τ = ε_max ({eps_mm:g} mm)"),
        Patch(facecolor=NO_FIX_GREY, edgecolor="none", label=f"fewer than {k} markers visible"),
        Patch(facecolor=OBSTACLE_STYLE["facecolor"], edgecolor="black", label="obstacle"),
        Line2D([], [], marker="^", linestyle="", markerfacecolor="#e8412c", markeredgecolor="black",
               markersize=8, label="marker"),
        Line2D([], [], marker="s", linestyle="", markerfacecolor="white", markeredgecolor="black",
               markersize=7, label="dock"),
    ]
    fig.legend(handles=handles, loc="outside lower center", ncols=5, fontsize=8, frameon=False)
    path = Path(path)
    try:
        fig.savefig(path, dpi=dpi, format=fmt)
    finally:
        plt.close(fig)
    return path
