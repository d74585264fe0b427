"""Kernels without numba until they run, and the ahead-of-time build (``pefsim compile``).

The build itself takes about 40 s, so these tests use the one ``pefsim compile`` made (the
README's and CI's test command run it first). Without a build the tests that need it are
skipped, except under CI (``CI`` set), where a missing build is a failure.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from estimators import aot, compiled

ROOT = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


def _python(code: str, cwd: Path = ROOT, **env) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], cwd=cwd, env={**ENV, **env},
                          capture_output=True, text=True, timeout=300)


def _built() -> dict:
    try:
        manifest = json.loads(aot.manifest_path().read_text())
    except OSError:
        manifest = {}
    fresh = manifest and all(aot.function(k, e["signature"]) is not None for k, e in manifest["kernels"].items())
    if not fresh:
        if os.environ.get("CI"):
            pytest.fail("no fresh ahead-of-time build: CI runs pefsim compile before the tests")
        pytest.skip("no fresh ahead-of-time build (run pefsim compile)")
    return manifest


LAZY = textwrap.dedent("""\
    import numpy as np
    from estimators import compiled

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


def test_a_kernel_imports_numba_only_when_it_runs(tmp_path):
    (tmp_path / "lazy_kernels.py").write_text(LAZY)
    out = _python("""
        import sys
        import lazy_kernels as m
        print("numba" in sys.modules, type(m.outer).__name__)
        print(m.outer(__import__("numpy").arange(3.0)))
        print("numba" in sys.modules, type(m.outer).__name__, type(m.inner).__name__)
        """, cwd=tmp_path, PYTHONPATH=os.pathsep.join([str(tmp_path), str(ROOT)]))
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


def test_the_build_is_used_only_for_the_sources_it_was_built_from(monkeypatch):
    manifest = _built()
    key, entry = next(iter(manifest["kernels"].items()))
    assert aot.function(key, entry["signature"]) is not None
    # another signature than the declared one: not this build's
    assert aot.function(key, entry["signature"].replace("float64", "float32", 1)) is None
    # an edit of any file the kernel's code comes from (its own, or an inlined callee's)
    for rel in entry["files"]:
        monkeypatch.setitem(aot._file_hashes, rel, "0" * 64)
        assert aot.function(key, entry["signature"]) is None, rel
        monkeypatch.undo()
    assert aot.function(key, entry["signature"]) is not None


@pytest.mark.parametrize("host, used", [(None, True), ("another-cpu", False)])
def test_a_build_made_on_another_cpu_is_not_used(host, used):
    """The build targets its host's instructions; on another CPU it is ignored, the JIT runs."""
    manifest = _built()
    key, entry = next(iter(manifest["kernels"].items()))
    out = _python(f"""
        from estimators import aot
        if {host!r} is not None:
            aot.host_fingerprint = lambda: {host!r}
        print(aot.function({key!r}, {entry["signature"]!r}) is not None)
        """)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == [str(used)]


def test_every_declared_kernel_is_in_the_build_with_its_declared_signature():
    manifest = _built()
    from sim.cli.compile import all_kernels

    declared = {k.key: k.aot for k in all_kernels() if k.aot is not None}
    assert declared == {k: e["signature"] for k, e in manifest["kernels"].items()}
    # each entry names its own file first, and the callees' files it inlines
    for key, e in manifest["kernels"].items():
        assert e["files"][0] == key.rsplit(".", 1)[0].replace(".", "/") + ".py"


def _drift_case():
    """Return the drift kernel (built) and arguments of its signature but the output array."""
    _built()
    from planner.schedule import drift  # noqa: F401 (defines the kernel)

    (kernel,) = [k for k in compiled.kernels() if k.key == "planner.schedule.drift._drift_kernel"]
    d, phi = np.array([0.0, 1.0, 2.0]), np.array([0.0, 0.3, 0.1])
    return kernel, d, phi, (0.5, 0.002, 0.01, 0.001, 3.0, 0.0, False, 0.05, 0.8)


