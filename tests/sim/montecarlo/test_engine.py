"""Monte-Carlo harness: seeds, determinism across executors, crashes, interruption and resume.

These tests drive the harness with ``tests.sim.montecarlo.fake_episode`` (same interface as
``sim.episode.drive``, results depend only on the seed); one test at the end runs the real episode.
"""

from __future__ import annotations

import base64
import os
import re
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pyarrow.parquet as pq
import pytest

import scenarios
from scenarios.errors import OutputError, PlanningError, ScenarioError, SimulationError
from scenarios.schema import PefModel
from sim.montecarlo import engine as montecarlo
from sim.montecarlo import results
from sim.montecarlo.engine import sweep
from sim.montecarlo.results import SweepLayout
from sim.montecarlo.rows import TIMING_COLUMNS
from tests.sim.montecarlo import fake_episode as fe

REPO = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="module")
def two_tasks():
    """paper-docks with a second task (B -> A), so runs alternate between tasks."""
    base = scenarios.load("paper-docks")
    return scenarios.loads(base.text + '\n[[tasks]]\nfrom = "B"\nto = "A"\n', source="two-tasks.toml")


def _tables(root):
    runs = results.read_runs(root).drop(list(TIMING_COLUMNS))
    return runs, results.read_steps(root), results.read_fixes(root)


def _assert_same(a, b):
    for ta, tb, name in zip(_tables(a), _tables(b), ("runs", "steps", "fixes"), strict=True):
        assert ta.schema == tb.schema, name
        for col in ta.column_names:
            assert ta.column(col).equals(tb.column(col)), f"{name}.{col} differs"


@pytest.fixture(scope="module")
def serial_sweep(tmp_path_factory, two_tasks):
    out = tmp_path_factory.mktemp("serial") / "mc"
    summary = sweep(two_tasks, out, runs=12, workers=1, api=fe.API, progress=False)
    return out, summary


def test_runs_get_their_own_seed_and_task(serial_sweep, two_tasks):
    out, summary = serial_sweep
    runs = results.read_runs(out)
    assert runs.column("run").to_pylist() == list(range(12))
    assert runs.column("task").to_pylist() == [i % 2 for i in range(12)]
    assert runs.column("seed").to_pylist()[5] == "SeedSequence(7, spawn_key=(5,))"
    # Independent check: run 5 re-run by hand from the documented seed gives the stored steps.
    again = fe.run_episode(two_tasks, 1, np.random.SeedSequence(two_tasks.seed, spawn_key=(5,)))
    all_steps = results.read_steps(out)
    steps = all_steps.filter(_run_mask(all_steps, 5))
    # Steps are stored as float32 (sim.montecarlo.parts): exactly the episode's values rounded so.
    np.testing.assert_array_equal(steps.column("error").to_numpy(), again.steps.error.astype(np.float32))
    # Different runs draw different numbers.
    assert len(set(runs.column("rmse").to_pylist())) == 12
    assert summary.runs == 12 and summary.executed == 12 and summary.crashed == 0


def _run_mask(table, run):
    import pyarrow.compute as pc

    return pc.equal(table.column("run"), run)


def test_two_workers_give_bit_identical_results(serial_sweep, two_tasks, tmp_path):
    out2 = tmp_path / "mc2"
    sweep(two_tasks, out2, runs=12, workers=2, api=fe.API, progress=False)
    _assert_same(serial_sweep[0], out2)
    # Negative control: the comparison does see a different seed.
    other = scenarios.loads(two_tasks.text.replace("seed = 7", "seed = 8"), source="seed8.toml")
    out3 = tmp_path / "mc3"
    sweep(other, out3, runs=12, workers=1, api=fe.API, progress=False)
    with pytest.raises(AssertionError, match="differs"):
        _assert_same(serial_sweep[0], out3)


RAY_MISSING = "the e2e tier runs with Ray installed: pip install -c constraints.txt -e '.[test,ray]'"


def _require_ray() -> None:
    """Fail, not skip, without Ray: the e2e tier installs the ray extra (README), so a skip would hide it."""
    try:
        import ray  # noqa: F401
    except ImportError:
        pytest.fail(RAY_MISSING)


