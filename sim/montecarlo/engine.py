"""Monte-Carlo sweeps: N seeded episodes of a scenario, run anywhere, written as they finish.

Run ``i`` draws from ``SeedSequence(scenario.seed, spawn_key=(i,))`` and drives task
``i % n_tasks`` (or one fixed task), so its result depends on nothing but ``i``: not on the
number of workers, the executor or the order in which runs finish. Results go to a sweep
directory (layout in :mod:`sim.montecarlo.results`) one run at a time, so an interrupted sweep loses no
finished run and ``resume=True`` completes only the missing ones. One process at a time writes a
directory (:mod:`sim.montecarlo.lock`); a resume first reads every finished part back and redoes
the runs whose parts do not (:func:`sim.montecarlo.directory.repair`).
"""

from __future__ import annotations

import contextlib
import os
import re
import sys
import tempfile
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from scenarios.errors import PefsimError, ScenarioError
from scenarios.limits import MAX_RUNS
from scenarios.output_names import check_output_names
from scenarios.schema import Scenario
from sim.montecarlo import directory, executors, lock, results
from sim.montecarlo.directory import SWEEP_FORMAT, open_sweep_dir
from sim.montecarlo.executors import ExecutorKind
from sim.montecarlo.progress import progress_bar
from sim.montecarlo.results import RunRecord, SweepLayout
from sim.montecarlo.rows import SINGLE, Schemas, concat_columns, robot_tables, run_row, table_schemas
from sim.montecarlo.steps import StepsMode, steps_mode
from sim.montecarlo.summary import SweepSummary, succeeded, summarize

__all__ = ["SWEEP_FORMAT", "EpisodeApi", "RunSpec", "StepsMode", "SweepSummary", "check_arguments",
           "default_api", "default_out", "open_sweep_dir", "plan_runs", "succeeded", "summarize", "sweep"]


@dataclass(frozen=True)
class EpisodeApi:
    """The episode functions a sweep calls (``sim.episode.run``'s; tests inject fakes).

    Attributes
    ----------
    prepare : callable ``(scenario, task_index) -> prepared``
        Plans a run once; the result is picklable and shared by all runs of the task.
    run_episode : callable ``(scenario, task_index, seed, world, prepared) -> FleetResult``
        One run (:func:`sim.episode.run.run`: each robot's episode); raises PefsimError for bad
        input, anything else is a crash.
    make_world : callable ``(scenario) -> world``, optional
        Builds the physics world a worker keeps and passes to every run (which resets it).
    """

    prepare: Callable[..., Any]
    run_episode: Callable[..., Any]
    make_world: Callable[..., Any] | None = None
    preload: tuple[str, ...] = ()
    """Modules worth importing once before workers start (see :mod:`sim.montecarlo.executors`)."""


def default_api(traffic: bool = True) -> EpisodeApi:
    """Return the real episode API: :mod:`sim.episode.run` in a ``sim.physics.world.PhysicsWorld``.

    A run drives a lone robot's task, or a fleet's robots all together. ``traffic`` False plans
    each fleet robot's measurement schedule as if it drove alone (a negative control). Its parts
    are module-level functions (and partials of them): the local pool pickles them to its workers.
    """
    from functools import partial

    from sim.episode import run

    # The episode imports its filter and fix code lazily; workers need them all anyway.
    preload = ("sim.episode.run", "sim.physics.world", "estimators.ekf", "sim.episode.fixes", "planner.pef.map")
    prepare = run.prepare if traffic else partial(run.prepare, traffic=False)
    return EpisodeApi(prepare, run.run, run.make_world, preload)


@dataclass(frozen=True)
class RunSpec:
    """One run of a sweep: its index, task, the scenario seed, and whether to record it."""

    run: int
    task: int
    entropy: int
    record: bool = False

    def seed_sequence(self) -> np.random.SeedSequence:
        return np.random.SeedSequence(self.entropy, spawn_key=(self.run,))

    @property
    def seed_text(self) -> str:
        """The seed as the Python expression that rebuilds it."""
        return f"SeedSequence({self.entropy}, spawn_key=({self.run},))"


def plan_runs(scenario: Scenario, runs: int, task: int | None = None, rrd_every: int = 0) -> list[RunSpec]:
    """List the runs ``0 .. runs-1``: run ``i`` drives task ``i % n_tasks`` unless ``task`` is set."""
    from sim.episode.run import task_choices

    n_tasks = task_choices(scenario)   # a fleet's every run drives all its robots' tasks
    return [RunSpec(i, task if task is not None else i % n_tasks, scenario.seed,
                    record=rrd_every > 0 and i % rrd_every == 0) for i in range(runs)]


