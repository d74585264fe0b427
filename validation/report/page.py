"""The Monte-Carlo report: figures (PNG) and one self-contained HTML page from a sweep directory.

The page embeds its figures as base64, so ``report.html`` can be mailed or attached on its
own; the same PNGs are also written to ``figures/``.
"""

from __future__ import annotations

import base64
import html
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

import scenarios
from estimators.consistency import clopper_pearson
from scenarios.errors import PefsimError, output_errors
from scenarios.schema import Scenario
from sim.episode.types import ran
from sim.montecarlo import results
from sim.montecarlo.directory import read_settings, stored_steps_mode
from sim.montecarlo.results import SweepLayout
from sim.montecarlo.steps import StepsMode
from sim.montecarlo.summary import succeeded, summarize
from validation.report import figures as figs

CONFIDENCE = 0.95
STEP_COLUMNS = ["true_x", "true_y", "error", "predicted_tau"]
"""The step columns the figures read (only these are read: steps are the bulk of a sweep)."""
FIX_COLUMNS = ["predicted_tau", "snapshot_error", "fault_diameter"]


def steps_mode(root: Path) -> StepsMode:
    """Return the steps mode of sweep directory ``root`` (``all`` when it has no sweep.json)."""
    layout = SweepLayout(Path(root))
    return stored_steps_mode(read_settings(root) if layout.sweep_json.exists() else {})


@dataclass
class Figure:
    """One rendered figure of the report."""

    name: str
    title: str
    caption: str
    png: bytes


def _pef_map(scenario: Scenario) -> Any:
    try:
        from planner.pef.map import PEF
    except ImportError:
        return None
    try:
        return PEF(scenario).grid()
    except PefsimError:
        return None


def _has_blocking(scenario: Scenario) -> bool:
    return scenario.sensor_actual.block_probability > 0.0