@pytest.mark.e2e
def test_ray_gives_the_same_results(serial_sweep, two_tasks, tmp_path):
    """Ray actors on a local cluster give the local sweep's tables, column for column."""
    _require_ray()
    out = tmp_path / "ray"
    summary = sweep(two_tasks, out, runs=12, workers=2, executor="ray", api=fe.API, progress=False)
    assert summary.runs == 12
    _assert_same(serial_sweep[0], out)


@pytest.mark.e2e
def test_ray_real_episodes_equal_local_ones(two_tasks, tmp_path):
    """The real episode (physics, filter, fixes) through Ray equals the local pool's, table for table.

    Negative control: the comparison sees one run's seed changed (a local sweep of another seed).
    """
    _require_ray()
    local, ray_out = tmp_path / "local", tmp_path / "ray"
    sweep(two_tasks, local, runs=4, workers=1, progress=False)
    sweep(two_tasks, ray_out, runs=4, workers=2, executor="ray", progress=False)
    _assert_same(local, ray_out)
    other = scenarios.loads(two_tasks.text.replace("seed = 7", "seed = 8"), source="seed8.toml")
    sweep(other, tmp_path / "other", runs=4, workers=1, progress=False)
    with pytest.raises(AssertionError, match="differs"):
        _assert_same(local, tmp_path / "other")


@pytest.mark.e2e
def test_ray_runs_a_scenario_whose_plan_carries_the_pefs_memos(tmp_path):
    """paper-two-markers through Ray equals the local pool (its payload carries the PEF's grown memos).

    Ray hands a payload's numpy arrays out read-only; a worker that grew the memos in them
    crashed every run ("assignment destination is read-only"). Negative control:
    :func:`test_a_ray_actor_works_on_a_writable_copy_of_its_payload`.
    """
    _require_ray()
    sc = scenarios.load("paper-two-markers")
    local, ray_out = tmp_path / "local", tmp_path / "ray"
    sweep(sc, local, runs=2, workers=1, progress=False)
    sweep(sc, ray_out, runs=2, workers=2, executor="ray", progress=False)
    assert results.read_runs(ray_out).column("status").to_pylist() == ["ok", "ok"]
    _assert_same(local, ray_out)


def test_a_ray_actor_works_on_a_writable_copy_of_its_payload():
    """A payload read-only as Ray's object store hands it out can be grown by the actor's context.

    Negative control: the same factory on the payload itself fails (the payload is read-only).
    """
    from sim.montecarlo.executors import _RayWorker

    def grow(payload):
        payload[0] = 1.0
        return SimpleNamespace(execute=lambda spec: float(payload[0]) + spec)

    frozen = np.frombuffer(np.zeros(4).tobytes())
    assert not frozen.flags.writeable
    assert _RayWorker(grow, frozen).execute(2.0) == 3.0
    with pytest.raises(ValueError, match="read-only"):
        grow(frozen)


def test_crashing_runs_are_recorded_and_others_continue(tmp_path, two_tasks):
    out = tmp_path / "crashy"
    summary = sweep(two_tasks, out, runs=10, workers=2, api=fe.CRASHY, progress=False)
    runs = results.read_runs(out).to_pylist()
    assert [r["run"] for r in runs] == list(range(10))
    crashed = [r["run"] for r in runs if r["status"] != "ok"]
    assert crashed == [i for i in range(10) if i % fe.CRASH_EVERY == 2]
    for r in runs:
        if r["run"] in crashed:
            want = r"crashed: ZeroDivisionError: fake bug \(at fake_episode\.py:\d+\)"
            assert re.fullmatch(want, r["status"])
            assert r["rmse"] is None
    assert set(results.read_steps(out).column("run").to_pylist()) == set(range(10)) - set(crashed)
    assert summary.crashed == len(crashed) and summary.ok == 10 - len(crashed)


def test_a_dying_worker_costs_only_its_own_run(tmp_path, two_tasks):
    out = tmp_path / "segv"
    sweep(two_tasks, out, runs=6, workers=2, api=fe.SEGFAULT, progress=False)
    status = results.read_runs(out).column("status").to_pylist()
    assert status == ["ok"] * 4 + ["crashed: worker process died", "ok"]