Recorder = Callable[..., Any]
"""Writes one run's recording: ``recorder(path, scenario, result, pef_map=...)`` (the sweep's
caller passes one, e.g. :func:`interop.recording.run.write_run_rrd`: the simulation does not
know the file formats of other tools). A module-level function: the local pool pickles it."""


@dataclass
class WorkerPayload:
    """What every worker receives once: the scenario, the prepared tasks, the episode API, the steps mode."""

    scenario: Scenario
    prepared: dict[int, Any]
    api: EpisodeApi
    steps: StepsMode = StepsMode.ALL
    recorder: Recorder | None = None
    schemas: Schemas = SINGLE

    @property
    def preload(self) -> tuple[str, ...]:
        return self.api.preload


_UNSET = object()


class RunContext:
    """One worker's state: a physics world kept across runs, and the prepared tasks.

    Used as the executors' worker factory: ``RunContext(payload)``.
    """

    def __init__(self, payload: WorkerPayload) -> None:
        self.payload = payload
        self.world: Any = None
        self._pef_map: Any = _UNSET

    def _world(self) -> Any:
        if self.world is None and self.payload.api.make_world is not None:
            self.world = self.payload.api.make_world(self.payload.scenario)
        return self.world

    def execute(self, spec: RunSpec) -> RunRecord:
        """Run one episode and turn it into a record; a crash becomes a record, bad input a fatal one."""
        p = self.payload
        start, cpu_start = time.perf_counter(), time.process_time()
        try:
            result = p.api.run_episode(p.scenario, task_index=spec.task, seed=spec.seed_sequence(),
                                       world=self._world(), prepared=p.prepared[spec.task])
        except PefsimError as exc:
            row = run_row(spec.run, spec.seed_text, spec.task, None, 0.0, status=f"error: {exc}")
            return RunRecord(spec.run, row, fatal=exc)
        except Exception as exc:  # any other exception is a bug in this run: record it, go on
            self._drop_world()  # it may be left in any state
            return RunContext.died(spec, _one_line(exc), time.perf_counter() - start)
        wall, cpu = time.perf_counter() - start, time.process_time() - cpu_start
        return self._record(spec, result, wall, cpu)

    def _record(self, spec: RunSpec, result: Any, wall: float, cpu: float) -> RunRecord:
        """Build a run's record: a row per robot (each with the whole run's wall and CPU time)."""
        p = self.payload
        ids = p.scenario.marker_ids()
        rows, steps, fixes = [], [], []
        for r in result.robots:
            row, st, fx = robot_tables(spec.run, spec.seed_text, r, p.schemas, p.steps, ids, result.names, wall, cpu)
            rows.append(row)
            if st is not None:
                steps.append(st)
            fixes.append(fx)
        record = RunRecord(spec.run, rows, concat_columns(steps) if steps else None, concat_columns(fixes))
        if spec.record:
            record.recording, record.warning = self._recording(result)
        return record

    @staticmethod
    def died(spec: RunSpec, reason: str, wall_time: float | None = None) -> RunRecord:
        """Make the record of a run that crashed (or whose worker died) with ``reason``."""
        return RunRecord(spec.run, run_row(spec.run, spec.seed_text, spec.task, None, wall_time,
                                                   status=f"crashed: {reason}"))

    def _recording(self, result: Any) -> tuple[bytes | None, str | None]:
        recorder = self.payload.recorder
        if recorder is None:
            return None, "recordings skipped: no recorder given"
        try:
            if self._pef_map is _UNSET:
                self._pef_map = recording_pef_map(self.payload.scenario)
            with tempfile.TemporaryDirectory(prefix="pefsim-rrd-") as tmp:
                path = Path(tmp) / "run.rrd"
                recorder(path, self.payload.scenario, result, pef_map=self._pef_map)
                return path.read_bytes(), None
        except Exception as exc:  # a recording is a by-product: keep the run, report the failure
            return None, f"recording failed: {_one_line(exc)}"

    def _drop_world(self) -> None:
        if self.world is not None:
            with contextlib.suppress(Exception):
                self.world.close()
            self.world = None

    def close(self) -> None:
        self._drop_world()


def recording_pef_map(scenario: Scenario) -> Any:
    """Compute the PEF map drawn in recordings (once per worker), or None if the planner cannot."""
    try:
        from planner.pef.map import PEF

        return PEF(scenario).grid()
    except (ImportError, PefsimError):
        return None