def build_figures(scenario: Scenario, root: Path, pef_map: Any = None) -> list[Figure]:
    """Render the report's figures from the sweep directory ``root``."""
    runs = results.read_runs(root)
    mode = steps_mode(root)
    steps = None if mode is StepsMode.NONE else results.read_steps(root, columns=STEP_COLUMNS)
    fixes = results.read_fixes(root, columns=FIX_COLUMNS)
    eps = scenario.planning.eps_max
    # A sweep of --steps fixes kept the steps at fix times only, where the error is smallest.
    at = (" Only the steps at fix times are drawn (the sweep was written with --steps fixes): errors "
          "between fixes, where they grow, are not in this figure." if mode is StepsMode.FIXES else "")

    def col(table: pa.Table, name: str) -> np.ndarray:
        return table.column(name).to_numpy(zero_copy_only=False).astype(float)

    out = []
    run_max = col(runs, "max_error")
    if steps is not None:
        fig = figs.error_cdf(col(steps, "error"), col(steps, "predicted_tau"), run_max[np.isfinite(run_max)], eps)
        out.append(Figure("error_cdf", "Error against the predicted bound and ε_max",
                          "Left: how often the position error (EKF estimate against the truth), the planner's "
                          "predicted bound τ and each run's largest error stay below a value. Right: error "
                          "divided by the bound at the same step; above 1 the prediction was broken." + at,
                          figs.png_bytes(fig)))
    fig = figs.fix_scatter(col(fixes, "predicted_tau"), col(fixes, "snapshot_error"),
                           col(fixes, "fault_diameter"))
    out.append(Figure("fix_scatter", "Each fix against its prediction",
                      "One point per fix: the predicted τ of its marker subset at the true position "
                      "against the error of the snapshot position from that fix alone (left) and against "
                      "the diameter of the realised fault area (right). Points above y = x exceed the "
                      "prediction.",
                      figs.png_bytes(fig)))
    if steps is not None:
        fig = figs.worst_error_map(scenario, pef_map, col(steps, "true_x"), col(steps, "true_y"),
                                   col(steps, "error"), eps)
        out.append(Figure("worst_error_map", "Where the error was largest",
                          "Left: the position error function over the floor (white line: the navigation "
                          "region's border τ = ε_max; red: τ above ε_max). Right: the largest error observed "
                          "in each cell any run passed through, same colours; red (outlined) cells exceeded "
                          "ε_max." + at, figs.png_bytes(fig)))
    fx = results.read_fixes(root, columns=["true_x", "true_y", "fallback"]) if _has_blocking(scenario) else None
    if fx is not None and "fallback" in fx.column_names:
        st = results.read_steps(root, columns=["true_x", "true_y", "certified", "excused"])
        excused = (st.column("excused").fill_null(False).to_numpy(zero_copy_only=False).astype(bool)
                   if "excused" in st.column_names else None)
        fig = figs.fallback_map(scenario, col(fx, "true_x"), col(fx, "true_y"),
                                fx.column("fallback").to_numpy(zero_copy_only=False).astype(bool),
                                col(st, "true_x"), col(st, "true_y"), col(st, "certified"), eps, excused)
        out.append(Figure("fallback_map", "Where fixes fell back, and where the layout fails one lost line of sight",
                          "Lines of sight blocked at random (sensor.block_probability): orange, fixes that "
                          "measured the schedule's fallback subset; crosses, steps where the bound the fixes "
                          "actually taken certify (their promises plus the drift since) exceeded ε_max. Red: "
                          "after fixes that lost at most one line of sight, i.e. where the "
                          "layout fails the single-failure test the plan check counts; grey: after fixes "
                          "that lost more, which no such layout promises.",
                          figs.png_bytes(fig)))
    if "blocked_by_robot" in results.sweep_schemas(root).fixes.names:   # robots hid lines of sight (a fleet's)
        fx = results.read_fixes(root, columns=["true_x", "true_y", "blocked_by_robot", "blocking_robots"])
        fig = figs.robot_blocked_map(scenario, col(fx, "true_x"), col(fx, "true_y"),
                                     fx.column("blocked_by_robot").to_pylist(),
                                     fx.column("blocking_robots").to_pylist())
        out.append(Figure("robot_blocked_map", "Where robots hid reflectors from each other",
                          "Red: each line of sight to a scheduled reflector that another robot's body hid at a "
                          "fix start (the reflector below the robot's top, the robot on the line), drawn from "
                          "where the fix was taken; such a fix measures the schedule's fallback or improvises.",
                          figs.png_bytes(fig)))
    failed = ~succeeded(runs)
    n = np.arange(1, failed.size + 1)
    lower, upper = clopper_pearson(np.cumsum(failed), n, 1.0 - CONFIDENCE)
    fig = figs.failure_rate(failed, 1.0 - scenario.montecarlo.success_target, lower, upper)
    out.append(Figure("failure_rate", "Failure rate and its confidence interval",
                      "A run fails when it crashes, does not reach its goal, or its error exceeds ε_max "
                      "at any step. The band is the exact 95 % (Clopper-Pearson) interval after each "
                      "run; the plan meets its target when the band ends below the dashed line.",
                      figs.png_bytes(fig)))
    return out


_NUMERIC = ("rmse", "max_error", "max_predicted_tau", "violations", "fixes", "mean_nees", "mean_nis",
            "duration", "wall_time", "cpu_time")
_UNITS = {"rmse": "mm", "max_error": "mm", "max_predicted_tau": "mm", "duration": "s", "wall_time": "s",
          "cpu_time": "s"}


def _stats_rows(runs: pa.Table) -> list[list[str]]:
    rows = []
    for name in _NUMERIC:
        v = runs.column(name).to_numpy(zero_copy_only=False).astype(float)
        v = v[np.isfinite(v)]
        scale = 1e3 if _UNITS.get(name) == "mm" else 1.0
        label = f"{name} [{_UNITS[name]}]" if name in _UNITS else name
        if v.size == 0:
            rows.append([label] + ["–"] * 5)
            continue
        q = np.quantile(v * scale, [0.0, 0.5, 0.95, 1.0])
        rows.append([label, f"{np.mean(v) * scale:.4g}"] + [f"{x:.4g}" for x in q])
    return rows


