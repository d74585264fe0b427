"""``--alone``: a fleet sweep whose schedules are planned as if each robot drove alone (a negative control).

The wiring only (seconds): the flag reaches :func:`sim.episode.fleet.prepare_fleet` as
``traffic=False`` through :func:`pefsim.sweep`, the directory records it, validating the
directory says so, and a scenario without ``[[robots]]`` is refused. That the alone plan counts on
lines of sight the other robots hide is ``test_the_fleet_planned_alone_counts_on_hidden_lines_of_sight`` (e2e).
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pyarrow.parquet as pq
import pytest

import cli
import pefsim
import scenarios
from scenarios import ScenarioError
from sim.episode import fleet
from sim.montecarlo.engine import default_api
from sim.montecarlo.negative_control import NEGATIVE_CONTROL_JSON, mark, read_mark


@dataclasses.dataclass
class _Summary:
    out: str
    report: str | None = None

    def to_dict(self) -> dict:
        return {"out": self.out}


@pytest.fixture
def planned(monkeypatch):
    """Record the ``traffic`` argument of every fleet planning instead of planning."""
    calls = []
    monkeypatch.setattr(fleet, "prepare_fleet", lambda scenario, pef=None, traffic=True: calls.append(traffic))
    return calls


@pytest.mark.parametrize("traffic", [True, False])
def test_the_episode_api_plans_with_or_without_traffic(planned, traffic):
    default_api(traffic=traffic).prepare(scenarios.load("warehouse-fleet"))
    assert planned == [traffic]


@pytest.mark.parametrize(("alone", "q_scale"), [(True, 1.0), (False, 1.0), (True, 0.5)])
def test_sweep_alone_plans_alone_and_marks_the_directory(monkeypatch, planned, tmp_path, alone, q_scale):
    import sim.montecarlo.engine as engine

    def fake_sweep(scenario, out, *, api=None, then=None, **kwargs):
        (api or default_api()).prepare(scenario)
        summary = _Summary(str(out))
        then(summary)
        return summary

    monkeypatch.setattr(engine, "sweep", fake_sweep)
    pefsim.sweep("warehouse-fleet", tmp_path, runs=1, alone=alone, q_scale=q_scale, report=False)
    assert planned == [not alone]
    marked = (tmp_path / NEGATIVE_CONTROL_JSON).exists()
    assert marked == (alone or q_scale != 1.0)
    assert read_mark(tmp_path) == (q_scale, alone)


def test_a_single_robot_scenario_cannot_be_planned_alone(tmp_path):
    with pytest.raises(ScenarioError, match="alone: paper-docks is not a fleet scenario"):
        pefsim.sweep("paper-docks", tmp_path / "mc", runs=1, alone=True)
    assert not (tmp_path / "mc").exists()


def test_resuming_with_another_negative_control_is_refused(tmp_path):
    mark(tmp_path, 1.0, alone=True)
    with pytest.raises(ScenarioError, match="resume: its runs were made with"):
        pefsim.sweep("warehouse-fleet", tmp_path, runs=1, resume=True)


def test_the_mark_reads_back_and_a_bad_one_is_refused(tmp_path):
    assert read_mark(tmp_path) == (1.0, False)
    mark(tmp_path, 0.01)
    assert read_mark(tmp_path) == (0.01, False)
    (tmp_path / NEGATIVE_CONTROL_JSON).write_text(json.dumps({"q_scale": 1.0, "alone": "yes"}))
    with pytest.raises(scenarios.OutputError, match="unreadable"):
        read_mark(tmp_path)


def test_the_cli_passes_alone_to_the_library_and_prints_it(monkeypatch, capsys):
    from validation.data import CheckResult, CheckStatus
    from validation.suite import ValidationReport

    seen = {}

    def fake_sweep(scenario, out, **kwargs):
        seen.update(kwargs)
        return _Summary(str(out))

    report = ValidationReport("warehouse-fleet", "x", 3, 10, 0.01, 1, 0.01, 1.0,
                              [CheckResult("plan", CheckStatus.FAIL, "0.5 (1/2)", "CI upper >= target", 0.01)],
                              alone=True)
    monkeypatch.setattr(pefsim, "sweep", fake_sweep)
    monkeypatch.setattr(pefsim, "validate", lambda *a, **k: report)
    assert cli.main(["validate", "warehouse-fleet", "--alone", "--runs", "1"]) == 1
    out = capsys.readouterr().out
    assert seen["alone"] is True
    assert "NEGATIVE CONTROL: each robot's measurement schedule was planned as if it drove alone" in out
    assert cli.main(["mc", "warehouse-fleet", "--alone", "--runs", "1", "--no-report", "--json"]) == 0
    assert seen["alone"] is True


def test_validate_from_refuses_alone(capsys, tmp_path):
    code = cli.main(["validate", "--from", str(tmp_path), "--alone"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--alone: not with --from" in err[0]


@pytest.fixture(scope="module")
def both_ways(tmp_path_factory):
    """Validate the built-in fleet at 3 runs, traffic-aware and planned alone: (code, report, runs) each."""
    import contextlib
    import io

    out = {}
    for alone in (False, True):
        where = tmp_path_factory.mktemp("alone" if alone else "traffic")
        argv = ["validate", "warehouse-fleet", "--runs", "3", "--workers", "1", "--out", str(where), "--json"]
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            code = cli.main(argv + (["--alone"] if alone else []))
        out[alone] = (code, json.loads(buf.getvalue()), pq.read_table(where / "runs.parquet").to_pydict())
    return out


@pytest.mark.e2e  # plans the fleet both ways (~5 min each), drives it 3 runs each (~2 min)
def test_the_fleet_planned_alone_counts_on_hidden_lines_of_sight(both_ways):
    """Planned alone, the fleet's schedules measure reflectors the other robots hide; traffic-aware, hardly.

    Measured (20 runs alone, 3 traffic-aware, the scenario's seeds): alone, r1 finds 7-8 of its
    scheduled lines of sight hidden in every run and r2 1-2, r3 none; traffic-aware r1 finds 1 and
    the others none. The fallback subsets the schedule keeps for every fix carry the robots through
    either way (the certified bound stays under eps_max: the plan check passes both ways, 60 of 60
    robot runs alone), so the difference is in what the robots had to fall back on, which is what
    the traffic-aware schedule is for. Negative control: the alone sweep, whose hidden lines of
    sight are at least three times as many in every run.
    """
    for alone, (code, report, _) in both_ways.items():
        status = {c["name"]: c["status"] for c in report["checks"]}
        assert report["alone"] is alone and code == 0, report["failed"]
        assert status["plan"] == status["containment"] == status["promise"] == "pass"
    hidden = {alone: np.bincount(np.asarray(runs["run"]), weights=np.asarray(runs["robot_blocked"], float))
              for alone, (_, _, runs) in both_ways.items()}
    assert hidden[True].size == hidden[False].size == 3
    assert np.all(hidden[True] >= 3 * np.maximum(hidden[False], 1))
    fell_back = {alone: sum(runs["fallback_fixes"]) for alone, (_, _, runs) in both_ways.items()}
    assert fell_back[True] > fell_back[False]


@pytest.mark.parametrize("traffic", [True, False])
def test_the_episode_api_crosses_to_worker_processes(planned, traffic):
    """The local pool pickles the episode API to its workers (``--workers 2`` on a fleet died of it)."""
    import pickle

    copy = pickle.loads(pickle.dumps(default_api(traffic=traffic)))
    copy.prepare(scenarios.load("warehouse-fleet"))
    assert planned == [traffic]
