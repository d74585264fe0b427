"""``pefsim mc`` on the command line: bad input is one line and exit 2; a real sweep end to end."""

from __future__ import annotations

import json
import sys

import cli
import scenarios
from sim.montecarlo import results
from sim.montecarlo.engine import sweep
from sim.montecarlo.rows import TIMING_COLUMNS
from tests.sim.montecarlo import fake_episode as fe


def _bad(capsys, argv: list[str], match: str) -> None:
    code = cli.main(["mc", *argv])
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pefsim: error: "), err
    assert match in lines[0], lines[0]


def test_runs_must_be_positive(capsys, tmp_path):
    _bad(capsys, ["paper-docks", "--runs", "0", "--out", str(tmp_path / "a")], "runs: expected a positive")
    _bad(capsys, ["paper-docks", "--runs", "-5", "--out", str(tmp_path / "a")], "got -5")


def test_unwritable_output_directory(capsys, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    _bad(capsys, ["paper-docks", "--runs", "2", "--out", str(blocker / "mc")],
         "cannot create the output directory")


def test_resume_on_a_directory_of_another_scenario(capsys, tmp_path):
    out = tmp_path / "docks"
    sweep(scenarios.load("paper-docks"), out, runs=2, workers=1, api=fe.API, progress=False)
    _bad(capsys, ["paper-two-markers", "--out", str(out), "--resume"], "was made from another scenario")
    _bad(capsys, ["paper-docks", "--out", str(out)], "resume to complete it, or choose another out")


def test_unknown_task_and_stray_address(capsys, tmp_path):
    _bad(capsys, ["paper-docks", "--task", "3", "--out", str(tmp_path / "t")], "task: expected 0 .. 0")
    _bad(capsys, ["paper-docks", "--address", "auto", "--out", str(tmp_path / "t")],
         "address: needs executor ray")


def test_ray_missing_tells_how_to_install(capsys, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray now raises ImportError
    _bad(capsys, ["paper-docks", "--executor", "ray", "--runs", "2", "--out", str(tmp_path / "r")],
         "pip install 'pefsim[ray]'")
    assert not (tmp_path / "r").exists()


def test_real_sweep_end_to_end(capsys, tmp_path):
    """The real episode through the CLI on 2 workers, then in-process: identical files.

    On paper-docks, the built-in with the cheapest plan and episode (1.4 s and 2.2 s CPU against
    paper-two-markers' 4.3 s and 4.2 s): what is compared does not depend on the world.
    """
    out = tmp_path / "real"
    code = cli.main(["mc", "paper-docks", "--runs", "2", "--workers", "2", "--out", str(out), "--json"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    summary = json.loads(captured.out)
    assert summary["runs"] == 2 and summary["crashed"] == 0 and summary["executed"] == 2
    assert summary["out"] == str(out) and summary["success_target"] == 0.95
    assert (out / "report.html").stat().st_size > 10_000 and (out / "runs.parquet").exists()
    steps = results.read_steps(out, columns=["run"])
    assert steps.num_rows > 100 * 2 and results.read_fixes(out).num_rows > 2

    serial = tmp_path / "serial"
    sweep(scenarios.load("paper-docks"), serial, runs=2, workers=1, progress=False)
    for read in (lambda d: results.read_runs(d).drop(list(TIMING_COLUMNS)), results.read_steps,
                 results.read_fixes):
        a, b = read(out), read(serial)
        for col in a.column_names:
            assert a.column(col).equals(b.column(col)), f"{col} differs between 2 workers and 1"

    code = cli.main(["mc", "paper-docks", "--out", str(out), "--resume", "--json", "--no-report"])
    again = json.loads(capsys.readouterr().out)
    assert code == 0 and again["executed"] == 0 and again["runs"] == 2
