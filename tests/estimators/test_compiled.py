"""numba's cache never runs stale code after an inlined kernel's file is edited."""

from __future__ import annotations

import importlib
import os
import pkgutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from numba.core.registry import CPUDispatcher

from estimators import compiled

ROOT = Path(__file__).resolve().parents[2]

CALLEE = "import numba\n\n\n@numba.njit(cache=True)\ndef f(x):\n    return x + {add}\n"
CALLER = textwrap.dedent("""\
    import numba

    import callee
    from estimators import compiled


    @numba.njit(cache=True)
    def g(x):
        return 2.0 * callee.f(x)
    """)


def _run(tmp: Path, module: str) -> float:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp), str(ROOT)])}
    out = subprocess.run([sys.executable, "-c", f"import {module}; print({module}.g(1.0))"], cwd=tmp, env=env,
                         capture_output=True, text=True, timeout=120, check=True)
    return float(out.stdout.strip())


@pytest.fixture
def kernels(tmp_path):
    (tmp_path / "callee.py").write_text(CALLEE.format(add=1.0))
    (tmp_path / "fresh.py").write_text(CALLER + "\n\ncompiled.keep_fresh(__name__)\n")
    (tmp_path / "stale.py").write_text(CALLER)  # negative control: numba's own cache key only
    return tmp_path


def test_an_edit_of_an_inlined_kernel_reaches_the_cached_caller(kernels):
    assert _run(kernels, "fresh") == 4.0
    assert _run(kernels, "stale") == 4.0
    assert list(kernels.glob("__pycache__/fresh.g-*.nbi")), "the caller was not cached"
    (kernels / "callee.py").write_text(CALLEE.format(add=2.0))
    assert _run(kernels, "fresh") == 6.0
    # without keep_fresh numba runs the caller's stale code: the edit does not reach it
    assert _run(kernels, "stale") == 4.0
    # and an unchanged tree keeps its cache (no recompile: the stamp matches)
    before = {p: p.stat().st_mtime_ns for p in kernels.glob("__pycache__/fresh.g-*")}
    assert _run(kernels, "fresh") == 6.0
    assert {p: p.stat().st_mtime_ns for p in kernels.glob("__pycache__/fresh.g-*")} == before


LAZY_CALLEE = "from estimators import compiled\n\n\n@compiled.njit(cache=True)\ndef f(x):\n    return x + {add}\n"
LAZY_CALLER = CALLER.replace("import numba\n\n", "").replace("@numba.njit", "@compiled.njit")


def _edit_reaches_fresh_only(tmp: Path, caller: str, other: str, before: str, after: str,
                             values: tuple[float, float]) -> None:
    """Check that an edit of file ``other`` (``before`` -> ``after``) reaches ``fresh`` only.

    ``fresh`` is the caller with keep_fresh; ``stale``, the caller alone (the negative control),
    keeps running its cached code.
    """
    (tmp / other).write_text(before)
    (tmp / "fresh.py").write_text(caller + "\n\ncompiled.keep_fresh(__name__)\n")
    (tmp / "stale.py").write_text(caller)
    assert _run(tmp, "fresh") == values[0]
    assert _run(tmp, "stale") == values[0]
    (tmp / other).write_text(after)
    assert _run(tmp, "fresh") == values[1]
    assert _run(tmp, "stale") == values[0]


def test_kernels_of_compiled_njit_are_kept_fresh_when_they_become_dispatchers(tmp_path):
    _edit_reaches_fresh_only(tmp_path, LAZY_CALLER, "callee.py", LAZY_CALLEE.format(add=1.0),
                             LAZY_CALLEE.format(add=2.0), (4.0, 6.0))


def _our_modules():
    for pkg in ("estimators", "planner", "sim"):
        base = importlib.import_module(pkg)
        for info in pkgutil.walk_packages(base.__path__, prefix=pkg + "."):
            if "recording" in info.name or info.name.startswith("sim.cli"):
                continue
            yield info.name


def test_every_module_whose_cached_kernels_inline_others_keeps_them_fresh():
    compiled.jit()  # every kernel a numba dispatcher, whichever tests ran before
    missing = []
    for name in _our_modules():
        mod = importlib.import_module(name)
        inlining = [o for o in vars(mod).values() if isinstance(o, CPUDispatcher) and o.__module__ == name
                    and getattr(o, "_cache", None) is not None and hasattr(o._cache, "cache_path")
                    and compiled.inlined_sources(o)]
        if inlining and "compiled.keep_fresh(__name__)" not in Path(mod.__file__).read_text():
            missing.append(name)
    assert missing == []


CONSTANTS = "LIMIT = {value}\n"
CONSTANT_READER = textwrap.dedent("""\
    import constants
    from constants import LIMIT
    from estimators import compiled


    @compiled.njit(cache=True)
    def g(x):
        return x + LIMIT + constants.LIMIT
    """)


def test_an_edit_of_a_constant_the_kernel_imports_reaches_its_cached_code(tmp_path):
    # numba freezes a global's value into the compiled code, and keys its cache on the kernel's file only
    _edit_reaches_fresh_only(tmp_path, CONSTANT_READER, "constants.py", CONSTANTS.format(value=1.0),
                             CONSTANTS.format(value=2.0), (3.0, 5.0))


def test_the_ahead_of_time_digest_covers_a_constant_imported_from_another_file():
    from estimators import lsq

    compiled.jit()
    assert ROOT / "estimators" / "measurements.py" in compiled.inlined_sources(lsq._gauss_newton_ranges)