def test_other_argument_types_than_the_signature_run_through_the_jit():
    kernel, d, phi, rest = _drift_case()
    right = np.zeros(3)
    kernel(d, phi, d ** 1.5, *rest, right)
    assert np.count_nonzero(right) == 2
    as_int = d.astype(np.int64)  # the same distances, as integers: another dtype than the signature's
    strided = np.repeat(d, 2)[::2]  # the same values, not contiguous
    for other in (as_int, strided):
        out = np.zeros(3)
        kernel(other, phi, d ** 1.5, *rest, out)
        np.testing.assert_allclose(out, right, rtol=1e-12)
    # negative control: the built code itself reads the integers' bits as float64
    misread = np.zeros(3)
    aot.function(kernel.key, kernel.aot)(as_int, phi, d ** 1.5, *rest, misread)
    assert not np.allclose(misread, right)


@pytest.mark.parametrize("command", [["map", "paper-docks", "--json"], ["plan", "warehouse", "--json"],
                                     ["plan", "warehouse-reflectors", "--json"]])
def test_map_and_plan_run_the_build_without_numba_and_print_what_the_jit_prints(command):
    _built()
    probe = f"""
        import sys, runpy
        sys.argv = ["pefsim", *{command!r}]
        from sim.cli import main
        code = main({command!r})
        print("NUMBA-IMPORTED" if "numba" in sys.modules else "NO-NUMBA", file=sys.stderr)
        sys.exit(code)
        """
    built, jit = _python(probe), _python(probe, PEFSIM_AOT="0")
    assert built.returncode == 0 and jit.returncode == 0, built.stderr + jit.stderr
    assert "NO-NUMBA" in built.stderr
    assert "NUMBA-IMPORTED" in jit.stderr  # negative control: without the build numba runs them
    assert built.stdout == jit.stdout


def test_pefsim_compile_check_tells_a_fresh_build_from_none():
    _built()
    check = [sys.executable, "-m", "sim.cli", "compile", "--check", "--json"]
    fresh = subprocess.run(check, cwd=ROOT, env=ENV, capture_output=True, text=True, timeout=120)
    assert fresh.returncode == 0, fresh.stderr
    report = json.loads(fresh.stdout)
    assert report["fresh"] and set(report["kernels"].values()) == {"built"} and len(report["kernels"]) >= 9
    # negative control: with the build ignored, every kernel is missing and --check exits 1
    ignored = subprocess.run(check, cwd=ROOT, env={**ENV, "PEFSIM_AOT": "0"}, capture_output=True, text=True,
                             timeout=120)
    assert ignored.returncode == 1 and not json.loads(ignored.stdout)["fresh"]
    assert set(json.loads(ignored.stdout)["kernels"].values()) == {"missing"}


def test_a_read_only_array_runs_through_the_jit_which_refuses_to_write_it():
    kernel, d, phi, rest = _drift_case()
    frozen = np.zeros(3)
    frozen.flags.writeable = False
    with pytest.raises(Exception, match="readonly|read-only|immutable"):
        kernel(d, phi, d ** 1.5, *rest, frozen)
    assert not frozen.any()
    # negative control: the built code itself writes into the read-only array
    aot.function(kernel.key, kernel.aot)(d, phi, d ** 1.5, *rest, frozen)
    assert np.count_nonzero(frozen) == 2


@compiled.njit(cache=False)
def _scaled(x, n):
    return x * n


def test_a_float_for_an_integer_argument_runs_through_the_jit():
    """The built code would truncate it (no kernel of ours takes an integer today: this guards the next)."""
    def built(x, n):
        return "built"

    (kernel,) = [k for k in compiled.kernels() if k.key == f"{__name__}._scaled"]  # jit() may have rebound the name
    call = compiled._checked(built, 2, (), (1,), kernel)
    assert call(2.0, 3) == "built"
    assert call(2.0, np.int64(3)) == "built"
    assert call(2.0, 3.5) == 7.0  # numba's dispatcher, compiled for a float
    # negative control: without the integer positions the built code gets the float
    assert compiled._checked(built, 2, (), (), kernel)(2.0, 3.5) == "built"