def _robot_rows(runs: pa.Table) -> list[list[str]]:
    """Per robot of a fleet sweep: counts, planned and simulated waits, hidden sight lines, collisions, worst error."""
    names = runs.column("robot").to_pylist()
    ok = succeeded(runs)

    def num(name: str) -> np.ndarray:
        return runs.column(name).to_numpy(zero_copy_only=False).astype(float)

    reached = np.asarray(runs.column("reached").fill_null(False).to_numpy(zero_copy_only=False), bool)
    wait, hidden, hits, err = num("wait_time"), num("robot_blocked"), num("collisions"), num("max_error")
    # the plan's waits, one value per robot (sweeps written before it was recorded have none)
    planned = num("predicted_wait_time") if "predicted_wait_time" in runs.column_names else np.full(len(names), np.nan)
    rows = []
    for name in sorted({n for n in names if n is not None}):
        sel = np.array([n == name for n in names])
        plan = planned[sel][np.isfinite(planned[sel])]
        rows.append([name, int(sel.sum()), int(ok[sel].sum()), int(reached[sel].sum()),
                     f"{plan[0]:.2f}" if len(plan) else "-", f"{np.nanmean(wait[sel]):.2f}",
                     f"{np.nanmax(wait[sel]):.2f}", f"{np.nanmean(hidden[sel]):.2f}",
                     int(np.nansum(hits[sel])), f"{np.nanmax(err[sel]) * 1e3:.3f}"])
    return rows


def _table(header: list[str], rows: list[list[Any]]) -> str:
    head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


_CSS = """body{font-family:system-ui,sans-serif;max-width:1150px;margin:2em auto;color:#222;padding:0 1em}
table{border-collapse:collapse;margin:0.5em 0 1.5em}
td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}
th{background:#f2f2f2}td:first-child{text-align:left}img{max-width:100%}figure{margin:1.5em 0}
figcaption{color:#555;font-size:0.92em;max-width:60em}.verdict{font-size:1.15em;font-weight:600}"""


