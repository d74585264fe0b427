"""Monte-Carlo sweeps: N seeded episodes of a scenario, run anywhere, written as they finish.

Run ``i`` draws from ``SeedSequence(scenario.seed, spawn_key=(i,))`` and drives task
``i % n_tasks`` (or one fixed task), so its result depends on nothing but ``i``: not on the
number of workers, the executor or the order in which runs finish. Results go to a sweep
directory (layout in :mod:`sim.montecarlo.results`) one run at a time, so an interrupted sweep loses no
finished run and ``resume=True`` completes only the missing ones.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
import time
import traceback
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

from scenarios.errors import OutputError, PefsimError, ScenarioError
from scenarios.schema import Scenario
from sim.montecarlo import executors, results
from sim.montecarlo.executors import ExecutorKind
from sim.montecarlo.progress import progress_bar
from sim.montecarlo.results import RunRecord, SweepLayout

SWEEP_FORMAT = 1


@dataclass(frozen=True)
class EpisodeApi:
    """The episode functions a sweep calls (``sim.episode.drive``'s; tests inject fakes).

    Attributes
    ----------
    prepare : callable ``(scenario, task_index) -> prepared``
        Plans a task once; the result is picklable and shared by all runs of the task.
    run_episode : callable ``(scenario, task_index, seed, world, prepared) -> EpisodeResult``
        One episode; raises PefsimError for bad input, anything else is a crash.
    make_world : callable ``(scenario) -> world``, optional
        Builds the physics world a worker keeps and passes to every run (which resets it).
    """

    prepare: Callable[..., Any]
    run_episode: Callable[..., Any]
    make_world: Callable[..., Any] | None = None
    preload: tuple[str, ...] = ()
    """Modules worth importing once before workers start (see :mod:`sim.montecarlo.executors`)."""


def default_api() -> EpisodeApi:
    """Return the real episode API: ``sim.episode.drive`` in a ``sim.physics.world.PhysicsWorld``."""
    from sim.episode import drive as episode
    from sim.physics.world import PhysicsWorld

    # The episode imports its filter and fix code lazily; workers need them all anyway.
    preload = ("sim.episode.drive", "sim.physics.world", "estimators.ekf", "sim.episode.fixes", "planner.pef.map")
    return EpisodeApi(episode.prepare, episode.run_episode, PhysicsWorld, preload)


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
    n_tasks = len(scenario.tasks)
    return [RunSpec(i, task if task is not None else i % n_tasks, scenario.seed,
                    record=rrd_every > 0 and i % rrd_every == 0) for i in range(runs)]


@dataclass
class WorkerPayload:
    """What every worker receives once: the scenario, the prepared tasks and the episode API."""

    scenario: Scenario
    prepared: dict[int, Any]
    api: EpisodeApi

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
            row = results.run_row(spec.run, spec.seed_text, spec.task, None, 0.0, status=f"error: {exc}")
            return RunRecord(spec.run, row, fatal=exc)
        except Exception as exc:  # any other exception is a bug in this run: record it, go on
            self._drop_world()  # it may be left in any state
            return RunContext.died(spec, _one_line(exc), time.perf_counter() - start)
        wall, cpu = time.perf_counter() - start, time.process_time() - cpu_start
        row = results.run_row(spec.run, spec.seed_text, spec.task, result.summary, wall, cpu_time=cpu)
        record = RunRecord(spec.run, row, results.step_columns(spec.run, result.steps),
                           results.fix_columns(spec.run, result.fixes))
        if spec.record:
            record.recording, record.warning = self._recording(result)
        return record

    @staticmethod
    def died(spec: RunSpec, reason: str, wall_time: float | None = None) -> RunRecord:
        """Make the record of a run that crashed (or whose worker died) with ``reason``."""
        return RunRecord(spec.run, results.run_row(spec.run, spec.seed_text, spec.task, None, wall_time,
                                                   status=f"crashed: {reason}"))

    def _recording(self, result: Any) -> tuple[bytes | None, str | None]:
        try:
            from sim import recording
        except ImportError as exc:
            return None, f"recordings skipped: {exc}"
        try:
            if self._pef_map is _UNSET:
                self._pef_map = recording_pef_map(self.payload.scenario)
            with tempfile.TemporaryDirectory(prefix="pefsim-rrd-") as tmp:
                path = Path(tmp) / "run.rrd"
                recording.write_episode_rrd(path, self.payload.scenario, result, pef_map=self._pef_map)
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

@dataclass
class SweepSummary:
    """What a sweep directory holds, as ``pefsim mc --json`` prints it.

    A run succeeds when it ran (status ok), reached its goal and never exceeded ε_max;
    crashed runs count as failures. ``success_ci`` is the 95 % Clopper-Pearson interval.
    """

    out: str
    runs: int
    ok: int
    crashed: int
    reached: int
    violation_runs: int
    successes: int
    success_fraction: float | None
    success_ci: list[float] | None
    success_target: float
    executed: int
    wall_time: float
    runs_per_minute: float | None

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def succeeded(runs: pa.Table) -> np.ndarray:
    """Per row of a runs table: ran (status ok), reached its goal and never exceeded ε_max."""
    status = np.asarray(runs.column("status").to_pylist(), dtype=object)
    reached = np.asarray(runs.column("reached").fill_null(False).to_numpy(zero_copy_only=False), dtype=bool)
    violations = np.asarray(runs.column("violations").fill_null(0).to_numpy(zero_copy_only=False))
    return (status == "ok") & reached & (violations == 0)


def summarize(out: str | Path, success_target: float, executed: int = 0,
              wall_time: float = 0.0) -> SweepSummary:
    """Count the finished runs of sweep directory ``out``."""
    from scipy.stats import binomtest

    table = results.read_runs(out)
    status = np.asarray(table.column("status").to_pylist(), dtype=object)
    ok = status == "ok"
    reached = np.asarray(table.column("reached").fill_null(False).to_numpy(zero_copy_only=False), dtype=bool)
    violations = np.asarray(table.column("violations").fill_null(0).to_numpy(zero_copy_only=False))
    n = len(status)
    k = int(succeeded(table).sum())
    fraction = ci = None
    if n:
        fraction = k / n
        interval = binomtest(k, n).proportion_ci(confidence_level=0.95, method="exact")
        ci = [float(interval.low), float(interval.high)]
    rate = 60.0 * executed / wall_time if executed and wall_time > 0 else None
    return SweepSummary(out=str(out), runs=n, ok=int(ok.sum()), crashed=int(np.sum(~ok)),
                        reached=int((reached & ok).sum()), violation_runs=int(np.sum(ok & (violations > 0))),
                        successes=k, success_fraction=fraction, success_ci=ci, success_target=success_target,
                        executed=executed, wall_time=wall_time, runs_per_minute=rate)


def check_arguments(scenario: Scenario, runs: int, task: int | None, workers: int, rrd_every: int) -> None:
    """Raise a one-line PefsimError for a bad run count, task, worker count or recording period."""
    if runs <= 0:
        raise ScenarioError(f"--runs: expected a positive number of runs, got {runs}")
    if not scenario.tasks:
        raise ScenarioError(f"{scenario.source}: tasks: expected at least one [[tasks]] entry to drive")
    if task is not None and not 0 <= task < len(scenario.tasks):
        raise ScenarioError(f"--task: expected 0 .. {len(scenario.tasks) - 1} "
                            f"({len(scenario.tasks)} tasks in {scenario.source}), got {task}")
    if workers <= 0:
        raise ScenarioError(f"--workers: expected a positive number, got {workers}")
    if rrd_every < 0:
        raise ScenarioError(f"--rrd-every: expected 0 (none) or a positive period, got {rrd_every}")


def open_sweep_dir(scenario: Scenario, out: Path, resume: bool, task: int | None) -> dict[str, Any]:
    """Check that ``out`` may take this sweep; returns the settings of an earlier sweep there ({} if new).

    Writes nothing. Raises OutputError for a file in the way, a non-empty directory without
    ``resume``, or a directory of another scenario or task.
    """
    layout = SweepLayout(out)
    if out.exists() and not out.is_dir():
        raise OutputError(f"{out}: exists and is not a directory")
    if not out.exists() or not any(out.iterdir()):
        return {}
    if not resume:
        raise OutputError(f"{out}: output directory is not empty; use --resume to complete it or --out "
                          "for a new one")
    try:
        previous_text = layout.scenario_toml.read_text(encoding="utf-8")
        settings = json.loads(layout.sweep_json.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        raise OutputError(f"{out}: not a pefsim mc directory (no readable scenario.toml and sweep.json); "
                          "use another --out") from None
    if previous_text != scenario.text:
        raise OutputError(f"{out}: was made from another scenario (its scenario.toml differs from "
                          f"{scenario.source}); use another --out")
    if settings.get("task") != task:
        raise OutputError(f"{out}: was made with --task {settings.get('task')}, not {task}; "
                          "resume with the same --task or use another --out")
    return settings


def _init_sweep_dir(layout: SweepLayout, scenario: Scenario, task: int | None, runs: int) -> None:
    layout.make_dirs()
    results.write_atomic(layout.scenario_toml, scenario.text.encode("utf-8"))
    settings = {"format": SWEEP_FORMAT, "scenario": scenario.name, "task": task, "runs": runs}
    results.write_atomic(layout.sweep_json, (json.dumps(settings, indent=2) + "\n").encode("utf-8"))


def sweep(scenario: Scenario, out: str | Path | None = None, *, runs: int | None = None,
          task: int | None = None, workers: int | None = None, executor: ExecutorKind | str = "local",
          address: str | None = None, resume: bool = False, rrd_every: int = 0,
          api: EpisodeApi | None = None, progress: bool | None = None,
          on_warning: Callable[[str], None] | None = None) -> SweepSummary:
    """Run (or complete) a Monte-Carlo sweep and return what the directory then holds.

    Parameters
    ----------
    scenario : Scenario
        Loaded from text (``scenario.text`` is kept as ``out/scenario.toml``).
    out : path, optional
        Sweep directory; default ``mc-<scenario name>``.
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
        Write a rerun recording of every ``rrd_every``-th run (0: none).
    api : EpisodeApi, optional
        The episode functions; default :func:`default_api`.
    progress : bool, optional
        Show a progress bar; default when stderr is a terminal.
    on_warning : callable, optional
        Receives one-line warnings (failed recordings); default prints them above the bar.

    Returns
    -------
    SweepSummary
    """
    kind = _executor_kind(executor)
    if kind is ExecutorKind.RAY:
        executors.import_ray()
    out = Path(out if out is not None else f"mc-{scenario.name}")
    settings = open_sweep_dir(scenario, out, resume, task)
    if runs is None:
        runs = int(settings.get("runs", scenario.montecarlo.runs))
    if workers is None:
        on_cluster = kind is ExecutorKind.RAY and address
        workers = executors.ray_cluster_cpus(address) if on_cluster else (os.cpu_count() or 1)
    check_arguments(scenario, runs, task, workers, rrd_every)
    if not scenario.text:
        raise ScenarioError(f"{scenario.source}: the scenario has no source text to keep beside the results")
    layout = SweepLayout(out)
    layout.check_writable()  # fails before the planning work; leaves at most an empty directory
    done = results.finished_runs(layout) if settings else set()
    todo = [s for s in plan_runs(scenario, runs, task, rrd_every) if s.run not in done]

    executed, wall = 0, 0.0
    if todo:
        api = api if api is not None else default_api()
        # Planning once here catches bad input (no route) before any worker starts.
        prepared = {t: api.prepare(scenario, t) for t in sorted({s.task for s in todo})}
        if settings:
            results.clean_unfinished(layout)
        _init_sweep_dir(layout, scenario, task, max(runs, int(settings.get("runs", 0))))
        payload = WorkerPayload(scenario, prepared, api)
        warn = on_warning
        start = time.perf_counter()
        with progress_bar(total=runs, initial=runs - len(todo), enabled=progress) as bar:
            warn = warn or bar.write
            stream = executors.execute(kind, RunContext, payload, todo, min(workers, len(todo)), address)
            with contextlib.closing(stream):
                for record in stream:
                    if record.fatal is not None:
                        raise type(record.fatal)(f"run {record.run}: {record.fatal}") from None
                    results.write_record(layout, record)
                    executed += 1
                    if record.warning:
                        warn(f"pefsim: warning: run {record.run}: {record.warning}")
                    bar.update(1)
        wall = time.perf_counter() - start
    results.compact_runs(layout)
    return summarize(out, scenario.montecarlo.success_target, executed, wall)


def _executor_kind(executor: ExecutorKind | str) -> ExecutorKind:
    try:
        return ExecutorKind(executor)
    except ValueError:
        choices = ", ".join(k.value for k in ExecutorKind)
        raise ScenarioError(f"--executor: expected one of {choices}, got {executor!r}") from None
