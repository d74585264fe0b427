"""Safe sweep directories: damaged parts redone on resume, one writer at a time, steps modes.

The harness runs ``tests.sim.montecarlo.fake_episode`` (its results depend only on the seed);
the CLI tests run ``pefsim`` in a subprocess with that episode patched in, so that their
stderr is the real one (warnings and refusals one line each, never a traceback).
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

import scenarios
from scenarios.errors import OutputError, SimulationError
from sim.montecarlo import lock, results
from sim.montecarlo.engine import sweep
from sim.montecarlo.results import SweepLayout
from sim.montecarlo.rows import (
    FIX_SCHEMA,
    RUN_SCHEMA,
    STEP_SCHEMA,
    TIMING_COLUMNS,
    _table,
    fix_columns,
    run_row,
    step_columns,
)
from tests.sim.montecarlo import fake_episode as fe
from validation import suite as validation

REPO = Path(__file__).resolve().parents[3]
RUNS = 6

# pefsim's CLI with the fake episode: argv after the script name; exit code as pefsim's.
CLI_DRIVER = """
import sys
from sim.montecarlo import engine
from tests.sim.montecarlo import fake_episode as fe
engine.default_api = lambda: fe.SLOW
from cli import main
sys.exit(main(sys.argv[1:]))
"""


@pytest.fixture(scope="module")
def scenario():
    return scenarios.load("paper-docks")


@pytest.fixture(scope="module")
def clean(tmp_path_factory, scenario):
    out = tmp_path_factory.mktemp("clean") / "mc"
    sweep(scenario, out, runs=RUNS, workers=1, api=fe.API, progress=False)
    return out


def _tables(root):
    return (results.read_runs(root).drop(list(TIMING_COLUMNS)), results.read_steps(root),
            results.read_fixes(root))


def _assert_same(a, b):
    for ta, tb, name in zip(_tables(a), _tables(b), ("runs", "steps", "fixes"), strict=True):
        assert ta.num_rows == tb.num_rows > 0, name
        for col in ta.column_names:
            assert ta.column(col).equals(tb.column(col)), f"{name}.{col} differs"


def _cli(tmp_path, *argv, sleep="0.0"):
    driver = tmp_path / "cli_driver.py"
    driver.write_text(textwrap.dedent(CLI_DRIVER))
    env = dict(os.environ, PYTHONPATH=str(REPO), FAKE_EPISODE_SLEEP=sleep)
    return subprocess.run([sys.executable, str(driver), *map(str, argv)], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=300)


def _damage(layout: SweepLayout) -> dict[int, Path]:
    """Damage four parts of a sweep of at least 6 runs; returns the damaged part of each run.

    Truncates run 1's steps part, empties run 3's fixes part, garbles run 4's runs part, and
    flips one byte in the middle of run 5's steps part (its footer intact: only the page
    checksum tells).
    """
    steps, fixes, runs, flipped = (layout.part(layout.steps_dir, 1), layout.part(layout.fixes_dir, 3),
                                   layout.part(layout.runs_dir, 4), layout.part(layout.steps_dir, 5))
    data = steps.read_bytes()
    steps.write_bytes(data[: len(data) // 2])
    fixes.write_bytes(b"")
    runs.write_bytes(bytes(np.random.default_rng(0).integers(0, 256, runs.stat().st_size, dtype=np.uint8)))
    data = bytearray(flipped.read_bytes())
    data[len(data) // 4] ^= 0xFF  # inside the first columns' pages, far from the footer
    flipped.write_bytes(bytes(data))
    return {1: steps, 3: fixes, 4: runs, 5: flipped}


def test_damaged_parts_are_moved_aside_and_exactly_their_runs_redone(tmp_path, scenario, clean):
    out = tmp_path / "mc"
    sweep(scenario, out, runs=RUNS, workers=1, api=fe.API, progress=False)
    layout = SweepLayout(out)
    damaged = _damage(layout)
    intact = {p: p.stat().st_mtime_ns for d in (layout.runs_dir, layout.steps_dir, layout.fixes_dir)
              for p in d.glob("run-*") if int(p.name[4:10]) not in damaged}
    with pytest.raises(OutputError, match=r"steps/run-000001\.parquet: does not read back"):
        results.read_steps(out)  # readers name the file instead of a pyarrow traceback
    warnings = []
    summary = sweep(scenario, out, workers=1, api=fe.API, resume=True, progress=False, on_warning=warnings.append)
    assert summary.executed == len(damaged) and summary.runs == RUNS
    assert len(warnings) == len(damaged)
    for run, path in damaged.items():
        line = next(w for w in warnings if str(path) in w)
        assert f"run {run} is redone" in line and "\n" not in line
        assert (layout.damaged_dir / f"{path.parent.name}-{path.name}").exists()
    for p, mtime in intact.items():
        assert p.stat().st_mtime_ns == mtime, f"{p} was rewritten, its run was not damaged"
    _assert_same(clean, out)  # same seeds, same numbers


def test_a_missing_part_of_a_finished_run_is_redone(tmp_path, scenario, clean):
    out = tmp_path / "mc"
    sweep(scenario, out, runs=RUNS, workers=1, api=fe.API, progress=False)
    layout = SweepLayout(out)
    layout.part(layout.fixes_dir, 2).unlink()
    warnings = []
    summary = sweep(scenario, out, workers=1, api=fe.API, resume=True, progress=False, on_warning=warnings.append)
    assert summary.executed == 1 and len(warnings) == 1 and "missing for finished run 2" in warnings[0]
    _assert_same(clean, out)


def test_cli_resume_of_a_damaged_sweep_warns_in_one_line_per_file(tmp_path, clean):
    out = tmp_path / "mc"
    first = _cli(tmp_path, "mc", "paper-docks", "--runs", RUNS, "--workers", 1, "--out", out, "--no-report")
    assert first.returncode == 0, first.stderr
    sizes = json.loads(SweepLayout(out).sweep_json.read_text())["bytes_per_run"]
    assert f"bytes per run: {sizes['total'] / 1e3:.1f} kB (steps {sizes['steps'] / 1e3:.1f} kB" in first.stdout
    damaged = _damage(SweepLayout(out))

    bad = _cli(tmp_path, "validate", "--from", out)
    assert bad.returncode == 2 and "Traceback" not in bad.stderr
    assert len(bad.stderr.strip().splitlines()) == 1 and "does not read back" in bad.stderr
    assert any(str(p) in bad.stderr for p in damaged.values())

    again = _cli(tmp_path, "mc", "paper-docks", "--workers", 1, "--out", out, "--resume", "--no-report", "--json")
    assert again.returncode == 0 and "Traceback" not in again.stderr
    lines = again.stderr.strip().splitlines()
    assert len(lines) == len(damaged)
    assert all(line.startswith("pefsim: warning: ") for line in lines)
    assert sorted(int(Path(line.split(": ")[2]).name[4:10]) for line in lines) == sorted(damaged)
    summary = json.loads(again.stdout)
    assert summary["executed"] == len(damaged) and summary["steps"] == "all"
    assert summary["bytes_per_run"]["total"] == sum(summary["bytes_per_run"][k] for k in ("runs", "steps", "fixes"))
    _assert_same(clean, out)


def _write_lock(root: Path, pid: int, host: str | None = None) -> None:
    root.mkdir(parents=True, exist_ok=True)
    holder = {"pid": pid, "host": host or socket.gethostname(), "since": "2026-12-01T23:40Z"}
    (root / lock.LOCK_NAME).write_text(json.dumps(holder))


def test_a_live_holder_refuses_a_second_writer(tmp_path, scenario):
    out = tmp_path / "mc"
    _write_lock(out, os.getpid())  # this very process: certainly alive, on this host
    want = f"{out} is being written by pid {os.getpid()} on host {socket.gethostname()} since 2026-12-01T23:40Z"
    with pytest.raises(OutputError) as info:
        sweep(scenario, out, runs=2, workers=1, api=fe.API, progress=False)
    assert str(info.value) == want
    proc = _cli(tmp_path, "mc", "paper-docks", "--runs", 2, "--out", out, "--resume", "--no-report")
    assert proc.returncode == 2 and proc.stderr == f"pefsim: error: {want}\n"
    assert (out / lock.LOCK_NAME).exists() and not (out / "runs").exists()  # the holder's lock is untouched


def test_a_lock_of_another_host_is_never_taken_over(tmp_path, scenario):
    out = tmp_path / "mc"
    _write_lock(out, 1, host="elsewhere.example")
    with pytest.raises(OutputError, match=r"pid 1 on host elsewhere\.example .*if that process is gone, delete"):
        sweep(scenario, out, runs=2, workers=1, api=fe.API, progress=False)


def test_a_running_sweep_holds_its_directory(tmp_path, scenario):
    out = tmp_path / "mc"
    driver = tmp_path / "cli_driver.py"
    driver.write_text(textwrap.dedent(CLI_DRIVER))
    env = dict(os.environ, PYTHONPATH=str(REPO), FAKE_EPISODE_SLEEP="0.3")
    proc = subprocess.Popen([sys.executable, str(driver), "mc", "paper-docks", "--runs", "12", "--workers", "1",
                             "--out", str(out), "--no-report"], cwd=tmp_path, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while not results.finished_runs(SweepLayout(out)):
            assert proc.poll() is None, proc.stderr.read()
            assert time.monotonic() < deadline, "the first sweep wrote no run in 120 s"
            time.sleep(0.05)
        with pytest.raises(OutputError, match=rf"is being written by pid {proc.pid} on host "):
            sweep(scenario, out, workers=1, api=fe.API, resume=True, progress=False)
        assert proc.wait(timeout=120) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        err = proc.stderr.read()
        proc.stderr.close()
    assert "Traceback" not in err
    assert not (out / lock.LOCK_NAME).exists()  # released at the end
    assert len(results.finished_runs(SweepLayout(out))) == 12


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_a_stale_lock_is_taken_over_with_a_warning(tmp_path, scenario, clean):
    out = tmp_path / "mc"
    pid = _dead_pid()
    _write_lock(out, pid)
    warnings = []
    summary = sweep(scenario, out, runs=RUNS, workers=1, api=fe.API, progress=False, on_warning=warnings.append)
    assert summary.executed == RUNS
    assert len(warnings) == 1 and f"took over the lock of pid {pid}" in warnings[0] and "not running" in warnings[0]
    assert not (out / lock.LOCK_NAME).exists()
    _assert_same(clean, out)


def test_a_reused_pid_does_not_keep_a_lock(tmp_path, scenario):
    out = tmp_path / "mc"
    _write_lock(out, os.getpid())
    holder = json.loads((out / lock.LOCK_NAME).read_text())
    holder["pid_start"] = -1  # this pid is alive, but started at another time than the holder
    (out / lock.LOCK_NAME).write_text(json.dumps(holder))
    warnings = []
    sweep(scenario, out, runs=2, workers=1, api=fe.API, progress=False, on_warning=warnings.append)
    assert len(warnings) == 1 and "took over" in warnings[0]


def test_the_lock_goes_on_errors_and_ctrl_c(tmp_path, scenario, monkeypatch):
    out = tmp_path / "fatal"
    with pytest.raises(SimulationError):
        sweep(scenario, out, runs=5, workers=1, api=fe.FATAL, progress=False)
    assert not (out / lock.LOCK_NAME).exists()

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    out = tmp_path / "ctrl-c"
    api = fe.EpisodeApi(fe.prepare, interrupted, fe.FakeWorld)
    with pytest.raises(KeyboardInterrupt):
        sweep(scenario, out, runs=3, workers=1, api=api, progress=False)
    assert not (out / lock.LOCK_NAME).exists()
    assert lock._held == {}


# -- steps modes -----------------------------------------------------------------------------

def test_steps_fixes_keeps_the_step_at_or_after_each_fix(tmp_path, scenario, clean):
    out = tmp_path / "fixes"
    summary = sweep(scenario, out, runs=RUNS, workers=1, api=fe.API, progress=False, steps="fixes")
    assert summary.steps == "fixes"
    assert json.loads(SweepLayout(out).sweep_json.read_text())["steps"] == "fixes"
    kept, every = results.read_steps(out), results.read_steps(clean)
    for run in range(RUNS):
        # The episode's own float64 times (the stored ones are float32) decide "at or after".
        again = fe.run_episode(scenario, 0, np.random.SeedSequence(scenario.seed, spawn_key=(run,)))
        t = again.steps.t
        want = sorted({int(np.argmax(t >= x)) for x in again.fixes.t if np.any(t >= x)})
        got = kept.filter(kept["run"].to_numpy() == run)
        assert got["step"].to_pylist() == want and len(want) > 1
        assert got["nees"].to_pylist() == every.filter(every["run"].to_numpy() == run)["nees"].take(want).to_pylist()
    assert 0 < summary.bytes_per_run["steps"] < SweepLayout(clean).part(SweepLayout(clean).steps_dir, 0).stat().st_size


def test_steps_none_writes_no_step_parts_and_resume_keeps_the_mode(tmp_path, scenario):
    out = tmp_path / "none"
    sweep(scenario, out, runs=3, workers=1, api=fe.API, progress=False, steps="none")
    layout = SweepLayout(out)
    assert not list(layout.steps_dir.iterdir())
    with pytest.raises(OutputError, match="was made with steps none, not all"):
        sweep(scenario, out, runs=5, workers=1, api=fe.API, resume=True, progress=False, steps="all")
    summary = sweep(scenario, out, runs=5, workers=1, api=fe.API, resume=True, progress=False)
    assert summary.executed == 2 and summary.steps == "none" and not list(layout.steps_dir.iterdir())
    settings = json.loads(layout.sweep_json.read_text())
    assert settings["steps"] == "none" and settings["bytes_per_run"]["steps"] == 0
    assert settings["bytes_per_run"]["total"] == settings["bytes_per_run"]["runs"] + settings["bytes_per_run"]["fixes"]


def test_validation_of_a_lean_sweep_says_what_it_cannot_check(tmp_path, scenario, clean):
    full = validation.validate(validation.load_sweep(clean))
    for mode in ("fixes", "none"):
        out = tmp_path / mode
        sweep(scenario, out, runs=RUNS, workers=1, api=fe.API, progress=False, steps=mode)
        lean = validation.validate(validation.load_sweep(out))
        nrun = lean.check("nees_nrun")
        assert nrun.status is validation.CheckStatus.NOT_APPLICABLE
        assert f"not available on a sweep written with --steps {mode}" in nrun.detail
        for c in full.checks:  # every other check sees the same numbers
            if c.name != "nees_nrun":
                assert lean.check(c.name).statistic == c.statistic, c.name


def test_bad_steps_value_is_one_line(tmp_path, scenario):
    from scenarios.errors import ScenarioError

    with pytest.raises(ScenarioError, match=r"steps: expected one of all, fixes, none, got 'some'"):
        sweep(scenario, tmp_path / "x", runs=1, workers=1, api=fe.API, progress=False, steps="some")
    assert not (tmp_path / "x").exists()


def test_the_report_of_a_lean_sweep_says_what_it_draws(tmp_path, scenario):
    from types import SimpleNamespace

    from scenarios.schema import PefModel
    from validation.report.page import write_report

    fake_map = SimpleNamespace(x=(np.arange(40) + 0.5) * 0.5, y=(np.arange(24) + 0.5) * 0.5,
                               tau=np.full((24, 40), 0.01), cell_size=(0.5, 0.5), model=PefModel.PARALLELOGRAM)
    for mode, figures in (("fixes", 4), ("none", 2)):
        out = tmp_path / mode
        sweep(scenario, out, runs=2, workers=1, api=fe.API, progress=False, steps=mode)
        html = write_report(out, scenario, pef_map=fake_map).read_text()
        assert len(list((out / "figures").iterdir())) == figures
        assert ("Only the steps at fix times are drawn" in html) == (mode == "fixes")
        assert ("kept no per-step rows" in html) == (mode == "none")


def test_a_directory_of_format_1_reads_exactly_and_resumes(tmp_path, scenario):
    """Parts written before the lean format (float64, pyarrow defaults) read back bit-exact, also mixed."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    out = tmp_path / "old"
    layout = SweepLayout(out)
    layout.make_dirs()
    layout.scenario_toml.write_text(scenario.text, encoding="utf-8")
    layout.sweep_json.write_text(json.dumps({"format": 1, "scenario": scenario.name, "task": None, "runs": 3}))
    episodes = {}
    for run in range(3):
        seed = np.random.SeedSequence(scenario.seed, spawn_key=(run,))
        episodes[run] = result = fe.run_episode(scenario, 0, seed)
        row = run_row(run, f"SeedSequence({scenario.seed}, spawn_key=({run},))", 0, result.summary, 0.1)
        for folder, table in ((layout.steps_dir, _table(step_columns(run, result.steps),
                                                                  STEP_SCHEMA)),
                              (layout.fixes_dir, _table(fix_columns(run, result.fixes),
                                                                  FIX_SCHEMA)),
                              (layout.runs_dir, pa.Table.from_pylist([row], schema=RUN_SCHEMA))):
            pq.write_table(table, layout.part(folder, run), compression="zstd")  # the format-1 writer
    summary = sweep(scenario, out, runs=5, workers=1, api=fe.API, resume=True, progress=False)
    assert summary.executed == 2 and summary.steps == "all"
    steps = results.read_steps(out)
    assert steps.schema == STEP_SCHEMA and set(steps["run"].to_pylist()) == set(range(5))
    for run, result in episodes.items():
        got = steps.filter(steps["run"].to_numpy() == run)["error"].to_numpy()
        np.testing.assert_array_equal(got, result.steps.error)  # float64 as written, not rounded
