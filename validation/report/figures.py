"""The figures of a Monte-Carlo report, each from plain arrays to a matplotlib ``Figure``.

Figures are built on ``matplotlib.figure.Figure`` directly (no pyplot), so nothing here
touches a global backend or window state; :func:`png_bytes` renders one to PNG.
"""

from __future__ import annotations

import io
from typing import Any

import matplotlib
import numpy as np
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from planner.schedule.promise import POLYGON_TOLERANCE
from scenarios.schema import Scenario
from validation.report.scene import draw_pef, draw_scene, pef_extent

MAX_POINTS = 20_000
"""Scatter plots draw at most this many points (a fixed-seed subsample); statistics use all."""

OK_COLOUR, BAD_COLOUR, BOUND_COLOUR, LIMIT_COLOUR = "tab:blue", "tab:red", "tab:green", "black"


def png_bytes(fig: Figure, dpi: int = 110) -> bytes:
    """Render the figure as PNG bytes."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    return buf.getvalue()


def _ecdf(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    v = np.sort(values[np.isfinite(values)])
    return v, np.arange(1, v.size + 1) / max(v.size, 1)


def _subsample(n: int, limit: int = MAX_POINTS) -> np.ndarray:
    if n <= limit:
        return np.arange(n)
    return np.sort(np.random.default_rng(0).choice(n, size=limit, replace=False))


def error_cdf(step_error: np.ndarray, step_tau: np.ndarray, run_max_error: np.ndarray,
              eps_max: float) -> Figure:
    """Left: distributions of the error, the predicted bound and each run's largest error, with ε_max.

    Right: distribution of error / predicted bound per step; the part right of 1 broke the bound.

    Parameters
    ----------
    step_error, step_tau : ndarray, shape (S,)
        Position error and predicted bound τ of every step of every run [m].
    run_max_error : ndarray, shape (R,)
        Largest error of each run [m].
    eps_max : float
        Allowed error [m].
    """
    fig = Figure(figsize=(11, 4.2))
    ax, ax_r = fig.subplots(1, 2)
    for values, label, style in ((step_error, "error (all steps)", dict(color=OK_COLOUR)),
                                 (step_tau, "predicted bound τ (all steps)",
                                  dict(color=BOUND_COLOUR, ls="--")),
                                 (run_max_error, "largest error of each run", dict(color="tab:purple"))):
        x, p = _ecdf(np.asarray(values, dtype=float) * 1e3)
        if x.size:
            ax.step(x, p, where="post", label=label, **style)
    ax.axvline(eps_max * 1e3, color=LIMIT_COLOUR, lw=1.5, label=f"ε_max = {eps_max * 1e3:g} mm")
    over = np.mean(step_error > eps_max) if step_error.size else 0.0
    ax.set(xlabel="error [mm]", ylabel="fraction ≤ x", ylim=(0, 1.02),
           title=f"Error distribution ({over:.2%} of steps above ε_max)")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)

    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.asarray(step_error, dtype=float) / np.asarray(step_tau, dtype=float)
    x, p = _ecdf(ratio)
    if x.size:
        ax_r.step(x, p, where="post", color=OK_COLOUR)
    ax_r.axvline(1.0, color=BOUND_COLOUR, ls="--", label="error = predicted bound")
    broke = np.mean(ratio[np.isfinite(ratio)] > 1.0) if x.size else 0.0
    ax_r.set(xlabel="error / predicted bound τ", ylabel="fraction ≤ x", ylim=(0, 1.02),
             title=f"Error against the bound ({broke:.2%} of steps above it)")
    ax_r.grid(alpha=0.3)
    ax_r.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    return fig


def fix_scatter(predicted_tau: np.ndarray, snapshot_error: np.ndarray, fault_diameter: np.ndarray,
                tolerance: float = POLYGON_TOLERANCE) -> Figure:
    """Per fix: the snapshot error and the realised fault-area diameter against the plan's promise.

    The promise bounds the fault-area diameter of the moving fix the robot makes (ranges one
    after another, carried by odometry) over every pose it may take near the planned ones
    (:mod:`planner.schedule.promise`): the same construction as the realised area, so the right
    panel compares like with like. Points above y = x exceed the promise.

    Parameters
    ----------
    predicted_tau, snapshot_error, fault_diameter : ndarray, shape (F,)
        The fix's promise, the snapshot fix's position error, and the realised exact
        fault-area diameter [m].
    tolerance : float
        Relative excess of a realised diameter over its promise that still keeps it (the
        promise check's, :data:`planner.schedule.promise.POLYGON_TOLERANCE`).
    """
    fig = Figure(figsize=(11, 4.6))
    axes = fig.subplots(1, 2)
    tau = np.asarray(predicted_tau, dtype=float) * 1e3
    for ax, values, name, tol in ((axes[0], snapshot_error, "snapshot-fix error", 0.0),
                                  (axes[1], fault_diameter, "realised fault-area diameter", tolerance)):
        y = np.asarray(values, dtype=float) * 1e3
        keep = np.isfinite(tau) & np.isfinite(y)
        above = keep & (y > tau * (1.0 + tol))
        limit = "τ" if tol == 0.0 else f"{1 + tol:g} τ"
        idx = _subsample(int(keep.sum()))
        xs, ys, bad = tau[keep][idx], y[keep][idx], above[keep][idx]
        ax.scatter(xs[~bad], ys[~bad], s=6, alpha=0.4, color=OK_COLOUR, lw=0, label=f"within {limit}")
        ax.scatter(xs[bad], ys[bad], s=10, alpha=0.8, color=BAD_COLOUR, lw=0, label=f"above {limit}")
        top = float(max(np.max(xs, initial=0.0), np.max(ys, initial=0.0))) * 1.05 or 1.0
        ax.plot([0, top], [0, top], color=LIMIT_COLOUR, lw=1, label="y = x")
        n = int(keep.sum())
        share = above.sum() / n if n else 0.0
        ax.set(xlim=(0, top), ylim=(0, top), xlabel="promised τ of the moving fix [mm]", ylabel=f"{name} [mm]",
               title=f"{name.capitalize()}: {above.sum()} of {n} fixes above {limit} ({share:.2%})")
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    return fig


def worst_error_grid(x: np.ndarray, y: np.ndarray, error: np.ndarray, size: tuple[float, float],
                     cells_long_side: int = 40,
                     origin: tuple[float, float] = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Find the largest error observed in each cell of a grid over the workspace.

    Parameters
    ----------
    x, y, error : ndarray, shape (S,)
        True positions [m] and errors [m] of all steps.
    size : (float, float)
        Workspace width and height [m].
    cells_long_side : int
        Cells along the longer side (square cells).
    origin : (float, float)
        Lower-left corner of the workspace [m].

    Returns
    -------
    edges_x : ndarray, shape (nx + 1,)
    edges_y : ndarray, shape (ny + 1,)
    worst : ndarray, shape (ny, nx)
        Largest error per cell [m]; nan where no step passed.
    """
    cell = max(size) / cells_long_side
    nx, ny = max(1, int(np.ceil(size[0] / cell))), max(1, int(np.ceil(size[1] / cell)))
    ix = np.clip(((np.asarray(x) - origin[0]) / cell).astype(int), 0, nx - 1)
    iy = np.clip(((np.asarray(y) - origin[1]) / cell).astype(int), 0, ny - 1)
    worst = np.full(ny * nx, -np.inf)
    finite = np.isfinite(error)
    np.maximum.at(worst, iy[finite] * nx + ix[finite], np.asarray(error)[finite])
    worst[np.isneginf(worst)] = np.nan
    return origin[0] + np.arange(nx + 1) * cell, origin[1] + np.arange(ny + 1) * cell, worst.reshape(ny, nx)


def worst_error_map(scenario: Scenario, pef_map: Any, x: np.ndarray, y: np.ndarray, error: np.ndarray,
                    eps_max: float) -> Figure:
    """Draw the predicted PEF map beside the largest observed error per cell.

    Left: the PEF τ map with the navigation-region border τ = ε_max. Right: the largest
    observed error per cell on the same colour scale. The scale ends at ε_max; values above it
    are red (and outlined cells on the right).

    Parameters
    ----------
    scenario : Scenario
        Workspace, obstacles and markers.
    pef_map : planner.pef.result.PefMap or None
        The predicted map (``x``, ``y``, ``tau``); None draws the observed panel only.
    x, y, error : ndarray, shape (S,)
        True positions and errors of all steps [m].
    eps_max : float
        Allowed error [m].
    """
    # The scale ends at ε_max: everything over the limit shows in one alarm colour.
    norm = Normalize(0.0, eps_max * 1e3)
    cmap = matplotlib.colormaps["viridis"].with_extremes(over="tab:red")
    panels = 2 if pef_map is not None else 1
    fig = Figure(figsize=(6.0 * panels, 6.0 * scenario.workspace.height / scenario.workspace.width + 1.2))
    axes = np.atleast_1d(fig.subplots(1, panels))
    image = None
    if pef_map is not None:
        ax = axes[0]
        image = draw_pef(ax, pef_map, eps_max, norm=norm, cmap=cmap, contour="white")
        draw_scene(ax, scenario, labels=False, docks=False)
        ax.set_title(f"Predicted τ ({pef_map.model.value} model)\nwhite line: τ = ε_max", fontsize=10)
    ax = axes[-1]
    ex, ey, worst = worst_error_grid(x, y, error, scenario.workspace.size, origin=scenario.workspace.origin)
    if pef_map is not None:
        ax.imshow(np.isfinite(pef_map.tau), origin="lower", extent=pef_extent(pef_map), cmap="Greys", vmin=0, vmax=4,
                  interpolation="nearest")
    mesh = ax.pcolormesh(ex, ey, np.ma.masked_invalid(worst * 1e3), cmap=cmap, norm=norm)
    image = image or mesh
    cell = ex[1] - ex[0]
    for j, i in zip(*np.nonzero(worst > eps_max), strict=True):
        ax.add_patch(Rectangle((ex[i], ey[j]), cell, cell, fill=False, edgecolor="black", lw=1.0,
                               zorder=5))
    draw_scene(ax, scenario, labels=False, docks=False)
    n_bad = int(np.sum(worst > eps_max))
    ax.set_title(f"Largest observed error per cell\n{n_bad} cells above ε_max (red, outlined)", fontsize=10)
    fig.colorbar(image, ax=list(axes), label="error [mm]; red: above ε_max", shrink=0.85, extend="max")
    return fig


def failure_rate(failed: np.ndarray, allowed: float, ci_lower: np.ndarray, ci_upper: np.ndarray) -> Figure:
    """Plot the failure rate as runs accumulate, with its 95 % Clopper-Pearson band and the allowed rate.

    Parameters
    ----------
    failed : ndarray of bool, shape (R,)
        Whether run i failed (crashed, did not reach its goal, or exceeded ε_max), in run order.
    allowed : float
        Allowed failure rate, 1 - success_target.
    ci_lower, ci_upper : ndarray, shape (R,)
        Confidence interval of the rate after the first i + 1 runs.
    """
    fig = Figure(figsize=(7.5, 4.0))
    ax = fig.subplots()
    n = np.arange(1, failed.size + 1)
    rate = np.cumsum(failed) / n
    ax.fill_between(n, ci_lower, ci_upper, color=OK_COLOUR, alpha=0.2, step="post",
                    label="95 % Clopper-Pearson")
    ax.step(n, rate, where="post", color=OK_COLOUR, label="failure rate")
    ax.axhline(allowed, color=BAD_COLOUR, ls="--", label=f"allowed (1 - success target) = {allowed:.3g}")
    if failed.size:
        ax.set_title(f"Failure rate {rate[-1]:.3f} [{ci_lower[-1]:.3f}, {ci_upper[-1]:.3f}] "
                     f"after {failed.size} runs")
    top = max(0.05, float(np.max(ci_upper, initial=0.0)), allowed) * 1.05
    ax.set(xlabel="runs", ylabel="fraction of runs failed", ylim=(0, top), xlim=(1, max(2, failed.size)))
    ax.xaxis.get_major_locator().set_params(integer=True)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    return fig


def fallback_map(scenario: Scenario, fix_x: np.ndarray, fix_y: np.ndarray, fallback: np.ndarray,
                 step_x: np.ndarray, step_y: np.ndarray, certified: np.ndarray, eps_max: float,
                 excused: np.ndarray | None = None) -> Figure:
    """Draw where fixes fell back to the schedule's subset and where the certified bound broke eps_max.

    Parameters
    ----------
    scenario : Scenario
        Workspace, obstacles, markers (flat ones with their wedges).
    fix_x, fix_y : ndarray, shape (F,)
        True position of every fix [m].
    fallback : ndarray of bool, shape (F,)
        The fix measured a fallback subset.
    step_x, step_y, certified : ndarray, shape (S,)
        True positions of all steps [m] and the bound the fixes taken certify there [m]
        (:mod:`sim.episode.certify`; inf where a fix failed with no promise to carry).
    eps_max : float
        Allowed error [m].
    excused : ndarray of bool, shape (S,), optional
        Steps the single-failure test does not judge (more lines of sight lost at a fix than it
        allows); drawn grey. The red ones are where the layout failed the test.
    """
    fig = Figure(figsize=(7.5, 7.5 * scenario.workspace.height / scenario.workspace.width + 1.0))
    ax = fig.add_subplot()
    draw_scene(ax, scenario, labels=False, docks=True)
    fb = np.asarray(fallback, bool)
    keep = _subsample(int(np.sum(~fb)))
    ax.scatter(np.asarray(fix_x)[~fb][keep], np.asarray(fix_y)[~fb][keep], s=4, c="tab:green", alpha=0.4,
               label="fix as scheduled", zorder=4)
    ax.scatter(np.asarray(fix_x)[fb], np.asarray(fix_y)[fb], s=10, c="tab:orange", label="fallback fix", zorder=4)
    cert = np.asarray(certified, float)
    over = ~(cert < eps_max)
    exc = np.zeros(over.shape, bool) if excused is None else np.asarray(excused, bool)
    for sel, color, label in ((over & exc, "tab:gray", "above ε_max, beyond one lost line of sight"),
                              (over & ~exc, "tab:red", "above ε_max: the single-failure test failed")):
        i = np.flatnonzero(sel)[_subsample(int(sel.sum()))]
        ax.scatter(np.asarray(step_x)[i], np.asarray(step_y)[i], s=16, c=color, marker="x", label=label, zorder=5)
    share = float(np.mean(over & ~exc)) if over.size else 0.0
    ax.set_title(f"Blocked lines of sight: {int(fb.sum())} fallback fixes of {fb.size}; "
                 f"single-failure test failed at {100 * share:.2f} % of steps", fontsize=10)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=3, fontsize=8)
    return fig


