"""pefsim: robot routes planned from a Position Error Function, and checked in simulation.

The public Python API; the ``pefsim`` command calls the same functions. Nothing here writes a
file unless told where (``out=``, ``rrd=``, ``tum=``)::

    import pefsim
    sc = pefsim.load("paper-docks")                      # Scenario
    m = pefsim.pef_map(sc)                               # PefMap (x, y, tau, best)
    p = pefsim.plan(sc)                                  # Plan of task 0
    placed = pefsim.place(sc)                            # Placement
    r = pefsim.run_episode(sc, seed=3)                   # EpisodeResult
    sw = pefsim.sweep(sc, out="sw", runs=4, workers=1)   # a finished sweep directory
    rep = pefsim.validate(sw)                            # ValidationReport
    ws = pefsim.worlds(3, seed=1, out="worlds")          # random honest worlds (PlannedWorld)

Units are metres, seconds and radians throughout. Bad input raises :class:`PefsimError` (its
subclasses ``ScenarioError``, ``PlanningError``, ``SimulationError``, ``OutputError``) with a
one-line message naming the file, key and value.
"""

from __future__ import annotations

from pathlib import Path

from planner.pef.map import PefMap
from planner.placement.placement import PlacementResult as Placement
from planner.plan import Plan
from scenarios import PefsimError, Scenario
from sim.episode.types import EpisodeResult
from sim.validation.suite import ValidationReport

__all__ = ["EpisodeResult", "PefMap", "PefsimError", "Placement", "Plan", "Scenario", "ValidationReport",
           "load", "pef_map", "place", "plan", "run_episode", "sweep", "validate", "worlds"]


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


def _scenario(scenario: Scenario | str | Path) -> Scenario:
    return scenario if isinstance(scenario, Scenario) else load(scenario)


def pef_map(scenario: Scenario | str | Path, *, model: str | None = None, resolution: float | None = None,
            speed: float | None = None) -> PefMap:
    """Compute the PEF map: predicted position error on a grid over the workspace.

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

    Returns
    -------
    PefMap
        ``x`` (nx,), ``y`` (ny,) cell centres [m], ``tau`` (ny, nx) [m] (inf: fewer than k
        markers visible, or not free), ``best`` (ny, nx, k) marker indices, ``free`` (ny, nx).
    """
    from planner.pef.map import PEF

    sc = _scenario(scenario)
    pef = PEF(sc, model=model)
    if speed is not None:
        from planner.schedule.promise import moving_map

        return moving_map(sc, pef, speed, resolution)
    return pef.grid(resolution)


def plan(scenario: Scenario | str | Path, task: int = 0, *, start: str | None = None, goal: str | None = None,
         free: bool | None = None) -> Plan:
    """Plan a route: candidates, criteria, the choice and its measurement schedule.

    Parameters
    ----------
    scenario : Scenario, str or path
    task : int
        Index into ``scenario.tasks`` (ignored when ``start`` and ``goal`` are given).
    start, goal : str, optional
        Dock names, instead of a task.
    free : bool, optional
        Free-space search (True) or the route network (False); default the network if any.

    Returns
    -------
    Plan
        ``candidates`` (each with its criteria), ``chosen``, ``reason``, the drivable ``path``
        (N, 2) [m] with ``speed`` (N,) [m/s] and the ``schedule`` (each fix with its promise
        ``predicted_tau`` [m]).
    """
    from planner.plan import plan_route, plan_task

    sc = _scenario(scenario)
    if (start is None) != (goal is None):
        from scenarios import PlanningError

        raise PlanningError("plan: give both start and goal, or neither (then a task is planned)")
    if start is not None:
        return plan_route(sc, start, goal, free=free)
    return plan_task(sc, task, free=free)


def place(scenario: Scenario | str | Path, *, method: str = "auto", out: str | Path | None = None,
          plannable: bool = True) -> Placement:
    """Find the fewest markers, among sites on walls and obstacle faces, that keep the routes under eps_max.

    With ``plannable`` (the default, as ``pefsim place``) the layout is planned for every task
    and the cover target tightened until each has an admissible route
    (:mod:`planner.placement.plannable`); ``plannable=False`` is the plain cover.

    Parameters
    ----------
    scenario : Scenario, str or path
    method : {"auto", "milp", "greedy"}
        Exact MILP (small instances), greedy with the LP lower bound, or chosen by size.
    out : str or path, optional
        Also write the scenario with the placed markers as TOML here.
    plannable : bool
        Check the layout with the planner and tighten the cover until every task plans.

    Returns
    -------
    Placement
        ``markers`` [(id, (x, y))] [m], ``count``, ``lower_bound``, ``optimal``, ``uncovered``.
    """
    from planner.placement.placement import place as _place
    from planner.placement.placement import write_scenario_with_markers

    sc = _scenario(scenario)
    if plannable:
        from planner.placement.plannable import place_plannable

        result = place_plannable(sc, method=method).result
    else:
        result = _place(sc, method=method)
    if out is not None:
        write_scenario_with_markers(sc, result, out)
    return result


