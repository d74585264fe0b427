"""pefsim: robot routes planned from a Position Error Function, and checked in simulation.

The public Python API; the ``pefsim`` command calls the same functions. Nothing here writes a
file unless told where (``out=``, ``png=``, ``rrd=``, ``tum=``, :func:`export`'s files)::

    import pefsim
    sc = pefsim.load("paper-docks")                      # Scenario
    m = pefsim.pef_map(sc)                               # PefMap (x, y, tau, best)
    p = pefsim.plan(sc)                                  # Plan of task 0 (a fleet's: FleetPlanSummary)
    placed = pefsim.place(sc)                            # Placement
    pefsim.export(sc, lif="routes.lif")                  # files for the tools downstream
    r = pefsim.run_episode(sc, seed=3)                   # EpisodeResult (a fleet's: FleetResult)
    sw = pefsim.sweep(sc, out="sw", runs=4, workers=1)   # SweepSummary of the finished sweep
    rep = pefsim.validate(sw)                            # ValidationReport
    rep = pefsim.validate_scenario(sc, runs=4)           # the same, sweeping into a temporary folder
    page = pefsim.paper("paper-report", quick=True)      # PaperPage: the paper's claims, one page
    pefsim.watch("hall.toml", save="hall.rrd")           # live view, updated on every save (Ctrl-C ends)
    ws = pefsim.worlds(3, seed=1, out="worlds")          # random honest worlds (PlannedWorld)

Every command of the ``pefsim`` program is these functions plus argument parsing and printing.
Units are metres, seconds and radians throughout. Bad input raises :class:`PefsimError` (its
subclasses ``ScenarioError``, ``PlanningError``, ``SimulationError``, ``OutputError``) with a
one-line message naming the file, key and value.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import TYPE_CHECKING, Any

from scenarios import PefsimError, Scenario

if TYPE_CHECKING:
    import threading
    from collections.abc import Callable, Iterator

    from interop.export.files import Exported
    from planner.fleet.summary import FleetPlanSummary
    from planner.pef.result import PefMap
    from planner.placement.placement import PlacementResult as Placement
    from planner.plan import Plan
    from sim.episode.types import EpisodeResult, FleetResult
    from sim.montecarlo.summary import SweepSummary
    from validation.paper.page import PaperPage
    from validation.suite import ValidationReport

_TYPES = {"PefMap": ("planner.pef.result", "PefMap"), "Placement": ("planner.placement.placement", "PlacementResult"),
          "Plan": ("planner.plan", "Plan"), "FleetPlanSummary": ("planner.fleet.summary", "FleetPlanSummary"),
          "EpisodeResult": ("sim.episode.types", "EpisodeResult"),
          "FleetResult": ("sim.episode.types", "FleetResult"),
          "SweepSummary": ("sim.montecarlo.summary", "SweepSummary"),
          "PaperPage": ("validation.paper.page", "PaperPage"),
          "ValidationReport": ("validation.suite", "ValidationReport"),
          "DEFAULT_ALPHA": ("validation.suite", "DEFAULT_ALPHA"),
          "EXPORT_FORMATS": ("interop.export.files", "EXPORT_FORMATS"),
          "Exported": ("interop.export.files", "Exported")}
"""The types the functions return, imported on first use: a command that needs one part of the
library (``pefsim list``, ``pefsim map``) does not pay for importing the others (seconds)."""


def __getattr__(name: str) -> Any:
    """Import the type ``name`` of :data:`_TYPES` on first use (PEP 562)."""
    try:
        module, attr = _TYPES[name]
    except KeyError:
        raise AttributeError(f"module 'pefsim' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(module), attr)
    globals()[name] = value
    return value


__all__ = ["DEFAULT_ALPHA", "EXPORT_FORMATS", "EpisodeResult", "Exported", "FleetPlanSummary", "FleetResult",
           "PaperPage", "PefMap", "PefsimError", "Placement", "Plan", "Scenario", "SweepSummary", "ValidationReport",
           "builtin_names", "export", "iter_worlds", "load", "paper", "pef_map", "place", "plan", "plan_fleet",
           "run_episode", "sweep", "validate", "validate_scenario", "watch", "worlds"]


def load(scenario: str | Path) -> Scenario:
    """Load a scenario: a built-in name (``pefsim list``) or a TOML file.

    Parameters
    ----------
    scenario : str or path
        Built-in name (``"warehouse"``) or path to a scenario TOML file.

    Returns
    -------
    Scenario
        Validated; every error names the file and key.
    """
    import scenarios

    return scenarios.load(scenario)


def builtin_names() -> list[str]:
    """Return the names of the built-in scenarios (``scenarios/library/``), sorted.

    Returns
    -------
    list of str
        Each loads with :func:`load`.
    """
    import scenarios

    return scenarios.builtin_names()


def _scenario(scenario: Scenario | str | Path) -> Scenario:
    return scenario if isinstance(scenario, Scenario) else load(scenario)


def pef_map(scenario: Scenario | str | Path, *, model: str | None = None, resolution: float | None = None,
            speed: float | None = None, out: str | Path | None = None, npz: str | Path | None = None,
            rrd: str | Path | None = None) -> PefMap:
    """Compute the PEF map: predicted position error on a grid over the workspace.

    Outputs are checked before the map is computed (a figure's extension, a recording's
    folder) and written at exactly the paths given.

    Parameters
    ----------
    scenario : Scenario, str or path
    model : {"exact", "parallelogram", "strips", "gdop"}, optional
        Error model; default the scenario's ``planning.pef_model``. Every model reports a
        diameter [m].
    resolution : float, optional
        Cell size [m]; default ``planning.resolution``.
    speed : float, optional
        The motion-aware PEF: the promise of a fix ending at each cell while driving at
        ``speed`` [m/s] (two markers per fix). Default the paper's static PEF.
    out : str or path, optional
        Write the figure here (``.png``, ``.pdf`` or ``.svg``).
    npz : str or path, optional
        Write the arrays ``tau``, ``x``, ``y``, ``best`` here (NumPy ``.npz`` content, whatever the name).
    rrd : str or path, optional
        Write a rerun recording of the static layers (map, region, markers, docks) here.

    Returns
    -------
    PefMap
        ``x`` (nx,), ``y`` (ny,) cell centres [m], ``tau`` (ny, nx) [m] (inf: fewer than k
        markers visible, or not free), ``best`` (ny, nx, k) marker indices, ``free`` (ny, nx).
    """
    from planner.pef.map import PEF

    sc = _scenario(scenario)
    _check_outputs(figure=out, rrd=rrd, named={"out": out, "npz": npz, "rrd": rrd})
    pef = PEF(sc, model=model)
    if speed is not None:
        from planner.schedule.promise import moving_map

        result = moving_map(sc, pef, speed, resolution)
    else:
        result = pef.grid(resolution)
    if npz is not None:
        from interop.export.npz import write_npz

        write_npz(npz, result)
    if out is not None:
        from scenarios.errors import output_errors
        from validation.report.map_figure import plot_map

        with output_errors(out, "write the figure"):
            plot_map(sc, result, sc.planning.eps_max, out, pef.k)
    if rrd is not None:
        from interop.recording import write_static_rrd

        write_static_rrd(rrd, sc, pef_map=result)
    return result


def plan(scenario: Scenario | str | Path, task: int | None = None, *, start: str | None = None,
         goal: str | None = None, free: bool | None = None, out: str | Path | None = None,
         rrd: str | Path | None = None, traffic: bool = True) -> Plan | FleetPlanSummary:
    """Plan a route: candidates, criteria, the choice and its measurement schedule; or a whole fleet.

    A fleet scenario (``[[robots]]``) given neither a task nor ``start`` and ``goal`` plans every
    robot's tasks together (:func:`plan_fleet`) and returns the fleet's summary.

    Parameters
    ----------
    scenario : Scenario, str or path
    task : int, optional
        Index into ``scenario.tasks`` (default 0; ignored when ``start`` and ``goal`` are given).
    start, goal : str, optional
        Dock names, instead of a task.
    free : bool, optional
        Free-space search (True) or the route network (False); default the network if any.
    out : str or path, optional
        Write the figure of the plan over the PEF map here (``.png``, ``.pdf`` or ``.svg``;
        checked before planning).
    rrd : str or path, optional
        Write a rerun recording of the map, the candidate routes and the schedule here.
        ``free``, ``out`` and ``rrd`` are refused for a fleet's plan (it neither searches free
        space nor draws).
    traffic : bool
        A fleet's plan: the traffic-aware measurement schedules; False: each robot's as if it
        drove alone (a lone robot plans alone anyway).

    Returns
    -------
    Plan or FleetPlanSummary
        A route's ``candidates`` (each with its criteria), ``chosen``, ``reason``, the drivable
        ``path`` (N, 2) [m] with ``speed`` (N,) [m/s] and the ``schedule`` (each fix with its
        promise ``predicted_tau`` [m]); a fleet's plan with one summary per robot (``robots``),
        ``to_dict()`` and ``lines()``.
    """
    from planner.pef.map import PEF
    from planner.plan import plan_route, plan_task
    from scenarios import PlanningError

    sc = _scenario(scenario)
    if (start is None) != (goal is None):
        raise PlanningError("plan: give both start and goal, or neither (then a task is planned)")
    if sc.robots and start is None and task is None:
        for name, value, what in (("out", out, "its plan draws no figure"), ("rrd", rrd, "its plan writes no "
                                  "recording"), ("free", free, "each robot is planned with the default search")):
            if value is not None:
                raise PlanningError(f"{name}: {sc.source} is a fleet ([[robots]]): {what}, got {value}")
        from planner.fleet.summary import FleetPlanSummary

        fleet, robots = plan_fleet(sc, traffic=traffic)
        return FleetPlanSummary(scenario=sc.name, eps_max=sc.planning.eps_max, fleet=fleet, robots=robots)
    task = 0 if task is None else task
    _check_outputs(figure=out, rrd=rrd, named={"out": out, "rrd": rrd})
    pef = PEF(sc)
    if start is not None:
        result = plan_route(sc, start, goal, free=free, pef=pef)
    else:
        result = plan_task(sc, task, free=free, pef=pef)
    grid = pef.grid() if (out is not None or rrd is not None) else None
    if out is not None:
        from validation.report.plan_figure import plot_plan  # matplotlib: only when a figure is asked for

        plot_plan(sc, result, grid, out)
    if rrd is not None:
        from interop.recording import write_static_rrd

        write_static_rrd(rrd, sc, pef_map=grid, plan=result)
    return result


def plan_fleet(scenario: Scenario | str | Path, *, traffic: bool = True):
    """Plan a fleet (``[[robots]]``): every robot's tasks, the zone timeline, the predicted blocking.

    Parameters
    ----------
    scenario : Scenario, str or path
        A fleet scenario.
    traffic : bool
        The traffic-aware measurement schedule (:mod:`planner.fleet.traffic`); False: each robot's
        schedule as if it drove alone (its blocking is still predicted).

    Returns
    -------
    fleet : planner.fleet.plan.FleetPlan
        Per robot its plans, timeline and predicted blocking (``robots[i].blocking``).
    summary : list of planner.fleet.summary.RobotSummary
        Per robot: tasks, expected blocked lines of sight and fixes, predicted waiting, what the
        traffic costs in time against driving alone, fixes per metre near the others and elsewhere.
    """
    from planner.fleet.plan import plan_fleet as _plan_fleet
    from planner.fleet.summary import summarize

    sc = _scenario(scenario)
    fleet = _plan_fleet(sc, traffic=traffic)
    return fleet, summarize(sc, fleet)


def place(scenario: Scenario | str | Path, *, method: str = "auto", out: str | Path | None = None,
          png: str | Path | None = None, plannable: bool = True, time_limit: float | None = None,
          progress=None) -> Placement:
    """Find the fewest markers, among sites on walls and obstacle faces, that keep the routes under eps_max.

    With ``plannable`` (the default, as ``pefsim place``) the layout is planned for every task
    and the cover target tightened until each has an admissible route
    (:mod:`planner.placement.plannable`); ``plannable=False`` is the plain cover. With
    ``placement.existing = "keep"`` the scenario's markers stay and only added ones are chosen.

    Parameters
    ----------
    scenario : Scenario, str or path
    method : {"auto", "milp", "greedy"}
        Exact MILP (small instances), greedy with the LP lower bound, or chosen by size.
    out : str or path, optional
        Also write the scenario with the placed markers as TOML here (when the layout has at
        least k markers).
    png : str or path, optional
        Also draw the candidate sites, the points to cover and the markers here.
    plannable : bool
        Check the layout with the planner and tighten the cover until every task plans.
    time_limit : float, optional
        Safety limit of the exact solver's LP and MILP rounds [s]; default
        :data:`planner.placement.cover.MILP_TIME_LIMIT`.
    progress : callable, optional
        ``progress(line)``, told each phase as it starts (cover, target, task planned,
        tightening; :func:`planner.placement.plannable.place_plannable`).

    Returns
    -------
    Placement
        ``markers`` [(id, (x, y))] [m] added, ``kept`` markers, ``count``, ``lower_bound``,
        ``optimal``, ``uncovered``, ``target`` [m] (the cover target used), ``unplanned`` (tasks
        without an admissible route on the layout), ``finest_spacing``, ``written`` (the TOML
        written with ``out``, None when the layout has fewer than k markers); ``to_dict()`` as JSON.

    Raises
    ------
    PlanningError
        A bad method or time limit.
    """
    import dataclasses

    from planner.placement.cover import MILP_TIME_LIMIT
    from planner.placement.placement import place as _place
    from planner.placement.placement import write_scenario_with_markers
    from scenarios import OutputError, PlanningError

    limit = MILP_TIME_LIMIT if time_limit is None else time_limit
    if not limit > 0:
        raise PlanningError(f"time_limit: expected a positive number of seconds, got {limit}")
    for path, suffix, what in ((out, ".toml", "out"), (png, ".png", "png")):
        if path is not None and Path(path).suffix.lower() != suffix:
            raise OutputError(f"{path}: {what}: expected a {suffix} file, got {Path(path).suffix or 'no extension'!r}")
    _check_outputs(named={"out": out, "png": png})
    sc = _scenario(scenario)
    if plannable:
        from planner.placement.plannable import place_plannable

        result = place_plannable(sc, method=method, time_limit=limit, progress=progress).result
    else:
        if progress is not None:
            progress(f"cover: target {sc.planning.eps_max * 1e3:.4g} mm")
        result = _place(sc, method=method, time_limit=limit)
    if out is not None and result.fixable(sc.sensor.markers_per_fix):
        result = dataclasses.replace(result, written=write_scenario_with_markers(sc, result, out))
    if png is not None:
        from validation.report.placement_figure import plot_placement

        plot_placement(sc, result, png)
    return result


def export(scenario: Scenario | str | Path, *, routes: str | Path | None = None, markers: str | Path | None = None,
           dxf: str | Path | None = None, lif: str | Path | None = None,
           keepout: str | Path | None = None) -> Exported:
    """Write the scenario's results for the tools downstream; only the files asked for.

    Parameters
    ----------
    scenario : Scenario, str or path
    routes : str or path, optional
        The route network as a Nav2 route graph (GeoJSON), each edge with ``max_tau``,
        ``mean_tau`` [m], ``min_visible``, ``admissible``, ``why_not``
        (:mod:`interop.export.routegraph`).
    markers : str or path, optional
        The markers as CSV ``id,x,y,x_mm,y_mm,kind,facing_deg`` (:mod:`interop.export.markers`).
    dxf : str or path, optional
        The drawing with the reflectors, the contour τ = ε_max and the routes, each labelled
        with its worst τ, inadmissible ones on their own layer (:mod:`interop.export.dxf`).
    lif : str or path, optional
        The route network as a VDA LIF file keeping every id, each node with its τ as
        ``nodePosition.allowedDeviationXY`` [m] (:mod:`interop.export.lif`).
    keepout : str or path, optional
        A Nav2 keepout mask: this map_server YAML and a PGM beside it, occupied outside the
        navigation region (:mod:`interop.export.keepout`).

    Returns
    -------
    Exported
        A dict of what was written, by output name (``keepout``: the YAML and the PGM);
        ``to_dict()`` as JSON.

    Raises
    ------
    PefsimError
        Nothing asked for, an extension that does not name the output's format, or a route
        export of a scenario without a route network: before anything is computed or written.
    """
    from interop.export.files import check_exports, write_exports

    asked = check_exports(routes=routes, markers=markers, dxf=dxf, lif=lif, keepout=keepout)
    return write_exports(_scenario(scenario), asked)


def run_episode(scenario: Scenario | str | Path, seed: int | None = None, *, task: int | None = None,
                rrd: str | Path | None = None, tum: str | Path | None = None) -> EpisodeResult | FleetResult:
    """Drive one run in PyBullet: plan, follow on the EKF estimate, measure, estimate.

    A scenario without ``[[robots]]`` runs its lone robot through one task; one with
    ``[[robots]]`` runs every robot through its tasks, together, under zone control. Outputs
    are checked before the run is driven (a recording's folder; the TUM folder is created) and
    written at exactly the paths given.

    Parameters
    ----------
    scenario : Scenario, str or path
    seed : int, optional
        Root of the run's random streams (same seed, same numbers); default the scenario's.
    task : int, optional
        Index into ``scenario.tasks`` of the lone robot's task (default 0); a fleet's robots
        drive their own (refused for a fleet).
    rrd : str or path, optional
        Write a rerun recording of the run here.
    tum : str or path, optional
        Write ``groundtruth.txt`` and ``estimate.txt`` (TUM format) into this directory (a
        fleet's: into a folder per robot, named for it).

    Returns
    -------
    EpisodeResult or FleetResult
        A lone robot's episode: ``steps`` (per control step: poses, covariance, error, NEES),
        ``fixes`` (per fix: the realised fault area against its promise), ``plan`` and ``summary``
        (with what the run did: ``status`` ok / collided / stuck, ``collisions``, the first
        contact, the longest stall, :mod:`sim.episode.outcome`). A fleet's: per robot (``robots``)
        its episode over all its tasks (summary keys as a lone robot's plus ``robot``,
        ``arrival``, ``wait_time`` [s], ``robot_blocked`` and ``deadlocked``), how often the
        robots' footprints overlapped (``collisions``) and the duration. Both give ``robots``,
        ``to_dict()``, ``lines(scenario)`` and ``written`` (the paths of the files written:
        the TUM trajectories, then the recording).
    """
    from scenarios import SimulationError
    from sim.episode import run

    sc = _scenario(scenario)
    task = run.check_episode_task(sc, task)
    seed = sc.seed if seed is None else seed
    if seed < 0:
        raise SimulationError(f"seed: expected a non-negative integer, got {seed}")
    _check_outputs(rrd=rrd, folder=tum, named={"rrd": rrd, "tum": tum})
    prepared = run.prepare(sc, task)
    result = run.run(sc, task, seed=seed, prepared=prepared)
    if tum is not None:
        from interop.export.tum import write_tum

        for r in result.robots:
            steps = r.result.steps
            result.written.extend(write_tum(Path(tum) if r.name is None else Path(tum) / r.name, steps.t,
                                            steps.true_pose, steps.est_pose))
    if rrd is not None:
        from interop.recording.run import write_run_rrd

        write_run_rrd(rrd, sc, result, pef_map=prepared.pef.grid())
        result.written.append(Path(rrd))
    return result


def sweep(scenario: Scenario | str | Path, out: str | Path | None = None, *, runs: int | None = None,
          workers: int | None = None, task: int | None = None, executor: str = "local", address: str | None = None,
          resume: bool = False, rrd_every: int = 0, steps: str | None = None, q_scale: float = 1.0,
          alone: bool = False, progress: bool | None = False, report: bool = True) -> SweepSummary:
    """Run a Monte-Carlo sweep into ``out`` (written run by run; ``resume`` completes it).

    Parameters
    ----------
    scenario : Scenario, str or path
    out : str or path, optional
        Sweep directory (new, or an earlier sweep of the same scenario with ``resume``);
        default ``mc-<scenario name>`` in the working directory.
    runs : int, optional
        Runs ``0 .. runs-1``; default ``montecarlo.runs``.
    workers : int, optional
        Worker processes (or Ray actors); default the CPU count. Results do not depend on it.
    task : int, optional
        Drive only this task; default run i drives task ``i % len(tasks)``.
    executor : {"local", "ray"}
        Where the runs execute: local worker processes, or a Ray cluster.
    address : str, optional
        Ray cluster address (with ``executor="ray"``; default starts one).
    resume : bool
        Complete the runs an earlier sweep into ``out`` left missing.
    rrd_every : int
        Write a rerun recording of every ``rrd_every``-th run into ``out/recordings/`` (0: none).
    steps : {"all", "fixes", "none"}, optional
        Per-step rows to keep: every control step, the steps at fix times (the N-run NEES
        check then does not apply), or none; default ``all`` (on resume: the sweep's own).
    q_scale : float
        NEGATIVE CONTROL ONLY: the filter's process noise times ``q_scale`` (1: as declared);
        the directory records it (:mod:`sim.montecarlo.negative_control`).
    alone : bool
        NEGATIVE CONTROL ONLY, fleets: plan each robot's measurement schedule as if it drove alone
        (no traffic prediction; :func:`plan_fleet` with ``traffic=False``); the directory records it.
    progress : bool or None
        Show a progress bar; None: when stderr is a terminal.
    report : bool
        Write ``report.html`` and its figures into ``out`` (as ``pefsim mc`` does).

    Returns
    -------
    SweepSummary
        What the directory holds (``out``, run counts, success and its interval, this call's
        runs and wall time, bytes per run) and ``report``, the page written (None without).
    """
    import dataclasses

    from scenarios import ScenarioError
    from sim.episode.drive import check_markers
    from sim.montecarlo.engine import sweep as _sweep
    from sim.montecarlo.negative_control import check_alone, check_q_scale, mark, read_mark, scaled_api

    sc = _scenario(scenario)
    check_markers(sc)  # before the output directory is made
    q_scale = check_q_scale(q_scale)
    alone = check_alone(sc, alone)
    control = q_scale != 1.0 or alone
    if resume and out is not None and Path(out).is_dir() and read_mark(out) != (q_scale, alone):
        raise ScenarioError(f"{out}: resume: its runs were made with (q_scale, alone) = {read_mark(out)}, "
                            f"not {(q_scale, alone)}")
    written: list[Path] = []

    def then(summary: SweepSummary) -> None:  # while the sweep still holds the directory's lock
        if control:
            mark(summary.out, q_scale, alone)
        if report:
            from validation.report.page import write_report

            written.append(write_report(summary.out, sc))

    recorder = None
    if rrd_every > 0:  # rerun: only when recordings are asked for
        from interop.recording.run import write_run_rrd as recorder
    summary = _sweep(sc, out, runs=runs, task=task, workers=workers, executor=executor, address=address,
                     resume=resume, rrd_every=rrd_every, steps=steps, progress=progress,
                     api=scaled_api(q_scale, alone) if control else None, then=then,
                     recorder=recorder)
    return dataclasses.replace(summary, report=str(written[0]) if written else None)


def validate(sweep: SweepSummary | str | Path, *, alpha: float | None = None,
             scenario: Scenario | str | Path | None = None, blocking_scale: float = 1.0) -> ValidationReport:
    """Check a sweep's results against the predictions (containment, promise, bound, NEES, NIS, ...).

    The checks judge the sweep's tables; running the sweep is :func:`sweep`'s job.

    Parameters
    ----------
    sweep : SweepSummary, str or path
        A sweep (its directory) written by :func:`sweep` (or ``pefsim mc``); refused while
        another process is still writing it.
    alpha : float, optional
        Family false-alarm probability, split Bonferroni over the statistical checks; default
        :data:`validation.suite.DEFAULT_ALPHA` (0.01).
    scenario : Scenario, str or path, optional
        When given, the sweep must have been made from exactly this scenario.
    blocking_scale : float
        NEGATIVE CONTROL ONLY: multiply the plan's predicted robot blocking by this before the
        checks (a fleet's ``blocking`` check must then fail).

    Returns
    -------
    ValidationReport
        ``checks`` (each with its statistic, acceptance region and false-alarm probability),
        ``passed``, ``failed``.
    """
    import dataclasses
    import time

    from sim.montecarlo.summary import SweepSummary
    from validation.suite import DEFAULT_ALPHA, load_sweep
    from validation.suite import validate as _validate

    start = time.perf_counter()
    directory = sweep.out if isinstance(sweep, SweepSummary) else sweep
    expected = None if scenario is None else _scenario(scenario)
    report = _validate(load_sweep(directory, expected), alpha=DEFAULT_ALPHA if alpha is None else alpha,
                       blocking_scale=blocking_scale)
    return dataclasses.replace(report, sweep=str(directory), wall_time=time.perf_counter() - start)


def validate_scenario(scenario: Scenario | str | Path, *, runs: int | None = None, out: str | Path | None = None,
                      workers: int | None = None, alpha: float | None = None, q_scale: float = 1.0,
                      alone: bool = False, progress: bool | None = False,
                      blocking_scale: float = 1.0) -> ValidationReport:
    """Sweep a scenario (:func:`sweep`, without its report) and judge the sweep (:func:`validate`).

    Every argument is checked before the sweep starts.

    Parameters
    ----------
    scenario : Scenario, str or path
    runs, workers, q_scale, alone, progress
        As :func:`sweep`'s.
    out : str or path, optional
        Keep the sweep in this directory; default a temporary directory, deleted afterwards
        (the report's ``sweep`` is then None).
    alpha, blocking_scale : float, optional
        As :func:`validate`'s.

    Returns
    -------
    ValidationReport
        With ``sweep`` the directory kept (or None) and ``wall_time`` the seconds of the sweep
        and the checks.
    """
    import dataclasses
    import tempfile
    import time

    from validation.suite import check_alpha

    if alpha is not None:
        check_alpha(alpha)  # before the sweep, which takes minutes
    sc = _scenario(scenario)
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="pefsim-validate-") as tmp:
        swept = sweep(sc, out if out is not None else Path(tmp) / "mc", runs=runs, workers=workers,
                      q_scale=q_scale, alone=alone, progress=progress, report=False)
        report = validate(swept, alpha=alpha, scenario=sc, blocking_scale=blocking_scale)
    kept = None if out is None else str(out)
    return dataclasses.replace(report, sweep=kept, wall_time=time.perf_counter() - start)


def paper(out: str | Path = "paper-report", *, quick: bool = False, runs: int | None = None,
          workers: int | None = None, claims: set[int] | None = None, sections: bool = True) -> PaperPage:
    """Reproduce the source paper's claims as figures, numbers and verdicts on one HTML page.

    Parameters
    ----------
    out : str or path
        Output directory: ``index.html``, ``figures/``, claim 7's sweep in ``mc/`` (completed,
        not redone, on a second call).
    quick : bool
        Fewer samples, coarser grids and 3 Monte-Carlo runs instead of 10 (seconds, for tests).
    runs : int, optional
        Monte-Carlo runs of claim 7 (default 10, 3 with ``quick``).
    workers : int, optional
        Monte-Carlo worker processes; default the CPU count.
    claims : set of int, optional
        Only these claims (1..7); default all.
    sections : bool
        Also the results beside the claims (redundancy against blocked lines of sight), when
        every claim is reproduced.

    Returns
    -------
    PaperPage
        ``index`` (the page), ``claims`` (each with its verdict), ``sections``, ``seconds``.
    """
    from validation.paper.claims import Options
    from validation.paper.page import reproduce_page

    return reproduce_page(out, Options(quick=quick, runs=runs, workers=workers), only=claims, sections=sections)


def watch(scenario: str | Path, *, save: str | Path | None = None, connect: str | None = None,
          on_update: Callable[..., None] | None = None, on_error: Callable[[PefsimError], None] | None = None,
          interval: float | None = None, max_updates: int | None = None, stop: threading.Event | None = None) -> int:
    """Show a scenario live in rerun and update the view whenever its files are saved.

    The view: the PEF map and the navigation region (τ < ε_max), the markers (flat ones with
    their facing), the route network coloured by each segment's worst τ (τ = ∞ and inadmissible
    segments apart), every task's chosen route and its fix schedule. The files followed are
    the scenario file and every file it reads (floor plan, map image, route graph). A version
    that does not load or plan is reported through ``on_error`` and the last good view stays.

    Parameters
    ----------
    scenario : str or path
        Scenario file (a built-in name follows the library's file).
    save : str or path, optional
        Write the recording to this ``.rrd`` file instead of showing it.
    connect : str, optional
        Stream to a running viewer at this gRPC URL (``""``: rerun's default).
        Neither: a viewer is started (``rerun`` must be on the ``PATH``).
    on_update : callable (interop.watch.loop.Update), optional
        Called after each update (``.line()`` is ``"updated in 0.23 s, planned in 0.51 s:
        hall.toml: ..."``: the map and the route network are shown first, the plans follow).
    on_error : callable (PefsimError), optional
        Called with the error of a refused version of the files.
    interval : float, optional
        Polling period [s]; default :data:`interop.watch.loop.POLL_INTERVAL`.
    max_updates : int, optional
        Return after this many updates (the first view included); default run until ``stop``
        is set or the process is interrupted (Ctrl-C: the recording is finished either way).
    stop : threading.Event, optional
        Return once it is set.

    Returns
    -------
    int
        Number of updates shown.

    Raises
    ------
    PefsimError
        An unknown scenario, both ``save`` and ``connect``, or an output that cannot be written
        (before anything is watched).
    """
    from interop.watch.live import watch_live

    return watch_live(scenario, save=save, connect=connect, on_update=on_update, on_error=on_error,
                      interval=interval, max_updates=max_updates, stop=stop)


def _check_outputs(*, figure: str | Path | None = None, rrd: str | Path | None = None,
                   folder: str | Path | None = None, named: dict[str, str | Path | None] | None = None) -> None:
    """Refuse, before any work, an output that cannot be written: one line naming the path.

    ``named`` maps each output's parameter to its path: names too long for the file system and
    two outputs at one path are refused (:func:`scenarios.output_names.check_output_names`).
    """
    from scenarios.output_names import check_output_names

    check_output_names(named if named is not None else {"out": figure, "rrd": rrd, "tum": folder})
    if figure is not None:
        from validation.report.figure_format import figure_format

        figure_format(figure)
    if rrd is not None:
        from interop.recording import check_writable

        check_writable(rrd)
    if folder is not None:
        from interop.export.tum import make_folder

        make_folder(folder)


def worlds(count: int, *, seed: int = 0, out: str | Path | None = None, first: int = 0,
           max_size: float | None = None, bounded: bool = False, workers: int = 1) -> list:
    """Draw random honest worlds that plan (declared sensor and robot = the simulated ones).

    World i draws from ``SeedSequence(seed, spawn_key=(i,))`` alone: the same ``seed`` gives
    the same files byte for byte, and world i does not depend on ``count``. A draw that does not
    plan is redrawn (:mod:`planner.worlds`; what is drawn: :mod:`scenarios.worlds`).

    Parameters
    ----------
    count : int
        Number of worlds (1 .. :data:`scenarios.limits.MAX_WORLDS`).
    seed : int
        Root seed (>= 0).
    out : str or path, optional
        Write ``<name>.toml`` for each world into this directory (created if missing); nothing
        is written without it.
    first : int
        Index of the first world (worlds ``first .. first + count - 1``).
    max_size : float, optional
        Cap on the floors' sides [m] (>= ``scenarios.worlds.SMALLEST_MAX_SIZE``): small floors,
        short tasks. None: the full ranges.
    bounded : bool
        Only uniform noise and set-membership PEF models, where containment and the promise are
        deterministic claims (no ``gdop``, no gaussian noise).
    workers : int
        Processes drawing worlds at once (>= 1; 1 draws in this process): the worlds are the same
        whatever the number.

    Returns
    -------
    list of planner.worlds.PlannedWorld
        Each with ``name``, ``text`` (the TOML with its header comment), ``scenario``,
        ``attempts`` and ``summary``; with ``out``, ``path`` is where it was written.
        :func:`iter_worlds` yields them one at a time instead, each written as it is drawn.
    """
    return list(iter_worlds(count, seed=seed, out=out, first=first, max_size=max_size, bounded=bounded,
                            workers=workers))


def iter_worlds(count: int, *, seed: int = 0, out: str | Path | None = None, first: int = 0,
                max_size: float | None = None, bounded: bool = False, workers: int = 1) -> Iterator:
    """Yield the worlds of :func:`worlds` in order, each written into ``out`` as soon as it is drawn.

    The arguments are checked and ``out`` is made when this is called, before any world is
    drawn; memory does not grow with ``count``, and an interrupted run keeps the worlds written.
    Parameters and the worlds yielded: :func:`worlds`.
    """
    from planner.worlds import iter_worlds as _iter_worlds
    from sim.montecarlo.executors import ExecutorKind, execute

    def pool(factory, indices: list[int], n: int) -> Iterator:  # worker processes on this machine
        return execute(ExecutorKind.LOCAL, factory, None, indices, n)

    return _iter_worlds(count, seed=seed, out=out, first=first, max_size=max_size, bounded=bounded, workers=workers,
                        pool=pool)