def robot_blocked_map(scenario: Scenario, fix_x: np.ndarray, fix_y: np.ndarray, hidden: list[str],
                      blockers: list[str]) -> Figure:
    """Draw where other robots hid reflectors from a fleet's robots: each hidden line of sight.

    Parameters
    ----------
    scenario : Scenario
        Workspace, obstacles, markers.
    fix_x, fix_y : ndarray, shape (F,)
        True position of every fix [m].
    hidden : list of str, length F
        Comma-joined ids of the scheduled markers another robot hid at the fix ("" for none).
    blockers : list of str, length F
        Comma-joined names of the robots that hid them, in the same order.
    """
    fig = Figure(figsize=(7.5, 7.5 * scenario.workspace.height / scenario.workspace.width + 1.0))
    ax = fig.add_subplot()
    draw_scene(ax, scenario, labels=True, docks=True)
    where = dict(zip(scenario.marker_ids(), scenario.marker_positions().tolist(), strict=True))
    segs, by = [], {}
    for x, y, ids, who in zip(np.asarray(fix_x, float), np.asarray(fix_y, float), hidden, blockers, strict=True):
        for m, r in zip([i for i in (ids or "").split(",") if i], [w for w in (who or "").split(",") if w],
                        strict=True):
            segs.append([(x, y), tuple(where[m])])
            by[r] = by.get(r, 0) + 1
    keep = _subsample(len(segs))
    if segs:
        from matplotlib.collections import LineCollection

        ax.add_collection(LineCollection([segs[i] for i in keep], colors="tab:red", linewidths=0.6, alpha=0.3,
                                         zorder=4, label="line of sight hidden by a robot"))
        starts = np.array([segs[i][0] for i in keep])
        ax.scatter(starts[:, 0], starts[:, 1], s=6, c="tab:red", zorder=5, label="fix that lost it")
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=2, fontsize=8)
    who = ", ".join(f"{r} {n}" for r, n in sorted(by.items()))
    ax.set_title(f"Lines of sight hidden by robots: {len(segs)} at {np.size(fix_x)} fixes"
                 + (f" (by {who})" if who else ""), fontsize=10)
    return fig