def test_bad_input_in_a_run_stops_the_sweep_keeping_finished_runs(tmp_path, two_tasks):
    out = tmp_path / "fatal"
    with pytest.raises(SimulationError, match=r"^run 3: fake: robot cannot start"):
        sweep(two_tasks, out, runs=8, workers=1, api=fe.FATAL, progress=False)
    assert results.finished_runs(SweepLayout(out)) == {0, 1, 2}


@pytest.mark.parametrize("kwargs, match", [
    (dict(runs=0), "runs: expected a positive number of runs, got 0"),
    (dict(runs=-3), "got -3"),
    (dict(task=2), r"task: expected 0 \.\. 1"),
    (dict(workers=0), "workers: expected a positive number, got 0"),
    (dict(executor="dask"), "executor: expected one of local, ray"),
])
def test_bad_arguments_are_one_line_errors(tmp_path, two_tasks, kwargs, match):
    args = dict(runs=2, api=fe.API, progress=False) | kwargs
    with pytest.raises(ScenarioError, match=match) as err:
        sweep(two_tasks, tmp_path / "x", **args)
    assert "\n" not in str(err.value)


def test_output_directory_rules(tmp_path, two_tasks):
    out = tmp_path / "dir"
    sweep(two_tasks, out, runs=3, workers=1, api=fe.API, progress=False)
    assert (out / "scenario.toml").read_text() == two_tasks.text
    with pytest.raises(OutputError, match="not empty; resume to complete it"):
        sweep(two_tasks, out, runs=3, workers=1, api=fe.API, progress=False)
    other = scenarios.load("paper-docks")
    with pytest.raises(OutputError, match="was made from another scenario"):
        sweep(other, out, runs=3, workers=1, api=fe.API, resume=True, progress=False)
    with pytest.raises(OutputError, match="was made with task None, not 1"):
        sweep(two_tasks, out, runs=3, task=1, workers=1, api=fe.API, resume=True, progress=False)
    stranger = tmp_path / "stranger"
    stranger.mkdir()
    (stranger / "notes.txt").write_text("mine")
    with pytest.raises(OutputError, match="not a pefsim mc directory"):
        sweep(two_tasks, stranger, runs=3, api=fe.API, resume=True, progress=False)
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(OutputError, match="cannot create the output directory"):
        sweep(two_tasks, blocker / "sub", runs=3, api=fe.API, progress=False)


def test_failed_planning_leaves_the_directory_usable(tmp_path, two_tasks):
    out = tmp_path / "unplannable"
    with pytest.raises(PlanningError, match="no admissible route"):
        sweep(two_tasks, out, runs=2, workers=1, api=fe.UNPLANNABLE, progress=False)
    assert not any(out.iterdir())
    assert sweep(two_tasks, out, runs=2, workers=1, api=fe.API, progress=False).runs == 2


def test_resume_completes_only_missing_runs_and_extends(tmp_path, two_tasks):
    out = tmp_path / "grow"
    sweep(two_tasks, out, runs=4, workers=1, api=fe.API, progress=False)
    before = {p.name: p.stat().st_mtime_ns for p in (out / "runs").iterdir()}
    again = sweep(two_tasks, out, workers=1, api=fe.API, resume=True, progress=False)  # runs from sweep.json
    assert again.executed == 0 and again.runs == 4
    more = sweep(two_tasks, out, runs=7, workers=1, api=fe.API, resume=True, progress=False)
    assert more.executed == 3 and more.runs == 7
    assert {p.name: p.stat().st_mtime_ns for p in (out / "runs").iterdir() if p.name in before} == before
    assert pq.read_table(out / "runs.parquet").column("run").to_pylist() == list(range(7))


KILL_DRIVER = """
import sys
import scenarios
from sim.montecarlo.engine import sweep
from tests.sim.montecarlo import fake_episode as fe

if __name__ == "__main__":
    sweep(scenarios.load("paper-docks"), sys.argv[1], runs=int(sys.argv[2]), workers=2, api=fe.SLOW,
          progress=False)
"""


