"""A fast stand-in for ``sim.episode.drive`` with the same interface, for Monte-Carlo harness tests.

Its results depend only on the seed (like the real episode's), so a harness that hands every
run its own ``SeedSequence`` must produce identical files whatever the workers or executor.
Functions live at module level so that worker processes and Ray actors can import them.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass

import numpy as np

from scenarios.errors import PlanningError, SimulationError
from sim.episode.types import SUMMARY_KEYS, EpisodeResult, FixLog, StepLog
from sim.montecarlo.engine import EpisodeApi

N_STEPS = 120
N_FIXES = 12


@dataclass(frozen=True)
class FakePrepared:
    task_index: int
    start: tuple[float, float]
    goal: tuple[float, float]


class FakeWorld:
    """Counts its resets; ``closed`` tells whether close() ran."""

    def __init__(self, scenario) -> None:
        self.resets = 0
        self.closed = False
        self.pid = os.getpid()

    def reset(self, pose) -> None:
        self.resets += 1

    def close(self) -> None:
        self.closed = True


def prepare(scenario, task_index: int) -> FakePrepared:
    task = scenario.tasks[task_index]
    return FakePrepared(task_index, scenario.dock(task.start).position, scenario.dock(task.goal).position)


def run_episode(scenario, task_index: int = 0, seed=0, world=None, prepared=None) -> EpisodeResult:
    if prepared is None:
        prepared = prepare(scenario, task_index)
    if prepared.task_index != task_index:
        raise SimulationError(f"prepared for task {prepared.task_index}, asked for task {task_index}")
    if world is not None:
        world.reset((*prepared.start, 0.0))
    rng = np.random.default_rng(seed)
    eps = scenario.planning.eps_max
    s = np.linspace(0.0, 1.0, N_STEPS)
    path = np.outer(1 - s, prepared.start) + np.outer(s, prepared.goal)
    true_pose = np.column_stack([path, np.full(N_STEPS, 0.1 * task_index)])
    err = rng.normal(0.0, eps / 3, size=(N_STEPS, 3))
    est_pose = true_pose + err
    error = np.hypot(err[:, 0], err[:, 1])
    cov = np.broadcast_to(np.diag([(eps / 3) ** 2] * 3), (N_STEPS, 3, 3)).copy()
    tau = np.full(N_STEPS, eps * 0.9)
    nees = np.einsum("ti,tij,tj->t", err, np.linalg.inv(cov), err)
    steps = StepLog(t=s * 10.0, true_pose=true_pose, est_pose=est_pose, est_cov=cov, error=error,
                    predicted_tau=tau, pef_tau=tau * 0.8, nees=nees, certified=tau * 1.1)
    idx = np.linspace(0, N_STEPS - 1, N_FIXES).astype(int)
    truth = path[idx]
    snap = truth + rng.uniform(-eps / 4, eps / 4, size=(N_FIXES, 2))
    k = scenario.sensor.markers_per_fix
    fixes = FixLog(
        t=s[idx] * 10.0, markers=np.tile(np.arange(k), (N_FIXES, 1)),
        ranges=rng.uniform(1.0, 5.0, size=(N_FIXES, k)), rho=np.full((N_FIXES, k), 1e-3),
        true_position=truth, snapshot=snap, snapshot_cov=np.broadcast_to(np.eye(2) * 1e-6, (N_FIXES, 2, 2)),
        fault_diameter=rng.uniform(0.5, 1.0, N_FIXES) * eps, fault_polygons=[np.zeros((4, 2))] * N_FIXES,
        contained=rng.uniform(size=N_FIXES) < 0.95, predicted_tau=tau[idx], static_tau=tau[idx] * 0.8,
        nis=rng.chisquare(2, N_FIXES),
        n_accepted=np.full(N_FIXES, k))
    summary = dict(reached=bool(rng.uniform() < 0.9), duration=10.0, steps=N_STEPS, fixes=N_FIXES,
                   rmse=float(np.sqrt(np.mean(error ** 2))), max_error=float(error.max()),
                   max_predicted_tau=float(tau.max()), eps_max=eps, violations=int(np.sum(error > eps)),
                   seed=0, mean_nees=float(nees.mean()), mean_nis=float(fixes.nis.mean()),
                   blocked_markers=0, fallback_fixes=0, failed_fixes=0, certified_max=float(tau.max()),
                   lost_guarantee=0)
    assert set(summary) == set(SUMMARY_KEYS)
    return EpisodeResult(scenario.name, task_index, 0, eps, steps, fixes, None, summary)


def _run_index(seed) -> int:
    return int(seed.spawn_key[0])


CRASH_EVERY = 5


def run_episode_crashy(scenario, task_index: int = 0, seed=0, world=None, prepared=None) -> EpisodeResult:
    """Crashes (a bug, not bad input) on runs 2, 7, 12, ..."""
    if _run_index(seed) % CRASH_EVERY == 2:
        raise ZeroDivisionError("fake bug")
    return run_episode(scenario, task_index, seed, world, prepared)


def run_episode_fatal(scenario, task_index: int = 0, seed=0, world=None, prepared=None) -> EpisodeResult:
    """Bad input on run 3: a PefsimError, which stops the sweep."""
    if _run_index(seed) == 3:
        raise SimulationError("fake: robot cannot start at dock A")
    return run_episode(scenario, task_index, seed, world, prepared)


def run_episode_slow(scenario, task_index: int = 0, seed=0, world=None, prepared=None) -> EpisodeResult:
    time.sleep(float(os.environ.get("FAKE_EPISODE_SLEEP", "0.05")))
    return run_episode(scenario, task_index, seed, world, prepared)


def run_episode_segfault(scenario, task_index: int = 0, seed=0, world=None, prepared=None) -> EpisodeResult:
    """Kills its own process on run 4, as a crash inside pybullet would."""
    if _run_index(seed) == 4:
        os._exit(139)
    return run_episode(scenario, task_index, seed, world, prepared)


def prepare_unplannable(scenario, task_index: int) -> FakePrepared:
    raise PlanningError(f"task {task_index}: no admissible route")


API = EpisodeApi(prepare, run_episode, FakeWorld)
UNPLANNABLE = EpisodeApi(prepare_unplannable, run_episode, FakeWorld)
CRASHY = EpisodeApi(prepare, run_episode_crashy, FakeWorld)
FATAL = EpisodeApi(prepare, run_episode_fatal, FakeWorld)
SLOW = EpisodeApi(prepare, run_episode_slow, FakeWorld)
SEGFAULT = EpisodeApi(prepare, run_episode_segfault, FakeWorld)