def _one_line(exc: BaseException) -> str:
    where = traceback.extract_tb(exc.__traceback__)[-1] if exc.__traceback__ else None
    at = f" (at {Path(where.filename).name}:{where.lineno})" if where else ""
    msg = str(exc).splitlines()[0] if str(exc) else ""
    return f"{type(exc).__name__}: {msg}{at}" if msg else f"{type(exc).__name__}{at}"


# -- the sweep ----------------------------------------------------------------------------

def check_runs(runs: int) -> None:
    """Raise a one-line PefsimError unless 0 < ``runs`` <= MAX_RUNS (the file's own cap, montecarlo.runs)."""
    if runs <= 0:
        raise ScenarioError(f"runs: expected a positive number of runs, got {runs}")
    if runs > MAX_RUNS:  # a row per run in every table
        raise ScenarioError(f"runs: expected at most {MAX_RUNS:.0e} runs, got {runs}")


def check_arguments(scenario: Scenario, runs: int, task: int | None, workers: int, rrd_every: int) -> None:
    """Raise a one-line PefsimError for a bad run count, task, worker count or recording period."""
    check_runs(runs)
    if not scenario.tasks:
        raise ScenarioError(f"{scenario.source}: tasks: expected at least one [[tasks]] entry to drive")
    from sim.episode.run import check_task

    check_task(scenario, task)
    if workers <= 0:
        raise ScenarioError(f"workers: expected a positive number, got {workers}")
    if rrd_every < 0:
        raise ScenarioError(f"rrd_every: expected 0 (none) or a positive period, got {rrd_every}")


def default_out(scenario: Scenario) -> Path:
    """Return the default sweep directory ``mc-<name>``: a plain name in the working directory.

    Every character of the scenario's name outside ``[A-Za-z0-9._-]`` becomes ``_``, so a name
    holding ``/`` or ``..`` cannot lead the sweep out of the working directory.
    """
    return Path("mc-" + re.sub(r"[^A-Za-z0-9._-]", "_", scenario.name))


def sweep(scenario: Scenario, out: str | Path | None = None, *, runs: int | None = None,
          task: int | None = None, workers: int | None = None, executor: ExecutorKind | str = "local",
          address: str | None = None, resume: bool = False, rrd_every: int = 0,
          steps: StepsMode | str | None = None, api: EpisodeApi | None = None, progress: bool | None = None,
          on_warning: Callable[[str], None] | None = None,
          then: Callable[[SweepSummary], Any] | None = None, recorder: Recorder | None = None) -> SweepSummary:
    """Run (or complete) a Monte-Carlo sweep and return what the directory then holds.

    The directory is locked (:mod:`sim.montecarlo.lock`) from the first write to the last, so
    a second process writing it is refused; on resume, parts that do not read back are moved
    aside and their runs redone (:func:`sim.montecarlo.directory.repair`).

    Parameters
    ----------
    scenario : Scenario
        Loaded from text (``scenario.text`` is kept as ``out/scenario.toml``).
    out : path, optional
        Sweep directory; default :func:`default_out` (``mc-<scenario name>``).
    runs : int, optional
        Runs ``0 .. runs-1``; default the earlier sweep's count on resume, else ``scenario.montecarlo.runs``.
    task : int, optional
        Drive only this task; default run ``i`` drives task ``i % n_tasks``.
    workers : int, optional
        Processes or actors; default ``os.cpu_count()`` (a Ray cluster's CPUs with ``address``).
    executor : ExecutorKind or str
        ``local`` or ``ray``.
    address : str, optional
        Ray cluster address.
    resume : bool
        Complete the runs missing in a non-empty ``out`` made from the same scenario.
    rrd_every : int
        Write a recording of every ``rrd_every``-th run with ``recorder`` (0: none).
    steps : StepsMode or str, optional
        Per-step rows to keep: ``all``, ``fixes`` (the steps at fix times) or ``none``; default
        the earlier sweep's on resume, else ``all``. Recorded in ``sweep.json``.
    api : EpisodeApi, optional
        The episode functions; default :func:`default_api`.
    progress : bool, optional
        Show a progress bar; default when stderr is a terminal.
    on_warning : callable, optional
        Receives one-line warnings (damaged parts, a stale lock, failed recordings); default
        prints them on stderr (above the bar).
    then : callable, optional
        Called with the summary while the directory is still locked (``pefsim mc`` writes its
        report there).
    recorder : Recorder, optional
        Writes the recordings ``rrd_every`` asks for; required when ``rrd_every`` > 0.

    Returns
    -------
    SweepSummary
    """
    kind = _executor_kind(executor)
    if address and kind is not ExecutorKind.RAY:
        raise ScenarioError(f"address: needs executor ray, got executor {kind.value}")
    if kind is ExecutorKind.RAY:
        executors.import_ray()
    if runs is not None:
        check_runs(runs)  # before the directory is made
    check_output_names({"out": out} if out is not None else {"out (default mc-<scenario name>)":
                                                               default_out(scenario)})
    out = Path(out) if out is not None else default_out(scenario)
    wanted = None if steps is None else steps_mode(steps)
    settings = open_sweep_dir(scenario, out, resume, task, wanted)
    if runs is None:
        runs = int(settings.get("runs", scenario.montecarlo.runs))
    if workers is None:
        on_cluster = kind is ExecutorKind.RAY and address
        workers = executors.ray_cluster_cpus(address) if on_cluster else (os.cpu_count() or 1)
    check_arguments(scenario, runs, task, workers, rrd_every)
    if rrd_every > 0 and recorder is None:
        raise ValueError("rrd_every > 0 needs a recorder (e.g. interop.recording.run.write_run_rrd)")
    if not scenario.text:
        raise ScenarioError(f"{scenario.source}: the scenario has no source text to keep beside the results")
    layout = SweepLayout(out)
    layout.check_writable()  # fails before the planning work; leaves at most an empty directory
    warnings: list[Callable[[str], None]] = [on_warning or _stderr]
    with lock.held(out, lambda line: warnings[-1](line)):
        # Read again under the lock: another process may have written between the check and the lock.
        settings = open_sweep_dir(scenario, out, resume, task, wanted)
        mode = directory.stored_steps_mode(settings) if settings else (wanted or StepsMode.ALL)
        if settings:
            directory.repair(layout, mode, warnings[-1])
        done = results.finished_runs(layout) if settings else set()
        todo = [s for s in plan_runs(scenario, runs, task, rrd_every) if s.run not in done]
        executed, wall = 0, 0.0
        if todo:
            executed, wall = _execute(scenario, layout, settings, todo, runs, task, mode, workers, kind,
                                      address, api, progress, on_warning, warnings, recorder)
        results.compact_runs(layout)
        sizes = directory.record_sizes(layout)
        summary = summarize(out, scenario.montecarlo.success_target, executed, wall, mode.value, sizes)
        if then is not None:
            then(summary)
    return summary