def render_html(scenario: Scenario, root: Path, figures: list[Figure]) -> str:
    """Render the report page: verdict, key numbers, figures (embedded), per-run statistics, notable runs."""
    runs = results.read_runs(root)
    s = summarize(root, scenario.montecarlo.success_target)
    if s.runs:
        met = s.success_ci[0] >= s.success_target
        missed = s.success_ci[1] < s.success_target
        lead = ("The plan meets its target" if met else "The plan misses its target" if missed
                else "Too few runs yet to tell whether the plan meets its target")
        verdict = (f"{lead}: {s.successes} of {s.runs} runs succeeded "
                   f"({s.success_fraction:.1%}, 95 % CI {s.success_ci[0]:.1%} – {s.success_ci[1]:.1%}) "
                   f"against a target of {s.success_target:.1%}.")
    else:
        verdict = "No finished runs yet."
    key = [["runs", s.runs], ["ok", s.ok], ["collided", s.collided], ["stuck", s.stuck],
           ["deadlocked", s.deadlocked], ["crashed", s.crashed], ["reached goal", s.reached],
           ["runs exceeding ε_max", s.violation_runs], ["ε_max [mm]", f"{scenario.planning.eps_max * 1e3:g}"],
           ["seed", scenario.seed], ["directory", str(root)]]
    name = html.escape(scenario.name)
    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>pefsim mc: {name}</title>"
             f"<style>{_CSS}</style></head><body>",
             f"<h1>Monte-Carlo report: {name}</h1>",
             f"<p>{html.escape(scenario.description)}</p>",
             f"<p class='verdict'>{html.escape(verdict)}</p>", _table(["", ""], key)]
    if steps_mode(root) is StepsMode.NONE:
        parts.append("<p>This sweep kept no per-step rows (<code>--steps none</code>): the figures of the "
                     "error along the routes are not available.</p>")
    for f in figures:
        data = base64.b64encode(f.png).decode("ascii")
        parts.append(f"<figure><h2>{html.escape(f.title)}</h2><img alt='{html.escape(f.name)}' "
                     f"src='data:image/png;base64,{data}'><figcaption>{html.escape(f.caption)}</figcaption></figure>")
    if "robot" in runs.column_names:
        parts.append("<h2>Per robot</h2>")
        parts.append(_table(["robot", "runs", "succeeded", "reached", "wait planned [s]", "wait mean [s]",
                             "wait max [s]", "hidden lines of sight per run", "collisions", "max error [mm]"],
                            _robot_rows(runs)))
    parts.append("<h2>Runs summary</h2>")
    parts.append(_table(["per run", "mean", "min", "median", "95 %", "max"], _stats_rows(runs)))
    rows = runs.select(["run", "task", "status", "max_error", "violations", "reached"]).to_pylist()
    worst = sorted((r for r in rows if r["max_error"] is not None), key=lambda r: -r["max_error"])[:10]
    if worst:
        parts.append("<h2>Largest errors</h2>")
        parts.append(_table(["run", "task", "max error [mm]", "steps above ε_max", "reached"],
                            [[r["run"], r["task"], f"{r['max_error'] * 1e3:.3f}", r["violations"],
                              r["reached"]] for r in worst]))
    failed = [r for r in rows if ran(r["status"]) and r["status"] != "ok"]
    if failed:   # touched something, stuck or deadlocked: the statistics above say nothing about why
        parts.append(f"<h2>Runs that collided, stuck or deadlocked ({len(failed)})</h2>")
        parts.append(_table(["run", "task", "status"], [[r["run"], r["task"], r["status"]] for r in failed[:50]]))
    crashed = [r for r in rows if not ran(r["status"])]
    if crashed:
        parts.append(f"<h2>Crashed runs ({len(crashed)})</h2>")
        parts.append(_table(["run", "task", "status"],
                            [[r["run"], r["task"], r["status"]] for r in crashed[:50]]))
    parts.append("<p>Rebuild run i's random numbers with <code>numpy.random.SeedSequence(seed, "
                 "spawn_key=(i,))</code>; the data are in <code>runs.parquet</code>, <code>steps/</code> "
                 "and <code>fixes/</code>.</p></body></html>")
    return "\n".join(parts)


def write_report(root: str | Path, scenario: Scenario | None = None, pef_map: Any = None) -> Path:
    """Write ``report.html`` and ``figures/*.png`` for sweep directory ``root``; returns the page's path.

    Parameters
    ----------
    root : path
        A sweep directory.
    scenario : Scenario, optional
        Default: parsed from ``root/scenario.toml``.
    pef_map : planner.pef.result.PefMap, optional
        Default: computed from the scenario (omitted from the map figure if the planner fails).
    """
    layout = SweepLayout(Path(root))
    if scenario is None:
        with output_errors(layout.scenario_toml, "read"):
            text = layout.scenario_toml.read_text(encoding="utf-8")
        scenario = scenarios.loads(text, source=str(layout.scenario_toml))
    if pef_map is None:
        pef_map = _pef_map(scenario)
    figures = build_figures(scenario, layout.root, pef_map)
    with output_errors(layout.figures_dir, "create"):
        layout.figures_dir.mkdir(exist_ok=True)
    for f in figures:
        results.write_atomic(layout.figures_dir / f"{f.name}.png", f.png)
    results.write_atomic(layout.report_html, render_html(scenario, layout.root, figures).encode("utf-8"))
    return layout.report_html
