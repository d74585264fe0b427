"""A fleet sweep's tables: a row per robot per run, fix columns naming what robots hid, checks per robot and run."""

from __future__ import annotations

import json

import numpy as np

import scenarios
from sim.episode.types import FixNote
from sim.montecarlo import results
from sim.montecarlo.results import RunRecord, SweepLayout
from sim.montecarlo.rows import (
    FLEET,
    FLEET_FIX_SCHEMA,
    FLEET_RUN_SCHEMA,
    concat_columns,
    fleet_fix_columns,
    run_row,
    step_columns,
)
from sim.montecarlo.summary import summarize
from tests.sim.montecarlo import fake_episode as fe
from validation.data import fleet_units


def _fleet_record(scenario, run: int, names: list[str]) -> RunRecord:
    rows, steps, fixes = [], [], []
    for j, name in enumerate(names):
        result = fe.run_episode(scenario, 0, np.random.SeedSequence(scenario.seed, spawn_key=(run, j)))
        result.fixes.notes = [FixNote({0: 1 - j} if f % 3 == 0 else {}, 0.25,
                                      {0: 1 - j, 2: 1 - j} if f % 3 == 0 else {3: 1 - j})
                              for f in range(len(result.fixes.t))]
        rows.append(run_row(run, f"seed {run}", 0, {**result.summary, "robot": name, "wait_time": 1.5 * j,
                                                     "robot_blocked": 2, "collisions": 0}, 0.5,
                            schema=FLEET_RUN_SCHEMA))
        st = step_columns(run, result.steps)
        st["robot"] = np.array([name] * len(st["run"]), dtype=object)
        steps.append(st)
        fixes.append(fleet_fix_columns(run, result.fixes, name, scenario.marker_ids(), names))
    return RunRecord(run, rows, concat_columns(steps), concat_columns(fixes))


def test_a_fleet_sweep_round_trips_a_row_per_robot(tmp_path):
    sc = scenarios.load("paper-docks")
    layout = SweepLayout(tmp_path)
    layout.make_dirs()
    layout.sweep_json.write_text(json.dumps({"fleet": True, "steps": "all"}))
    names = ["a", "b"]
    for run in range(3):
        results.write_record(layout, _fleet_record(sc, run, names), FLEET)
    runs = results.read_runs(tmp_path)
    assert runs.schema == FLEET_RUN_SCHEMA and runs.num_rows == 6
    assert runs.column("robot").to_pylist() == names * 3
    assert runs.column("wait_time").to_pylist() == [0.0, 1.5] * 3
    fixes = results.read_fixes(tmp_path)
    assert fixes.schema == FLEET_FIX_SCHEMA
    hid = fixes.filter(fixes.column("blocked_by_robot_count").to_numpy(zero_copy_only=False) > 0)
    assert set(hid.column("blocked_by_robot").to_pylist()) == {sc.marker_ids()[0]}
    assert np.all(fixes.column("p_block_robot").to_numpy() == 0.25)   # the plan's prediction, for the blocking check
    # robot a's hidden line of sight was hidden by b and the other way round
    pairs = set(zip(hid.column("robot").to_pylist(), hid.column("blocking_robots").to_pylist(), strict=True))
    assert pairs == {("a", "b"), ("b", "a")}
    # every line of sight a robot hid, scheduled or not: the scheduled one and two more
    ids = sc.marker_ids()
    sight = fixes.column("sight_blocked_by_robot").to_pylist()
    count = fixes.column("sight_blocked_by_robot_count").to_numpy()
    hidden = fixes.column("blocked_by_robot_count").to_numpy()
    assert set(sight) == {f"{ids[0]},{ids[2]}", ids[3]}
    assert np.all(count == np.where(hidden > 0, 2, 1))
    s = summarize(tmp_path, 0.95)
    assert (s.runs, s.robots, s.collisions) == (6, 2, 0) and "robots" in s.to_dict()


def test_checks_judge_each_robot_of_each_run_as_a_unit():
    import pyarrow as pa

    sc = scenarios.load("warehouse-fleet")
    table = pa.table({"run": [0, 0, 0, 1, 1, 1, 2], "robot": ["r1", "r2", "r3", "r1", "r2", "r3", None]})
    units = fleet_units(sc, table).column("run").to_pylist()
    assert units == [0, 1, 2, 3, 4, 5, 6]
    single = pa.table({"run": [0, 1]})
    assert fleet_units(sc, single) is single