def _execute(scenario: Scenario, layout: SweepLayout, settings: dict[str, Any], todo: list[RunSpec], runs: int,
             task: int | None, mode: StepsMode, workers: int, kind: ExecutorKind, address: str | None,
             api: EpisodeApi | None, progress: bool | None, on_warning: Callable[[str], None] | None,
             warnings: list[Callable[[str], None]], recorder: Recorder | None = None) -> tuple[int, float]:
    """Plan the tasks, run ``todo`` and write each record as it comes; returns (runs executed, wall seconds)."""
    api = api if api is not None else default_api()
    # Planning once here catches bad input (no route) before any worker starts.
    tasks = sorted({s.task for s in todo})
    prepared = {}
    with progress_bar(total=len(tasks), enabled=progress, desc="tasks", verb="planned") as bar:
        for t in tasks:   # a large map's tasks take minutes to plan: say how far it is
            prepared[t] = api.prepare(scenario, t)
            bar.update(1)
    if settings:
        results.clean_unfinished(layout)
    directory.init_sweep_dir(layout, scenario, task, max(runs, int(settings.get("runs", 0))), mode)
    sch = table_schemas(scenario)
    payload = WorkerPayload(scenario, prepared, api, mode, recorder, sch)
    executed = 0
    start = time.perf_counter()
    with progress_bar(total=runs, initial=runs - len(todo), enabled=progress) as bar:
        warnings.append(on_warning or bar.write)
        try:
            stream = executors.execute(kind, RunContext, payload, todo, min(workers, len(todo)), address)
            with contextlib.closing(stream):
                for record in stream:
                    if record.fatal is not None:
                        raise type(record.fatal)(f"run {record.run}: {record.fatal}") from None
                    results.write_record(layout, record, sch)
                    executed += 1
                    if record.warning:
                        warnings[-1](f"pefsim: warning: run {record.run}: {record.warning}")
                    bar.update(1)
        finally:
            warnings.pop()
    return executed, time.perf_counter() - start


def _stderr(line: str) -> None:
    print(line, file=sys.stderr)


def _executor_kind(executor: ExecutorKind | str) -> ExecutorKind:
    try:
        return ExecutorKind(executor)
    except ValueError:
        choices = ", ".join(k.value for k in ExecutorKind)
        raise ScenarioError(f"executor: expected one of {choices}, got {executor!r}") from None