def run_episode(scenario: Scenario | str | Path, seed: int = 0, *, task: int = 0, rrd: str | Path | None = None,
                tum: str | Path | None = None) -> EpisodeResult:
    """Drive one episode in PyBullet: plan, follow on the EKF estimate, measure, estimate.

    Parameters
    ----------
    scenario : Scenario, str or path
    seed : int
        Root of the episode's random streams (same seed, same numbers).
    task : int
        Index into ``scenario.tasks``.
    rrd : str or path, optional
        Write a rerun recording of the episode here.
    tum : str or path, optional
        Write ``groundtruth.txt`` and ``estimate.txt`` (TUM format) into this directory.

    Returns
    -------
    EpisodeResult
        ``steps`` (per control step: poses, covariance, error, NEES), ``fixes`` (per fix: the
        realised fault area against its promise), ``plan`` and ``summary``.
    """
    from sim.episode.drive import prepare
    from sim.episode.drive import run_episode as _run

    sc = _scenario(scenario)
    if rrd is not None:
        from sim.recording import check_writable

        check_writable(rrd)
    prepared = prepare(sc, task)
    result = _run(sc, task, seed=seed, prepared=prepared)
    if tum is not None:
        from sim.export.tum import write_tum

        write_tum(tum, result.steps.t, result.steps.true_pose, result.steps.est_pose)
    if rrd is not None:
        from sim.recording import write_episode_rrd

        write_episode_rrd(rrd, sc, result, pef_map=prepared.pef.grid())
    return result


def sweep(scenario: Scenario | str | Path, out: str | Path, *, runs: int | None = None, workers: int | None = None,
          task: int | None = None, resume: bool = False, progress: bool = False, report: bool = True,
          steps: str | None = None) -> Path:
    """Run a Monte-Carlo sweep into ``out`` (written run by run; ``resume`` completes it).

    Parameters
    ----------
    scenario : Scenario, str or path
    out : str or path
        Sweep directory (new, or an earlier sweep of the same scenario with ``resume``).
    runs : int, optional
        Runs ``0 .. runs-1``; default ``montecarlo.runs``.
    workers : int, optional
        Worker processes; default the CPU count. Results do not depend on it.
    task : int, optional
        Drive only this task; default run i drives task ``i % len(tasks)``.
    resume : bool
        Complete the runs an earlier sweep into ``out`` left missing.
    progress : bool
        Show a progress bar.
    report : bool
        Write ``report.html`` and its figures into ``out`` (as ``pefsim mc`` does).
    steps : {"all", "fixes", "none"}, optional
        Per-step rows to keep: every control step, the steps at fix times (the N-run NEES
        check then does not apply), or none; default ``all`` (on resume: the sweep's own).

    Returns
    -------
    pathlib.Path
        The sweep directory (``runs.parquet``, per-step and per-fix parts, ``report.html``).
    """
    from sim.montecarlo.engine import sweep as _sweep

    sc = _scenario(scenario)

    def write(summary) -> None:  # while the sweep still holds the directory's lock
        from sim.report.page import write_report

        write_report(summary.out, sc)

    summary = _sweep(sc, out, runs=runs, task=task, workers=workers, resume=resume, progress=progress,
                     steps=steps, then=write if report else None)
    return Path(summary.out)


def validate(sweep_dir: str | Path, *, alpha: float = 0.01) -> ValidationReport:
    """Check a sweep's results against the predictions (containment, promise, bound, NEES, NIS, ...).

    Parameters
    ----------
    sweep_dir : str or path
        A sweep directory written by :func:`sweep` (or ``pefsim mc``).
    alpha : float
        Family false-alarm probability, split Bonferroni over the statistical checks.

    Returns
    -------
    ValidationReport
        ``checks`` (each with its statistic, acceptance region and false-alarm probability),
        ``passed``, ``failed``.
    """
    from sim.validation.suite import load_sweep
    from sim.validation.suite import validate as _validate

    return _validate(load_sweep(sweep_dir), alpha=alpha)


def worlds(count: int, *, seed: int = 0, out: str | Path | None = None, first: int = 0) -> list:
    """Draw random honest worlds that plan (declared sensor and robot = the simulated ones).

    World i draws from ``SeedSequence(seed, spawn_key=(i,))`` alone: the same ``seed`` gives
    the same files byte for byte, and world i does not depend on ``count``. A draw that does not
    plan is redrawn (:mod:`planner.worlds`; what is drawn: :mod:`scenarios.worlds`).

    Parameters
    ----------
    count : int
        Number of worlds (>= 1).
    seed : int
        Root seed (>= 0).
    out : str or path, optional
        Write ``<name>.toml`` for each world into this directory (created if missing); nothing
        is written without it.
    first : int
        Index of the first world (worlds ``first .. first + count - 1``).

    Returns
    -------
    list of planner.worlds.PlannedWorld
        Each with ``name``, ``text`` (the TOML with its header comment), ``scenario``,
        ``attempts`` and ``summary``; with ``out``, ``path`` is where it was written.
    """
    from dataclasses import replace

    from planner.worlds import plannable_world
    from scenarios import ScenarioError
    from scenarios.errors import output_errors

    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise ScenarioError(f"count: expected a whole number of worlds >= 1, got {count!r}")
    for key, value in (("seed", seed), ("first", first)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise ScenarioError(f"{key}: expected a whole number >= 0, got {value!r}")
    drawn = [plannable_world(seed, i) for i in range(first, first + count)]
    if out is None:
        return drawn
    folder = Path(out)
    with output_errors(folder, "create the output directory"):
        folder.mkdir(parents=True, exist_ok=True)
    written = []
    for w in drawn:
        path = folder / f"{w.name}.toml"
        with output_errors(path, "write the world"):
            path.write_text(w.text, encoding="utf-8")
        written.append(replace(w, path=path))
    return written
