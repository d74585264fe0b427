"""Run a ``nogil`` numba kernel over index ranges on several threads.

The PEF and visibility kernels are plain ``@compiled.njit(nogil=True, cache=True)`` functions of an
index range; Python threads run the ranges in parallel. This replaces ``parallel=True``/``prange``,
whose compilation (the parfor passes and a second optimisation of every callee) cost tens of
seconds per fresh cache, for the same speed on our loops.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from jit import compiled

_threads: int | None = None
_pool: ThreadPoolExecutor | None = None  # shared by every call: a plan makes hundreds of calls
_pool_size = 0


def _forget_pool() -> None:
    # a forked child has the pool object but none of its threads: it makes its own
    global _pool, _pool_size
    _pool, _pool_size = None, 0


os.register_at_fork(after_in_child=_forget_pool)


def _executor(threads: int) -> ThreadPoolExecutor:
    global _pool, _pool_size
    if _pool is None or _pool_size != threads:
        if _pool is not None:
            _pool.shutdown(wait=False)
        _pool, _pool_size = ThreadPoolExecutor(max_workers=threads, thread_name_prefix="pef-kernel"), threads
    return _pool


def set_threads(n: int | None) -> None:
    """Limit the threads of every kernel call in this process (None: back to the default).

    Process-parallel sweeps call this with 1 in each worker: the workers already fill the
    cores, and kernel threads on top would only contend with them.
    """
    global _threads
    _threads = None if n is None else max(1, int(n))


def default_threads() -> int:
    """Threads of a kernel call: ``NUMBA_NUM_THREADS`` if set, else the cores this process may use.

    numba's own default, read without importing numba (0.5 s, which a command whose kernels are
    built ahead of time does not pay).
    """
    try:
        return max(1, int(os.environ["NUMBA_NUM_THREADS"]))
    except (KeyError, ValueError):
        return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


def run_ranges(kernel: Callable, n: int, args: tuple, min_chunk: int = 1) -> None:
    """Call ``kernel(lo, hi, *args)`` for ranges covering ``[0, n)``, in parallel.

    Parameters
    ----------
    kernel : callable
        A numba function compiled with ``nogil=True`` that handles indices ``lo <= i < hi`` and
        writes its results into arrays among ``args`` (disjoint per range).
    n : int
        Number of indices.
    args : tuple
        Further arguments of ``kernel``.
    min_chunk : int
        Smallest range worth a thread; below ``2 * min_chunk`` indices the call runs inline.

    Notes
    -----
    Uses :func:`default_threads` threads (numba's own thread pool is never started: ~0.1 s),
    with four ranges per thread so that uneven ranges (e.g. cells inside obstacles) balance out.
    The threads are kept between calls (one pool per process). Not reentrant from the kernel
    threads themselves (no kernel calls back into Python).
    """
    kernel = kernel.resolve() if isinstance(kernel, compiled.Kernel) else kernel  # once, not in each thread
    threads = _threads if _threads is not None else default_threads()
    if n <= 0:
        return
    if threads == 1 or n < 2 * min_chunk:
        kernel(0, n, *args)
        return
    parts = max(2, min(4 * threads, math.ceil(n / min_chunk)))
    bounds = np.linspace(0, n, parts + 1).astype(np.int64)
    pool = _executor(threads)
    futures = [pool.submit(kernel, int(lo), int(hi), *args)
               for lo, hi in zip(bounds[:-1], bounds[1:], strict=True) if hi > lo]
    for f in futures:
        f.result()  # re-raises a kernel's exception
