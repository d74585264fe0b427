"""Kernels without numba until they run; numba's cache never runs stale code; a cold run says so once."""

from __future__ import annotations

import importlib
import json
import os
import pkgutil
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from jit import compiled

ROOT = Path(__file__).resolve().parents[2]

CALLEE = "from jit import compiled\n\n\n@compiled.njit(cache=True)\ndef f(x):\n    return x + {add}\n"
CALLER = textwrap.dedent("""\
    import callee
    from jit import compiled


    @compiled.njit(cache=True)
    def g(x):
        return 2.0 * callee.f(x)
    """)


def _plain(caller: str) -> str:
    """Return the same kernel under ``numba.njit``, which numba keys on its own file only."""
    # the callee's kernels become numba functions first, as numba.njit needs its callees to be
    return "import numba\n" + caller.replace("@compiled.njit", "@numba.njit") + "\n\ncompiled.jit()\n"


def _run(tmp: Path, *modules: str, **env: str) -> list[float]:
    """``module.g(1.0)`` of each module, in one new process (each caller has its own cache)."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp), str(ROOT)]), **env}
    code = "".join(f"import {m}; print({m}.g(1.0))\n" for m in modules)
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp, env=env, capture_output=True, text=True, timeout=120,
                         check=True)
    return [float(v) for v in out.stdout.split()]


def test_an_edit_of_an_inlined_kernel_reaches_the_cached_caller(tmp_path):
    (tmp_path / "callee.py").write_text(CALLEE.format(add=1.0))
    (tmp_path / "fresh.py").write_text(CALLER + "\n\ncompiled.keep_fresh(__name__)\n")
    (tmp_path / "stale.py").write_text(_plain(CALLER))  # negative control: numba's own cache key only
    assert _run(tmp_path, "fresh", "stale") == [4.0, 4.0]
    cached = sorted(tmp_path.glob("__pycache__/fresh.g-*"))
    assert [p.suffix for p in cached] == [".nbc", ".nbi"], cached  # numba's place, one entry
    (tmp_path / "callee.py").write_text(CALLEE.format(add=2.0))
    # numba.njit alone runs the caller's stale code: the edit does not reach it
    assert _run(tmp_path, "fresh", "stale") == [6.0, 4.0]
    # the new code replaced the old entry in place (nothing piles up) ...
    assert sorted(tmp_path.glob("__pycache__/fresh.g-*")) == cached
    # ... and an unchanged tree keeps its cache (no recompile: the stamp matches)
    before = {p: p.stat().st_mtime_ns for p in cached}
    assert _run(tmp_path, "fresh") == [6.0]
    assert {p: p.stat().st_mtime_ns for p in cached} == before


def test_a_numba_njit_function_that_inlines_other_files_is_refused(tmp_path):
    """keep_fresh refuses what it cannot key: a ``numba.njit`` caller of another file's kernel.

    Negative controls: the same caller under ``jit.compiled.njit``, and a ``numba.njit`` function
    that inlines nothing, pass.
    """
    (tmp_path / "callee.py").write_text(CALLEE.format(add=1.0))
    (tmp_path / "plain.py").write_text(_plain(CALLER) + "\ncompiled.keep_fresh(__name__)\n")
    (tmp_path / "ours.py").write_text(CALLER + "\n\ncompiled.keep_fresh(__name__)\n")
    (tmp_path / "alone.py").write_text("import numba\nfrom jit import compiled\n\n\n@numba.njit(cache=True)\n"
                                       "def g(x):\n    return x\n\n\ncompiled.keep_fresh(__name__)\n")
    refused = _python("import plain", tmp_path)
    assert refused.returncode == 1
    assert refused.stderr.splitlines()[-1] == (
        "TypeError: plain.g is a numba.njit function that inlines callee.py; numba keys its cache on its own "
        "file only: define it with jit.compiled.njit"), refused.stderr
    assert _run(tmp_path, "ours", "alone") == [4.0, 1.0]


#: where numba puts the cache: beside the source; NUMBA_CACHE_DIR; the per-user folder (a read-only tree)
WHERE = {"in-tree": {}, "NUMBA_CACHE_DIR": {"NUMBA_CACHE_DIR": "cache"},
         "user-wide": {"XDG_CACHE_HOME": "xdg", "NUMBA_CACHE_LOCATOR_CLASSES": "UserWideCacheLocator"}}


def _edit_reaches_fresh_only(tmp: Path, caller: str, other: str, before: str, after: str,
                             values: tuple[float, float], where: str = "in-tree") -> None:
    """Check that an edit of file ``other`` (``before`` -> ``after``) reaches ``fresh`` only.

    ``fresh`` is the kernel of ``jit.compiled.njit``; ``stale``, the same under ``numba.njit`` (the
    negative control), keeps running its cached code. ``where``: one of :data:`WHERE`.
    """
    env = {k: str(tmp / v) if k.endswith(("_DIR", "_HOME")) else v for k, v in WHERE[where].items()}
    (tmp / other).write_text(before)
    (tmp / "fresh.py").write_text(caller + "\n\ncompiled.keep_fresh(__name__)\n")
    (tmp / "stale.py").write_text(_plain(caller))
    assert _run(tmp, "fresh", "stale", **env) == [values[0], values[0]]
    (tmp / other).write_text(after)
    assert _run(tmp, "fresh", "stale", **env) == [values[1], values[0]]
    # the cache stays where numba puts it (only numba.njit's stale.g would be there otherwise)
    roots = {p.relative_to(tmp).parts[0] for p in tmp.rglob("fresh.g-*.nbi")}
    assert roots == {next(iter(WHERE[where].values()), "__pycache__")}, roots


@pytest.mark.parametrize("where", list(WHERE))
def test_kernels_of_compiled_njit_are_kept_fresh_when_they_become_dispatchers(tmp_path, where):
    _edit_reaches_fresh_only(tmp_path, CALLER, "callee.py", CALLEE.format(add=1.0), CALLEE.format(add=2.0),
                             (4.0, 6.0), where)


def _our_modules():
    for pkg in ("estimators", "planner", "sim"):
        base = importlib.import_module(pkg)
        for info in pkgutil.walk_packages(base.__path__, prefix=pkg + "."):
            if "recording" in info.name or info.name.startswith("cli"):
                continue
            yield info.name


def test_every_cached_kernel_of_ours_is_keyed_on_the_files_it_inlines():
    from jit import locators

    compiled.jit()  # every kernel a numba dispatcher, whichever tests ran before
    for name in _our_modules():
        importlib.import_module(name)
        compiled.keep_fresh(name)  # no numba.njit function that inlines other files
    inlining = [k for k in compiled._kernels if k.options.get("cache") and compiled.inlined_sources(k)]
    assert len(inlining) > 20  # the PEF's, the estimators', the control tick's
    assert [k.key for k in inlining if k.py_func not in locators.inlined] == []


CONSTANTS = "LIMIT = {value}\n"
CONSTANT_READER = textwrap.dedent("""\
    import constants
    from constants import LIMIT
    from jit import compiled


    @compiled.njit(cache=True)
    def g(x):
        return x + LIMIT + constants.LIMIT
    """)


def test_an_edit_of_a_constant_the_kernel_imports_reaches_its_cached_code(tmp_path):
    # numba freezes a global's value into the compiled code, and keys its cache on the kernel's file only
    _edit_reaches_fresh_only(tmp_path, CONSTANT_READER, "constants.py", CONSTANTS.format(value=1.0),
                             CONSTANTS.format(value=2.0), (3.0, 5.0))


def test_the_freshness_key_covers_a_constant_imported_from_another_file():
    from estimators import lsq

    compiled.jit()
    assert ROOT / "estimators" / "measurements.py" in compiled.inlined_sources(lsq._gauss_newton_ranges)


LAZY = textwrap.dedent("""\
    import numpy as np
    from jit import compiled

    @compiled.njit(cache=False)
    def inner(x):
        return x + 1.0

    @compiled.njit(cache=False)
    def outer(a):
        s = 0.0
        for v in a:
            s += inner(v)
        return s
    """)


def _python(code: str, cwd: Path, **env) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(cwd), str(ROOT)]), **env}
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=300)


def test_a_kernel_imports_numba_only_when_it_runs(tmp_path):
    (tmp_path / "lazy_kernels.py").write_text(LAZY)
    out = _python("""
        import sys
        import lazy_kernels as m
        print("numba" in sys.modules, type(m.outer).__name__)
        print(m.outer(__import__("numpy").arange(3.0)))
        print("numba" in sys.modules, type(m.outer).__name__, type(m.inner).__name__)
        """, tmp_path)
    assert out.returncode == 0, out.stderr
    before, value, after = out.stdout.split("\n")[:3]
    assert before == "False Kernel"
    assert float(value) == 6.0  # 1 + 2 + 3: outer compiled with inner as a numba function
    # the module's names are numba's dispatchers now: a kernel compiled later finds them as such
    assert after == "True CPUDispatcher CPUDispatcher"


def test_a_kernel_pickles_by_name():
    import pickle

    from planner.schedule import drift

    assert pickle.loads(pickle.dumps(drift._drift_kernel)) is drift._drift_kernel


ANNOUNCING = textwrap.dedent("""\
    import json, sys
    from jit import compiled

    @compiled.njit(cache={cache})
    def twice(x):
        return 2.0 * x

    compiled.announce_compiles(7)
    compiled.announce_compiles()  # a second call adds nothing
    print("before the first call", file=sys.stderr, flush=True)
    first = twice(21.0)
    print("after the first call", file=sys.stderr, flush=True)
    json.dump({{"twice": first, "again": twice(4.0)}}, sys.stdout)
    """)


@pytest.mark.parametrize("cache", [True, False])
def test_a_cold_run_says_once_that_it_compiled_and_a_warm_run_says_nothing(tmp_path, cache):
    numba_cache = tmp_path / "numba-cache"
    (tmp_path / "announcing.py").write_text(ANNOUNCING.format(cache=cache))
    runs = [_python("import announcing", tmp_path, NUMBA_CACHE_DIR=str(numba_cache)) for _ in range(2)]
    for run in runs:
        assert run.returncode == 0, run.stderr
        assert json.loads(run.stdout) == {"twice": 42.0, "again": 8.0}  # stdout stays the program's own (--json)
    cold, warm = (r.stderr.splitlines() for r in runs)
    quiet = ["before the first call", "after the first call"]
    if cache:
        # said as the compilation starts (before the silence), with the estimate; then what it took
        assert cold[:3] == ["before the first call",
                            "pefsim: compiling the kernels once, about 7 s; numba caches them for later runs",
                            "after the first call"], cold
        assert len(cold) == 4 and re.fullmatch(
            r"pefsim: compiled the kernels once \(\d+ s\); later runs use numba's cache", cold[3]), cold
        assert warm == quiet  # loaded from numba's cache: nothing to say
    else:
        # negative control: a kernel numba does not cache compiles on every run, and promising a
        # cache there would be false
        assert cold == warm == quiet


WORKER_KERNELS = textwrap.dedent("""\
    import sys
    from jit import compiled

    @compiled.njit(cache=True)
    def once(x):
        return 1.0 * x

    @compiled.njit(cache=True)
    def thrice(x):
        return 3.0 * x

    def work(state):
        compiled.announce_in_worker(state)
        print("worker", thrice(2.0), file=sys.stderr, flush=True)  # a kernel the parent never called
    """)

WORKER_MAIN = textwrap.dedent("""\
    import multiprocessing
    from jit import compiled
    import worker_kernels as k

    compiled.announce_compiles(9)
    if {parent_first}:
        k.once(1.0)  # the parent compiles (and says so) first
    p = multiprocessing.get_context("spawn").Process(target=k.work, args=(compiled.announce_state(),))
    p.start()
    p.join()
    """)


@pytest.mark.parametrize("parent_first", [False, True])
def test_a_worker_says_it_compiles_unless_its_parent_did(tmp_path, parent_first):
    """A pool worker on a cold cache says the first line itself (a cold ``validate --workers 2``).

    Negative control: where the parent said it already (it compiled first, its estimate covers
    the command), the worker compiles its own kernel in silence.
    """
    (tmp_path / "worker_kernels.py").write_text(WORKER_KERNELS)
    run = _python(WORKER_MAIN.format(parent_first=parent_first), tmp_path, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    assert run.returncode == 0, run.stderr
    lines = run.stderr.splitlines()
    worker = "pefsim: a worker is compiling the kernels once, about 9 s; numba caches them for later runs"
    parent = "pefsim: compiling the kernels once, about 9 s; numba caches them for later runs"
    assert "worker 6.0" in lines, lines
    if parent_first:
        assert lines[0] == parent and worker not in lines, lines
    else:
        assert lines.index(worker) < lines.index("worker 6.0") and parent not in lines, lines
