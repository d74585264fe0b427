"""Figures of the paper report, one per claim, from plain arrays to a matplotlib ``Figure``.

Built on ``matplotlib.figure.Figure`` (no pyplot, no global backend state), like
:mod:`validation.report.figures`; :func:`validation.paper.claims.save_figure` writes them as PNG.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib import colormaps
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, LogLocator, MaxNLocator, NullFormatter

MODEL_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple")


def _plain_log(*axes: Any, which: str = "y") -> None:
    """Label a log axis with plain numbers at 1, 2 and 5 times the powers of ten."""
    for ax in axes:
        for axis in ((ax.yaxis,) if which == "y" else (ax.xaxis,) if which == "x" else (ax.xaxis, ax.yaxis)):
            axis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
            axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
            axis.set_minor_formatter(NullFormatter())


def _finish(fig: Figure, *axes: Any) -> Figure:
    for ax in axes:
        ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    return fig


def alpha_sweep(alpha_deg: np.ndarray, series: list[dict[str, Any]]) -> Figure:
    """Claim 1: exact and linearised fault area and diameter against the angle alpha.

    Parameters
    ----------
    alpha_deg : ndarray, shape (n,)
        Angle between the markers seen from the robot [deg].
    series : list of dict
        Per range pair: ``label`` and arrays (n,) ``area``, ``lin_area`` [m^2], ``diameter``,
        ``lin_diameter`` [m].
    """
    fig = Figure(figsize=(11, 4.2))
    ax_a, ax_d = fig.subplots(1, 2)
    for s, c in zip(series, MODEL_COLOURS, strict=False):
        ax_a.plot(alpha_deg, s["lin_area"] * 1e6, color=c, lw=1.5, label=f"{s['label']}: 4ρ1ρ2/sin α")
        ax_a.plot(alpha_deg, s["area"] * 1e6, "o", color=c, ms=3, label=f"{s['label']}: exact")
        ax_d.plot(alpha_deg, s["lin_diameter"] * 1e3, color=c, lw=1.5, label=f"{s['label']}: eq. 12")
        ax_d.plot(alpha_deg, s["diameter"] * 1e3, "o", color=c, ms=3, label=f"{s['label']}: exact")
        i = int(np.argmin(s["area"]))
        ax_a.plot(alpha_deg[i], s["area"][i] * 1e6, "*", color="black", ms=11, zorder=5)
    for ax in (ax_a, ax_d):
        ax.axvline(90.0, color="0.3", ls=":", lw=1)
        ax.set_ylim(bottom=0.0)
        ax.set_xlabel("α = angle M1-R-M2 [deg]")
        ax.legend(fontsize=7)
    ax_a.set(ylabel="fault area [mm²]", title="Area (★ = smallest exact)")
    ax_d.set(ylabel="fault-area diameter [mm]", title="Diameter (worst-case error)")
    return _finish(fig, ax_a, ax_d)


def equal_ranges(q: np.ndarray, thales: dict[str, tuple[np.ndarray, np.ndarray]], s_m: np.ndarray,
                 ellipse: dict[str, np.ndarray], numbers: dict[str, Any],
                 legend: dict[str, str] | None = None) -> Figure:
    """Claim 2: area along the alpha = 90 deg circle, and where the minimum sits at a fixed a + b.

    Parameters
    ----------
    q : ndarray, shape (n,)
        a / b on the alpha = 90 deg circle.
    thales : dict
        Error-model label -> (linearised, exact) areas relative to a = b, each (n,).
    s_m : ndarray, shape (p,)
        Range sums (a + b) / m.
    ellipse : dict
        Error-model label -> |a - b| / m at the smallest linearised area, (p,).
    numbers : dict
        The claim's numbers (thresholds per model under ``sum_threshold_over_m``).
    legend : dict, optional
        Error-model label -> legend text.
    """
    legend = legend or {}
    fig = Figure(figsize=(11, 4.4))
    ax_t, ax_e = fig.subplots(1, 2)
    for (label, (lin, exact)), c in zip(thales.items(), MODEL_COLOURS, strict=False):
        ax_t.plot(q, lin, color=c, lw=1.5, label=legend.get(label, label))
        ax_t.plot(q, exact, "o", color=c, ms=3)
    ax_t.axvline(1.0, color="0.3", ls=":", lw=1)
    ax_t.set(xscale="log", xlabel="a / b  (robot on the α = 90° circle, m = 5 m)",
             ylabel="fault area / area at a = b", title="Fixed α = 90°: lines linearised, dots exact")
    ax_t.legend(fontsize=8)
    for (label, argmin), c in zip(ellipse.items(), MODEL_COLOURS, strict=False):
        ax_e.plot(s_m, argmin, "-o", color=c, ms=3, lw=1.2, label=legend.get(label, label))
        thr = numbers[label]["sum_threshold_over_m"]
        if thr is not None:
            ax_e.axvline(thr, color=c, ls="--", lw=1)
    ax_e.set(xlabel="(a + b) / m  (robot on an ellipse around the markers)",
             ylabel="|a − b| / m at the smallest area", ylim=(-0.03, 1.0),
             title="Fixed a + b: 0 means a = b is best (dashed: from here on)")
    ax_e.legend(fontsize=8)
    return _finish(fig, ax_t, ax_e)


def shape_error(res: np.ndarray, err: np.ndarray, alpha_deg: np.ndarray,
                example: tuple[np.ndarray, np.ndarray, float, float] | None) -> Figure:
    """Claim 5: exact-vs-parallelogram shape error against Re, and one example at large Re.

    Parameters
    ----------
    res : ndarray, shape (n,)
        Relative range errors Re.
    err : ndarray, shape (G, n)
        Symmetric-difference area / exact area per geometry.
    alpha_deg : ndarray, shape (G,)
        Angle of each geometry [deg] (colour).
    example : (exact ring (p, 2), linear ring (q, 2), Re, alpha) or None
        Polygons [m] to overlay.
    """
    fig = Figure(figsize=(11, 4.4))
    ax, ax_x = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.5, 1]})
    cmap, norm = colormaps["viridis"], Normalize(0.0, 180.0)
    for e, al in zip(err, alpha_deg, strict=True):
        ax.plot(res, e * 100, color=cmap(norm(al)), lw=0.9, alpha=0.8)
    ax.plot(res, err.max(axis=0) * 100, color="black", lw=2, label="worst geometry")
    ax.plot(res, np.median(err, axis=0) * 100, color="black", lw=2, ls="--", label="median")
    for level, style in ((1.0, ":"), (5.0, "-.")):
        ax.axhline(level, color="tab:red", ls=style, lw=1, label=f"{level:g} %")
    ax.axvline(0.01, color="0.3", lw=1, label="Re = 1 % (paper)")
    ax.axvline(1e-3 / 15, color="tab:blue", lw=1, label="paper laser 1 mm/15 m")
    ax.set(xscale="log", yscale="log", xlabel="relative range error Re", ylabel="shape error [%]",
           title="Symmetric difference / exact area (colour: α)")
    sm = fig.colorbar(ScalarMappable(norm, cmap), ax=ax)
    sm.set_label("α [deg]")
    ax.legend(fontsize=7, loc="upper left")
    if example is not None:
        ex, lin, re, al = example
        ax_x.fill(ex[:, 0], ex[:, 1], color="tab:orange", alpha=0.5, label="exact fault area")
        ax_x.plot(lin[:, 0], lin[:, 1], color="black", lw=1.5, label="parallelogram")
        ax_x.plot(0, 0, "k+", ms=10)
        ax_x.set_aspect("equal")
        ax_x.set(xlabel="x [m]", ylabel="y [m]", title=f"Re = {re:g}, α = {al:g}°, a = 5 m, b = 10 m")
        ax_x.legend(fontsize=8)
    return _finish(fig, ax, ax_x)


def gdop_lines(lines: list[tuple[float, np.ndarray, np.ndarray, np.ndarray, float]], diam: np.ndarray,
               g: np.ndarray, ygrid: np.ndarray, numbers: dict[str, Any]) -> Figure:
    """Claim 6: exact diameter and GDOP along vertical lines, and against each other on the grid.

    Parameters
    ----------
    lines : list of (x [m], y (n,) [m], diameter (n,) [m], gdop (n,), y of the alpha = 90 deg circle [m])
    diam, g, ygrid : ndarray, shape (ny, nx)
        Exact diameter [m], GDOP and y [m] on the grid.
    numbers : dict
        The claim's numbers (Spearman correlations).
    """
    fig = Figure(figsize=(11, 4.4))
    ax, ax_s = fig.subplots(1, 2)
    ax_g = ax.twinx()
    for (x0, y, d, gl, y90), c in zip(lines, MODEL_COLOURS, strict=False):
        ax.plot(y, d * 1e3, color=c, lw=1.8, label=f"exact diameter, x = {x0:g} m")
        ax_g.plot(y, gl, color=c, lw=1.2, ls="--", label=f"GDOP, x = {x0:g} m")
        ax.axvline(y90, color=c, ls=":", lw=1)
    ax.set(xscale="log", yscale="log", xlabel="y (distance from the markers' axis) [m]",
           ylabel="exact fault-area diameter [mm] (solid)", title="Along x = const (dotted: α = 90°)")
    ax_g.set_yscale("log")
    ax_g.set_ylabel("GDOP (dashed)")
    _plain_log(ax, ax_g)
    _plain_log(ax, which="x")
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax_g.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, fontsize=7, loc="upper center")
    sc = ax_s.scatter(g.ravel(), diam.ravel() * 1e3, c=ygrid.ravel(), s=10, cmap="viridis")
    fig.colorbar(sc, ax=ax_s).set_label("y [m]")
    ax_s.set(xscale="log", yscale="log")
    _plain_log(ax_s, which="both")
    ax_s.set(xlabel="GDOP", ylabel="exact diameter [mm]",
             title=f"Grid: Spearman = {numbers['spearman_diameter_gdop']:.3f} "
                   f"(range-independent error: {numbers['spearman_diameter_gdop_absolute_error']:.3f})")
    return _finish(fig, ax, ax_s)


def _ecdf(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    v = np.sort(np.asarray(values, float)[np.isfinite(values)])
    return v, np.arange(1, v.size + 1) / max(v.size, 1)


def more_markers(ratios: dict[str, np.ndarray], violations: dict[str, int]) -> Figure:
    """Claim 3: distributions of tau(more markers) / tau(fewer markers); right of 1 is a violation.

    Parameters
    ----------
    ratios : dict
        Label -> ratios (n,); labels starting with ``fix:`` go left (single fixes), the rest right (PEF).
    violations : dict
        Label -> ratios above 1 beyond the model's slack.
    """
    fig = Figure(figsize=(11, 4.2))
    axes = fig.subplots(1, 2)
    groups = ({k: v for k, v in ratios.items() if k.startswith("fix:")},
              {k: v for k, v in ratios.items() if not k.startswith("fix:")})
    titles = ("One fix: a subset and the subset + 1 marker", "PEF of random layouts (best subset per cell)")
    for ax, group, title in zip(axes, groups, titles, strict=True):
        for i, (label, r) in enumerate(group.items()):
            x, p = _ecdf(r)
            ax.step(x, p, where="post", color=MODEL_COLOURS[i % len(MODEL_COLOURS)],
                    ls="-" if i < 5 else "--",
                    label=f"{label} (n = {x.size}, {violations.get(label, 0)} violations)")
        ax.axvline(1.0, color="tab:red", lw=1.2)
        ax.set(xscale="log", xlabel="τ with more markers / τ with fewer", ylabel="fraction ≤ x",
               ylim=(0, 1.02), title=title)
        ax.legend(fontsize=7, loc="upper left")
    return _finish(fig, *axes)


def measurement_cost(curves: dict[str, tuple[np.ndarray, list[np.ndarray], list[float]]],
                     numbers: dict[str, Any]) -> Figure:
    """Claim 4: accuracy gained per marker against the time and distance a fix costs.

    Parameters
    ----------
    curves : dict
        Model -> (k (n,), per k the per-cell ratios tau_k / tau_2, per k the median tau [mm]).
    numbers : dict
        The claim's numbers (fix time, distance and drift during a fix, eps_max).
    """
    fig = Figure(figsize=(11, 4.2))
    ax, ax_mm = fig.subplots(1, 2)
    ks = None
    for (model, (ks, rel, med_mm)), c in zip(curves.items(), MODEL_COLOURS, strict=False):
        med = [np.median(r) for r in rel]
        ax.plot(ks, med, "-o", color=c, label=f"τ_k / τ_2 ({model}), median")
        ax.fill_between(ks, [np.percentile(r, 10) for r in rel], [np.percentile(r, 90) for r in rel],
                        color=c, alpha=0.2, label=f"10-90 % of cells ({model})")
        ax_mm.plot(ks, med_mm, "-o", color=c, label=f"median τ with up to k markers ({model})")
    ax.plot(ks, ks / 2.0, "-s", color="black", label="fix time / fix time at k = 2")
    ax.set(xlabel="markers per fix k", ylabel="relative to k = 2", xticks=ks,
           title="Accuracy gained vs time spent per fix")
    ax.legend(fontsize=7)
    ax_mm.plot(ks, np.array(numbers["distance_during_fix_m"]) * 1e3, "-s", color="black",
               label="distance driven during the fix at max speed")
    ax_mm.plot(ks, np.array(numbers["drift_during_fix_m"]) * 1e3, "-^", color="tab:purple",
               label="odometry drift bound over that distance")
    ax_mm.axhline(numbers["eps_max_m"] * 1e3, color="tab:red", ls="--", label="ε_max")
    ax_mm.set(yscale="log", xlabel="markers per fix k", ylabel="[mm]", xticks=ks, ylim=(0.5, 2000.0),
              title="What a longer fix costs (warehouse)")
    _plain_log(ax_mm)
    ax_mm.legend(fontsize=7, loc="upper left")
    return _finish(fig, ax, ax_mm)


def planned_route(series: list[tuple[np.ndarray, np.ndarray, np.ndarray]], run_max_error: np.ndarray,
                  eps_max: float, numbers: dict[str, Any]) -> Figure:
    """Claim 7: error against time for every run, with eps_max and the planner's predicted bound.

    Parameters
    ----------
    series : list of (t (T,) [s], error (T,) [m], predicted bound (T,) [m])
        One per run.
    run_max_error : ndarray, shape (R,)
        Largest error of each run [m].
    eps_max : float
        Allowed error [m].
    numbers : dict
        The claim's numbers (success count and interval).
    """
    fig = Figure(figsize=(11, 4.2))
    ax, ax_r = fig.subplots(1, 2, gridspec_kw={"width_ratios": [2.2, 1]})
    for i, (t, e, p) in enumerate(series):
        ax.plot(t, e * 1e3, color="tab:blue", lw=0.8, alpha=0.6,
                label="position error (each run)" if i == 0 else None)
        ax.plot(t, p * 1e3, color="tab:green", lw=0.8, ls="--", alpha=0.6,
                label="predicted bound τ + drift (each run)" if i == 0 else None)
    ax.axhline(eps_max * 1e3, color="tab:red", lw=1.5, label=f"ε_max = {eps_max * 1e3:g} mm")
    ax.set(xlabel="time [s]", ylabel="[mm]", title="Error along the planned route (paper-docks, A → B)")
    ax.legend(fontsize=8, loc="upper right")
    ratio = np.asarray(run_max_error, float) / eps_max
    crashed = ~np.isfinite(ratio)          # a crashed run has no error: drawn as a red cross at the top
    ratio = np.where(crashed, np.nan, ratio)
    ax_r.plot(np.arange(ratio.size), ratio, "o", color="tab:blue")
    ax_r.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax_r.axhline(1.0, color="tab:red", lw=1.5)
    lo, hi = numbers["ci95"]
    top = max(1.1, float(np.nanmax(ratio, initial=0.0)) * 1.1)
    ax_r.plot(np.flatnonzero(crashed), np.full(int(crashed.sum()), 0.98 * top), "x", color="tab:red", ms=9)
    ax_r.set(xlabel="run", ylabel="largest error / ε_max", ylim=(0, top),
             title=f"{numbers['under_eps_max']}/{numbers['runs']} under ε_max (95 % CI {lo:.2f}–{hi:.2f})")
    return _finish(fig, ax, ax_r)
