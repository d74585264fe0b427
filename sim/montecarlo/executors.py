"""Where Monte-Carlo runs execute: in-process, a local process pool, or Ray actors.

Every executor gets a *worker factory* and a *payload*: each worker builds one context
``factory(payload)`` (which keeps one physics world and the prepared plans) and calls
``context.execute(spec)`` for every run it is handed; the payload is shipped once per worker,
not once per run. Executors yield each run's record as it finishes, in completion order; the
caller writes it. A worker process that dies (a crash inside pybullet) costs only its own
run, recorded through ``factory.died(spec, reason)``: the other runs are re-run elsewhere.
"""

from __future__ import annotations

import copy
import logging
import multiprocessing
import multiprocessing.connection
import multiprocessing.util
import os
import signal
import threading
from collections import deque
from collections.abc import Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from enum import Enum
from typing import Any, Protocol

from jit import compiled
from scenarios.errors import PefsimError


class ExecutorKind(str, Enum):
    """Where runs execute.

    ``local``: a process pool on this machine (one run in-process with one worker);
    ``ray``: Ray actors on a local or remote cluster.
    """

    LOCAL = "local"
    RAY = "ray"


class WorkerContext(Protocol):
    def execute(self, spec: Any) -> Any: ...

    def close(self) -> None: ...


class WorkerFactory(Protocol):
    def __call__(self, payload: Any) -> WorkerContext: ...

    def died(self, spec: Any, reason: str) -> Any: ...


RAY_INSTALL_HINT = "executor ray needs Ray: pip install 'pefsim[ray]'"

# Start workers from a fresh single-threaded server process rather than by forking the caller,
# which may hold threads (BLAS, tqdm, Ray) or a pybullet client that fork would duplicate.
START_METHOD = "forkserver"


def execute(kind: ExecutorKind, factory: WorkerFactory, payload: Any, specs: list[Any], workers: int,
            address: str | None = None) -> Iterator[Any]:
    """Run every spec and yield the records as they finish.

    Parameters
    ----------
    kind : ExecutorKind
        Where to run.
    factory, payload
        ``factory(payload)`` builds one worker's context (see the module docstring).
    specs : list
        The runs, each handed to ``context.execute``.
    workers : int
        Worker processes or actors (1 with ``local`` runs in this process, without a pool).
    address : str, optional
        Ray cluster address (``ray`` only); default starts a local cluster of ``workers`` CPUs.
    """
    if kind is ExecutorKind.RAY:
        return iter_ray(factory, payload, specs, workers, address)
    if workers <= 1:
        return iter_serial(factory, payload, specs)
    return iter_local_pool(factory, payload, specs, workers)


def iter_serial(factory: WorkerFactory, payload: Any, specs: Iterable[Any]) -> Iterator[Any]:
    """Run the specs one after another in this process, with one context."""
    context = factory(payload)
    try:
        for spec in specs:
            yield context.execute(spec)
    finally:
        context.close()


# -- local process pool -------------------------------------------------------------------

_context: WorkerContext | None = None  # the one context of a pool worker process


def _pool_init(factory: WorkerFactory, payload: Any, announce: tuple | None = None) -> None:
    global _context
    # a cold cache: the worker says it compiles (jit.compiled.announce_in_worker), unless the parent did
    compiled.announce_in_worker(announce)
    # The parent decides what an interrupt means (stop, keep finished runs); a worker that
    # died of Ctrl-C mid-run would only look like a crash.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    parent = multiprocessing.parent_process()
    if parent is not None:
        # Without this, workers of a parent killed with SIGKILL would wait on the task queue forever.
        threading.Thread(target=_exit_with, args=(parent.sentinel,), daemon=True).start()
    _one_thread_per_worker()
    _context = factory(payload)
    multiprocessing.util.Finalize(None, _context.close, exitpriority=10)


def _one_thread_per_worker() -> None:
    # Workers already fill the cores; kernel threads on top only contend for them.
    from planner.pef.threads import set_threads

    set_threads(1)


def _exit_with(sentinel: int) -> None:
    multiprocessing.connection.wait([sentinel])
    os._exit(1)


def _pool_run(spec: Any) -> Any:
    if _context is None:
        raise RuntimeError("pool worker was not initialised")
    return _context.execute(spec)


def _new_pool(factory: WorkerFactory, payload: Any, workers: int) -> ProcessPoolExecutor:
    context = multiprocessing.get_context(START_METHOD)
    if START_METHOD == "forkserver":
        # The server imports these once and every worker forks with them loaded, instead of
        # each worker importing scipy, pybullet, ... anew (seconds each, all at once).
        # Takes effect when the server starts (the first pool of this process).
        context.set_forkserver_preload(["sim.montecarlo.engine", *getattr(payload, "preload", ())])
    return ProcessPoolExecutor(max_workers=workers, mp_context=context,
                               initializer=_pool_init, initargs=(factory, payload, compiled.announce_state()))