def test_killed_sweep_resumes_without_losing_or_duplicating_runs(tmp_path):
    runs = 40
    out = tmp_path / "killed"
    driver = tmp_path / "driver.py"
    driver.write_text(textwrap.dedent(KILL_DRIVER))
    env = dict(os.environ, PYTHONPATH=str(REPO), FAKE_EPISODE_SLEEP="0.15")
    proc = subprocess.Popen([sys.executable, str(driver), str(out), str(runs)], cwd=tmp_path, env=env,
                            start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    layout = SweepLayout(out)
    try:
        deadline = time.monotonic() + 120
        while len(results.finished_runs(layout)) < 6:
            if proc.poll() is not None:
                pytest.fail(f"driver exited early: {proc.stderr.read().decode()[-2000:]}")
            if time.monotonic() > deadline:
                pytest.fail("driver wrote no runs in 120 s")
            time.sleep(0.05)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)  # the driver, its fork server and its workers
        proc.wait()
        proc.stderr.close()
    finished = results.finished_runs(layout)
    assert 6 <= len(finished) < runs, "the kill came too late to test anything"
    kept = {p: p.read_bytes() for d in (layout.runs_dir, layout.steps_dir, layout.fixes_dir)
            for p in d.iterdir() if p.name.startswith("run-") and int(p.name[4:10]) in finished}
    mtimes = {p: p.stat().st_mtime_ns for p in kept}

    summary = sweep(scenarios.load("paper-docks"), out, runs=runs, workers=1, api=fe.API, resume=True,
                    progress=False)
    assert summary.executed == runs - len(finished)
    table = results.read_runs(out)
    assert table.column("run").to_pylist() == list(range(runs))
    steps = results.read_steps(out, columns=["run", "step"])
    pairs = set(zip(steps.column("run").to_pylist(), steps.column("step").to_pylist(), strict=True))
    assert len(pairs) == steps.num_rows == runs * fe.N_STEPS  # no step row twice
    for p, data in kept.items():
        assert p.read_bytes() == data and p.stat().st_mtime_ns == mtimes[p], f"{p.name} was rewritten"
    assert not [p for d in (layout.runs_dir, layout.steps_dir, layout.fixes_dir) for p in d.glob(".*")]
    # And the interrupted-then-resumed sweep equals an uninterrupted one.
    fresh = tmp_path / "fresh"
    sweep(scenarios.load("paper-docks"), fresh, runs=runs, workers=1, api=fe.API, progress=False)
    _assert_same(fresh, out)


def test_recordings_every_mth_run(tmp_path, two_tasks, monkeypatch):
    written = []

    def write_episode_rrd(path, scenario, result, pef_map=None):
        written.append(pef_map)
        Path(path).write_bytes(b"RRF2 fake " + result.scenario_name.encode())
        return Path(path)

    monkeypatch.setattr(montecarlo, "recording_pef_map", lambda scenario: "the map")
    out = tmp_path / "rrd"
    sweep(two_tasks, out, runs=7, workers=1, api=fe.API, rrd_every=3, progress=False, recorder=write_episode_rrd)
    assert sorted(p.name for p in (out / "recordings").iterdir()) == [
        "run-000000.rrd", "run-000003.rrd", "run-000006.rrd"]
    assert (out / "recordings" / "run-000003.rrd").read_bytes() == b"RRF2 fake paper-docks"
    assert written == ["the map"] * 3


def test_a_failing_recording_keeps_the_run_and_warns(tmp_path, two_tasks, monkeypatch):
    def broken(path, scenario, result, pef_map=None):
        raise ValueError("no plan")

    monkeypatch.setattr(montecarlo, "recording_pef_map", lambda scenario: None)
    warnings = []
    out = tmp_path / "rrd-broken"
    sweep(two_tasks, out, runs=2, workers=1, api=fe.API, rrd_every=1, progress=False,
          on_warning=warnings.append, recorder=broken)
    assert results.read_runs(out).column("status").to_pylist() == ["ok", "ok"]
    assert len(warnings) == 2 and "recording failed: ValueError: no plan" in warnings[0]


