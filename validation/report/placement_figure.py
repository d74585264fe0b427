"""The placement figure: candidate sites, the points to cover, the markers kept and added.

Matplotlib with the Agg backend only (no display needed).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from planner.placement.placement import PlacementResult
from scenarios.errors import output_errors
from scenarios.schema import Scenario
from validation.report.scene import draw_scene


def plot_placement(scenario: Scenario, result: PlacementResult, path: str | Path, dpi: int = 120) -> Path:
    """Write the placement of ``scenario`` as a PNG.

    Parameters
    ----------
    scenario : Scenario
        Workspace, obstacles and docks to draw (its own markers are drawn only when kept).
    result : PlacementResult
        Points to cover, candidate sites, uncoverable points, kept and added markers [m].
    path : str or Path
        Output PNG.
    dpi : int

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    OutputError
        The file cannot be written.
    """
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    w, h = scenario.workspace.size
    fig = Figure(figsize=(8, 8 * h / w + 0.6))
    ax = fig.add_subplot()
    draw_scene(ax, dataclasses.replace(scenario, markers=result.kept), labels=bool(result.kept))
    pts, sites = result.points, result.sites
    ax.plot(pts[:, 0], pts[:, 1], ".", ms=2, color="tab:blue", label=f"points to cover ({len(pts)})")
    ax.plot(sites[:, 0], sites[:, 1], "o", ms=4, mfc="none", color="0.4",
            label=f"candidate sites ({len(sites)})")
    if len(result.uncovered):
        u = result.uncovered
        ax.plot(u[:, 0], u[:, 1], "x", ms=4, color="tab:red", label=f"uncoverable ({len(u)})")
    for mid, (x, y) in result.markers:
        ax.annotate(mid, (x, y), textcoords="offset points", xytext=(4, 4), fontsize=8)
    if result.markers:
        m = [p for _, p in result.markers]
        what = "markers added" if result.kept else "markers"
        ax.plot(*zip(*m, strict=True), "*", ms=14, color="tab:orange", mec="black", label=f"{what} ({len(m)})")
    state = "optimal" if result.optimal else f"lower bound {result.lower_bound}"
    head = f"{len(result.kept)} kept + {result.count} added" if result.kept else f"{result.count}"
    ax.set_title(f"{scenario.name}: {head} markers ({state}), cover target {result.target:g} m")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=2, fontsize=8)
    fig.tight_layout()
    out = Path(path)
    with output_errors(out, "write the figure"):
        fig.savefig(out, dpi=dpi, bbox_inches="tight")
    return out