def iter_local_pool(factory: WorkerFactory, payload: Any, specs: Iterable[Any],
                    workers: int) -> Iterator[Any]:
    """Run the specs on a pool of ``workers`` processes, each keeping its context.

    At most ``2 * workers`` runs are queued at a time, so that an interrupt stops soon and a
    dying worker leaves few runs in doubt; those are re-run one at a time in a fresh process,
    which records as crashed only the run that kills its process again.
    """
    queue = deque(specs)
    window = 2 * workers
    while queue:
        pool = _new_pool(factory, payload, workers)
        in_flight: dict[Future, Any] = {}
        suspects: list[Any] = []
        broken = False
        yielded = 0
        try:
            while (queue or in_flight) and not broken:
                while queue and len(in_flight) < window:
                    try:
                        fut = pool.submit(_pool_run, queue[0])
                    except BrokenProcessPool:
                        broken = True
                        break
                    in_flight[fut] = queue.popleft()
                done, _ = wait(in_flight, return_when=FIRST_COMPLETED)
                for fut in done:
                    spec = in_flight.pop(fut)
                    try:
                        record = fut.result()
                    except BrokenProcessPool:
                        suspects.append(spec)
                        broken = True
                        continue
                    yielded += 1
                    yield record
            suspects.extend(in_flight.values())
            in_flight.clear()
        finally:
            pool.shutdown(wait=not broken and not in_flight, cancel_futures=True)
        if broken and not suspects and not yielded:
            raise RuntimeError("Monte-Carlo worker processes die while starting; run with one "
                               "worker to see why")
        for spec in sorted(suspects, key=_order):
            yield _isolated(factory, payload, spec)


def _order(spec: Any) -> Any:
    return getattr(spec, "run", 0)


def _pool_ping() -> int:
    return os.getpid()


def _isolated(factory: WorkerFactory, payload: Any, spec: Any) -> Any:
    pool = _new_pool(factory, payload, 1)
    try:
        try:
            pool.submit(_pool_ping).result()
        except BrokenProcessPool:
            # Not the run's fault: no worker can start (unimportable payload, failing initializer).
            raise RuntimeError("Monte-Carlo worker processes die while starting; run with one "
                               "worker to see why") from None
        try:
            return pool.submit(_pool_run, spec).result()
        except BrokenProcessPool:
            return factory.died(spec, "worker process died")
    finally:
        pool.shutdown(wait=True)


# -- Ray ----------------------------------------------------------------------------------

class _RayWorker:
    """A Ray actor keeping one context (one physics world) for all the runs it is given."""

    def __init__(self, factory: WorkerFactory, payload: Any) -> None:
        _one_thread_per_worker()
        # Ray hands numpy arrays out of its object store read-only (zero-copy); the PEF's
        # memos grow theirs in place, so the actor works on its own copy.
        self.context = factory(copy.deepcopy(payload))

    def execute(self, spec: Any) -> Any:
        return self.context.execute(spec)


def import_ray() -> Any:
    """Import ``ray``, or raise a PefsimError telling how to install it."""
    try:
        import ray
    except ImportError:
        raise PefsimError(RAY_INSTALL_HINT) from None
    return ray


def start_ray(workers: int | None, address: str | None) -> tuple[Any, bool]:
    """Connect to the cluster at ``address`` or start a local one; returns (ray, started_here)."""
    ray = import_ray()
    if ray.is_initialized():
        return ray, False
    # Ray's INFO lines ("Started a local Ray instance.") would be stray output on stderr
    quiet = {"log_to_driver": False, "logging_level": logging.WARNING}
    try:
        if address:
            ray.init(address=address, **quiet)
        else:
            # A local cluster needs no token; without this Ray writes ~/.ray/auth_token.
            os.environ.setdefault("RAY_AUTH_MODE", "disabled")
            ray.init(num_cpus=workers, include_dashboard=False, **quiet)
    except (ConnectionError, ValueError, RuntimeError) as exc:
        where = f"the Ray cluster at {address}" if address else "a local Ray cluster"
        raise PefsimError(f"cannot start or reach {where}: {str(exc).splitlines()[0]}") from None
    return ray, True


def ray_cluster_cpus(address: str | None) -> int:
    """CPUs of the Ray cluster at ``address`` (connecting to it), at least 1."""
    ray, _ = start_ray(None, address)
    return max(1, int(ray.cluster_resources().get("CPU", 1)))


def iter_ray(factory: WorkerFactory, payload: Any, specs: Iterable[Any], workers: int,
             address: str | None) -> Iterator[Any]:
    """Run the specs on ``workers`` Ray actors, one run in flight per actor.

    One run per actor at a time keeps the bookkeeping exact: when an actor dies, the run it
    held is the one recorded as crashed, and a fresh actor takes its place.
    """
    ray, started = start_ray(workers, address)
    Actor = ray.remote(num_cpus=1)(_RayWorker)
    payload_ref = ray.put(payload)
    queue = deque(specs)
    actors = {Actor.remote(factory, payload_ref) for _ in range(min(workers, len(queue)))}
    in_flight: dict[Any, tuple[Any, Any]] = {}  # object ref -> (actor, spec)
    try:
        for actor in actors:
            if queue:
                spec = queue.popleft()
                in_flight[actor.execute.remote(spec)] = (actor, spec)
        while in_flight:
            ready, _ = ray.wait(list(in_flight), num_returns=1)
            ref = ready[0]
            actor, spec = in_flight.pop(ref)
            try:
                record = ray.get(ref)
            except ray.exceptions.RayActorError as exc:
                if getattr(exc, "actor_init_failed", False):
                    # Not the run's fault: no actor can start (unimportable payload, ...).
                    raise RuntimeError(f"Monte-Carlo Ray actors fail to start: {exc}") from None
                record = factory.died(spec, f"Ray actor died: {str(exc).splitlines()[0]}")
                ray.kill(actor)
                actors.discard(actor)
                actor = Actor.remote(factory, payload_ref)
                actors.add(actor)
            yield record
            if queue:
                spec = queue.popleft()
                in_flight[actor.execute.remote(spec)] = (actor, spec)
    finally:
        for actor in actors:
            ray.kill(actor)
        if started:
            ray.shutdown()
