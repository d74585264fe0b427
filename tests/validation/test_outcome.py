"""validate names what made runs fail before any check, and fails on it (synthetic runs tables)."""

from __future__ import annotations

import numpy as np

import cli
import scenarios
from sim.montecarlo import results
from sim.montecarlo.results import RunRecord, SweepLayout
from sim.montecarlo.rows import fix_columns, run_row
from tests.validation.synthetic_fixes import FIXES_PER_RUN, fix_log
from validation.data import CheckStatus

RUNS = 5


def _scenario():
    return scenarios.load("paper-two-markers")


def write_sweep(root, scenario, seed: int, outcomes: dict | None = None) -> None:
    """Write a synthetic sweep of a consistent model (as ``test_suite.py`` does); ``outcomes``: run -> what it did.

    What a run did is the summary keys of :mod:`sim.episode.outcome` (status, collisions, ...).
    """
    rng = np.random.default_rng(seed)
    layout = SweepLayout(root)
    layout.make_dirs()
    results.write_atomic(layout.scenario_toml, scenario.text.encode())
    for run in range(RUNS):
        log = fix_log(scenario, rng, 1.0)
        log.nis[:] = rng.chisquare(1, (FIXES_PER_RUN, 2)).sum(axis=1)
        summary = {"reached": True, "violations": 0, "fixes": FIXES_PER_RUN,
                   "mean_nees": rng.chisquare(3, 50).mean(), **(outcomes or {}).get(run, {})}
        results.write_record(layout, RunRecord(run, run_row(run, f"s{run}", 0, summary, 0.1), None,
                                               fix_columns(run, log)))

#: Runs 1 and 3 pressed against a pillar: what sim.episode.outcome writes for them.
TOUCHED = {"status": "collided", "collisions": 2, "contact_t": 3.25, "contact_x": 0.52, "contact_y": -0.48,
           "contact_s": 3.2, "contact_with": "obstacle 4 (circle at (0.70, -0.48))"}


def test_collided_runs_are_named_first_and_fail_validate(tmp_path, capsys):
    sc = _scenario()
    write_sweep(tmp_path / "mc", sc, seed=1, outcomes={1: TOUCHED, 3: TOUCHED})
    code = cli.main(["validate", "--from", str(tmp_path / "mc")])
    out = capsys.readouterr().out.splitlines()
    assert code == 1
    task = sc.tasks[0]
    cause = (f"2 of {RUNS} runs touched an obstacle; first at (0.52, -0.48) s=3.2 m t=3.2 s, "
             f"task {task.start} -> {task.goal} (obstacle 4 (circle at (0.70, -0.48)), 2 contact(s) in that run)")
    assert out[1] == cause, out[:3]   # right after the header, before the table of checks
    table = [line.split() for line in out if line.startswith("runs ")]
    assert table[0][1] == f"{RUNS - 2}/{RUNS}" and table[0][-1] == CheckStatus.FAIL.value


def test_stuck_runs_get_their_own_line(tmp_path, capsys):
    stuck = {"status": "stuck", "stuck": True, "stall_time": 40.5, "stuck_bound": 14.7, "stall_x": 1.0,
             "stall_y": 2.0, "stall_s": 0.5}
    write_sweep(tmp_path / "mc", _scenario(), seed=1, outcomes={0: stuck})
    assert cli.main(["validate", "--from", str(tmp_path / "mc")]) == 1
    out = capsys.readouterr().out.splitlines()
    assert out[1].startswith(f"1 of {RUNS} runs stuck: no progress along the path for 40.5 s (bound 14.7 s) "
                             "from (1.00, 2.00) s=0.5 m")


def test_runs_that_did_what_was_asked_give_no_cause_line(tmp_path, capsys):
    """Negative control: the same sweep with every run ok passes, and nothing comes before the table."""
    write_sweep(tmp_path / "mc", _scenario(), seed=1)
    assert cli.main(["validate", "--from", str(tmp_path / "mc")]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[1].startswith("family alpha")
    assert [line.split()[-1] for line in out if line.startswith("runs ")] == [CheckStatus.PASS.value]


def test_an_incomplete_sweep_says_how_many_runs_are_missing(tmp_path, capsys):
    """sweep.json asks for more runs than finished: one line says how many are missing."""
    from sim.montecarlo.directory import init_sweep_dir
    from sim.montecarlo.results import SweepLayout
    from sim.montecarlo.steps import StepsMode

    sc = _scenario()
    write_sweep(tmp_path / "mc", sc, seed=1)
    init_sweep_dir(SweepLayout(tmp_path / "mc"), sc, None, RUNS + 3, StepsMode.ALL)
    assert cli.main(["validate", "--from", str(tmp_path / "mc")]) == 0
    out = capsys.readouterr().out.splitlines()
    assert [line for line in out if "missing" in line] == [
        f"incomplete sweep: 3 runs missing (pefsim mc SCENARIO --out {tmp_path / 'mc'} --resume completes it); "
        "judged on the finished ones"]


def _fleet_rows(rows: list[dict]):
    """Return a sweep stand-in with only the runs' outcome table (all :func:`validation.outcome.waits` reads)."""
    import types

    import pyarrow as pa

    return types.SimpleNamespace(runs=types.SimpleNamespace(outcome=pa.Table.from_pylist(rows)))


def test_waits_put_the_plan_s_waits_beside_the_simulated_ones():
    from validation.outcome import waits

    r2 = [{"run": 3 * i + 1, "robot": "r2", "wait_time": w, "longest_wait": w - 1.0, "predicted_wait": 30.1,
           "predicted_wait_time": 31.0} for i, w in enumerate([20.0, 30.0, 40.0, 28.0, 33.0])]
    r1 = [{"run": 3 * i, "robot": "r1", "wait_time": 0.0, "longest_wait": 0.0, "predicted_wait": 0.0,
           "predicted_wait_time": 0.0} for i in range(5)]
    lines = waits(_fleet_rows(r1 + r2))
    q95 = np.quantile([20.0, 30.0, 40.0, 28.0, 33.0], 0.95)
    assert lines == [
        "r1: in all predicted 0.0 s, simulated median 0.0 s (95 % 0.0 s, max 0.0 s); longest predicted 0.0 s, "
        "simulated median 0.0 s (95 % 0.0 s, max 0.0 s); 5 runs",
        f"r2: in all predicted 31.0 s, simulated median 30.0 s (95 % {q95:.1f} s, max 40.0 s); longest predicted "
        f"30.1 s, simulated median 29.0 s (95 % {q95 - 1:.1f} s, max 39.0 s); 5 runs"]


def test_waits_of_a_sweep_written_before_the_plan_s_total_say_none_and_lone_robots_have_none():
    from validation.outcome import waits

    old = [{"run": 0, "robot": "r1", "wait_time": 2.0, "longest_wait": 2.0, "predicted_wait": 1.5}]
    assert waits(_fleet_rows(old)) == [
        "r1: in all predicted none, simulated median 2.0 s (95 % 2.0 s, max 2.0 s); longest predicted 1.5 s, "
        "simulated median 2.0 s (95 % 2.0 s, max 2.0 s); 1 runs"]
    assert waits(_fleet_rows([{"run": 0, "robot": None, "status": "ok"}])) == []