def test_report_is_self_contained(serial_sweep, two_tasks):
    from estimators.consistency import clopper_pearson
    from validation.report.page import write_report

    out, _ = serial_sweep
    x = (np.arange(40) + 0.5) * 0.5
    y = (np.arange(24) + 0.5) * 0.5
    fake_map = SimpleNamespace(x=x, y=y, tau=np.full((24, 40), 0.01), cell_size=(0.5, 0.5),
                               model=PefModel.PARALLELOGRAM)
    page = write_report(out, two_tasks, pef_map=fake_map).read_text()
    images = re.findall(r"src='data:image/png;base64,([^']+)'", page)
    assert len(images) == 4
    assert all(base64.b64decode(i).startswith(b"\x89PNG\r\n\x1a\n") for i in images)
    assert "src='http" not in page and "href=" not in page  # nothing to fetch
    assert sorted(p.name for p in (out / "figures").iterdir()) == [
        "error_cdf.png", "failure_rate.png", "fix_scatter.png", "worst_error_map.png"]
    # Clopper-Pearson against scipy's own implementation.
    from scipy.stats import binomtest

    for k, n in ((0, 10), (3, 10), (10, 10), (47, 200)):
        lo, hi = clopper_pearson(np.array([k]), np.array([n]), 0.05)
        ci = binomtest(k, n).proportion_ci(0.95, method="exact")
        assert lo[0] == pytest.approx(ci.low, abs=1e-12) and hi[0] == pytest.approx(ci.high, abs=1e-12)


def test_summary_counts_match_the_rows(serial_sweep):
    out, summary = serial_sweep
    rows = results.read_runs(out).to_pylist()
    ok = [r for r in rows if r["status"] == "ok"]
    success = [r for r in ok if r["reached"] and r["violations"] == 0]
    assert summary.ok == len(ok) and summary.successes == len(success)
    assert summary.violation_runs == sum(r["violations"] > 0 for r in ok)
    assert summary.success_fraction == len(success) / len(rows)
    lo, hi = summary.success_ci
    assert lo <= summary.success_fraction <= hi


def test_progress_bar_on_stderr_only_when_asked(capsys):
    from sim.montecarlo.progress import progress_bar

    with progress_bar(total=3, initial=1, enabled=True) as bar:
        bar.update(2)
        bar.write("note")
    err = capsys.readouterr()
    assert "3/3" in err.err and "note" in err.err and err.out == ""
    with progress_bar(total=3) as bar:  # stderr is not a terminal under pytest
        bar.update(3)
    assert capsys.readouterr().err == ""


def test_progress_lines_off_a_terminal_come_every_period():
    """Off a terminal: no line before PERIOD seconds, then runs done of runs asked (a fake clock)."""
    from sim.montecarlo.progress import PERIOD, Lines

    now, got = [100.0], []
    lines = Lines(total=10, initial=2, clock=lambda: now[0], emit=got.append)
    lines.update(3)
    now[0] += PERIOD - 0.1
    lines.tick()
    assert got == []   # a sweep shorter than the period prints nothing
    now[0] += 0.1
    lines.tick()
    assert got == [f"pefsim: 5 of 10 runs done ({PERIOD:.0f} s, {60 * 3 / PERIOD:.1f} runs/min)"]
    lines.tick()
    assert len(got) == 1 and 0 < lines.due() <= PERIOD   # the next one a period later


def test_a_sweep_without_a_terminal_prints_progress_lines(tmp_path):
    """A child process whose stderr is a pipe: the timer thread prints while no run finishes."""
    import subprocess
    import sys

    code = ("import time; from sim.montecarlo import progress as p; p.PERIOD = 0.2\n"
            "with p.progress_bar(total=4, initial=1) as bar:\n"
            "    time.sleep(0.5); bar.update(1); time.sleep(0.3)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True)
    lines = out.stderr.splitlines()
    assert out.stdout == "" and len(lines) >= 2, out.stderr
    assert lines[0].startswith("pefsim: 1 of 4 runs done") and lines[-1].startswith("pefsim: 2 of 4 runs done")
