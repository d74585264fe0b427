"""Figure of a route plan: candidate routes over the PEF map, the chosen one, its fixes.

Uses matplotlib's object API (``Figure``), never pyplot, so no global state is touched.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from planner.plan import Plan
from scenarios.errors import output_errors
from scenarios.schema import Scenario
from validation.report.figure_format import figure_format
from validation.report.scene import MARKER_STYLE, draw_pef, draw_scene


def plot_plan(scenario: Scenario, plan: Plan, pef_map, path: str | Path) -> Path:
    """Draw ``plan`` over the PEF map and save it (PNG, PDF or SVG by the extension of ``path``).

    Parameters
    ----------
    scenario : Scenario
        Obstacles, markers, docks and the route network.
    plan : Plan
        From :func:`planner.plan.plan_route`.
    pef_map : planner.pef.result.PefMap
        ``x`` (nx,), ``y`` (ny,), ``tau`` (ny, nx) [m].
    path : str or Path
        Output file, written at exactly this path (:func:`~validation.report.figure_format.figure_format`).

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    OutputError
        If the extension is unknown (before drawing) or the file cannot be written.
    """
    fmt = figure_format(path)
    w, h = scenario.workspace.size
    fig = Figure(figsize=(10.0, 10.0 * h / w * 0.85 + 1.2), dpi=110, layout="constrained")
    ax = fig.add_subplot()
    eps = plan.eps_max
    im = draw_pef(ax, pef_map, eps)
    fig.colorbar(im, ax=ax, label="predicted error τ [mm] (log scale; black line: τ = ε_max)", shrink=0.8)
    draw_scene(ax, scenario)
    if scenario.routes is not None:
        for i, (a, b) in enumerate(scenario.routes.segments):
            pa, pb = scenario.routes.nodes[a], scenario.routes.nodes[b]
            # an imported edge too close to an obstacle: kept in the graph, never driven
            blocked = bool(scenario.routes.why_not(i))
            ax.plot([pa[0], pb[0]], [pa[1], pb[1]], ":" if blocked else "-", color="tab:red" if blocked else "black",
                    lw=0.6, alpha=0.4, zorder=2)
    for i, c in enumerate(plan.candidates):
        if i == plan.chosen:
            continue
        style = "-" if c.admissible else "--"
        ax.plot(c.path.points[:, 0], c.path.points[:, 1], style, lw=1.2, alpha=0.9, zorder=3,
                color="tab:orange" if c.admissible else "tab:red")
        # Stagger the labels along the routes so that overlapping routes stay readable.
        frac = 0.2 + 0.6 * (i + 0.5) / len(plan.candidates)
        at = c.path.points[int(frac * (len(c.path.points) - 1))]
        ax.annotate(c.id, at, fontsize=7, color="black", zorder=6)
    if plan.chosen is not None:
        ax.plot(plan.path[:, 0], plan.path[:, 1], "-", lw=3.2, color="deeppink", zorder=4)
    if plan.schedule is not None and plan.schedule.fixes:
        fx = np.array([f.position for f in plan.schedule.fixes])
        sw = np.array([f.switch for f in plan.schedule.fixes])
        ax.plot(fx[~sw, 0], fx[~sw, 1], "o", ms=1.8, color="black", mew=0, zorder=5)
        ax.plot(fx[sw, 0], fx[sw, 1], "D", ms=5, color="yellow", mec="black", mew=0.5, zorder=5)
    chosen = plan.candidates[plan.chosen].id if plan.chosen is not None else "none"
    ax.set_title(f"{scenario.name}: {plan.start} → {plan.goal}, ε_max = {eps * 1000:g} mm, chosen {chosen}",
                 pad=14)
    handles = [Line2D([], [], color="deeppink", lw=3.2, label="chosen"),
               Line2D([], [], color="tab:orange", lw=1.2, label="admissible candidate"),
               Line2D([], [], color="tab:red", lw=1.2, ls="--", label="inadmissible candidate"),
               Line2D([], [], ls="", marker="o", ms=3, color="black", mec="black", mew=0.3, label="fix"),
               Line2D([], [], ls="", marker="D", ms=5, color="yellow", mec="black", label="marker switch"),
               Line2D([], [], ls="", marker="^", ms=7, color=MARKER_STYLE["c"], mec="black", label="marker")]
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=6, fontsize=8,
              frameon=False)
    out = Path(path)
    with output_errors(out, "write the plan figure"):
        fig.savefig(out, format=fmt)
    return out
