"""Parquet layout of a sweep: round trip, commit order, clean-up of unfinished runs."""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import scenarios
from scenarios.errors import OutputError
from sim.montecarlo import results
from sim.montecarlo.results import RunRecord, SweepLayout
from sim.montecarlo.rows import RUN_SCHEMA, STEP_SCHEMA, _table, fix_columns, run_row, step_columns
from tests.sim.montecarlo import fake_episode as fe


@pytest.fixture(scope="module")
def scenario():
    return scenarios.load("paper-docks")


def _record(scenario, run: int) -> tuple[RunRecord, object]:
    seed = np.random.SeedSequence(scenario.seed, spawn_key=(run,))
    result = fe.run_episode(scenario, 0, seed)
    row = run_row(run, f"seed {run}", 0, result.summary, 0.5)
    rec = RunRecord(run, row, step_columns(run, result.steps), fix_columns(run, result.fixes))
    return rec, result


def test_round_trip_keeps_every_value(tmp_path, scenario):
    layout = SweepLayout(tmp_path)
    layout.make_dirs()
    rec, result = _record(scenario, 3)
    results.write_record(layout, rec)

    runs = results.read_runs(tmp_path)
    assert runs.num_rows == 1 and runs.schema == RUN_SCHEMA
    row = runs.to_pylist()[0]
    for key in ("rmse", "max_error", "violations", "reached", "mean_nees"):
        assert row[key] == result.summary[key]
    steps = results.read_steps(tmp_path)
    assert steps.schema == STEP_SCHEMA  # read back as float64 whatever the storage

    def f32(a):  # steps are stored as float32: exactly the episode's values rounded to it
        return np.asarray(a).astype(np.float32)

    # near the origin float32 keeps the positions to 1e-5 m: stored float32 (sim.montecarlo.parts)
    assert pq.read_schema(layout.part(layout.steps_dir, 3)).field("true_x").type == pa.float32()
    np.testing.assert_array_equal(steps.column("true_x").to_numpy(), f32(result.steps.true_pose[:, 0]))
    np.testing.assert_array_equal(steps.column("est_theta").to_numpy(), f32(result.steps.est_pose[:, 2]))
    np.testing.assert_array_equal(steps.column("xtheta_cov").to_numpy(), f32(result.steps.est_cov[:, 0, 2]))
    np.testing.assert_array_equal(steps.column("step").to_numpy(), np.arange(len(result.steps.t)))
    fixes = results.read_fixes(tmp_path)
    np.testing.assert_array_equal(np.array(fixes.column("markers").to_pylist()), result.fixes.markers)
    np.testing.assert_array_equal(np.array(fixes.column("ranges").to_pylist()), result.fixes.ranges)
    np.testing.assert_array_equal(fixes.column("contained").to_numpy(zero_copy_only=False),
                                  result.fixes.contained)
    # snapshot_error is derived: check it against an independent computation
    want = np.linalg.norm(result.fixes.snapshot - result.fixes.true_position, axis=1)
    np.testing.assert_allclose(fixes.column("snapshot_error").to_numpy(), want, rtol=1e-15)


def test_steps_far_from_the_origin_keep_the_estimate_s_millimetres(tmp_path, scenario):
    """A site 700 km from its origin: est - true read back from the steps as the episode had it.

    In float32 a coordinate of 7e5 m is kept to 6 cm; the negative control stores the same
    positions as float32 and loses the error.
    """
    layout = SweepLayout(tmp_path)
    layout.make_dirs()
    rec, _ = _record(scenario, 1)
    steps = dict(rec.steps)
    rng = np.random.default_rng(5)
    n = len(steps["true_x"])
    steps["true_x"] = 718012.7 + np.linspace(0.0, 20.0, n)
    steps["true_y"] = -249086.5 + np.linspace(0.0, 5.0, n)
    steps["est_x"] = steps["true_x"] + rng.normal(0.0, 1e-3, n)
    steps["est_y"] = steps["true_y"] + rng.normal(0.0, 1e-3, n)
    results.write_record(layout, RunRecord(rec.run, rec.row, steps, rec.fixes))
    back = results.read_steps(tmp_path)
    stored = pq.read_schema(layout.part(layout.steps_dir, rec.run))
    assert stored.field("true_x").type == pa.float64() and stored.field("t").type == pa.float32()
    err = back.column("est_x").to_numpy() - back.column("true_x").to_numpy()
    np.testing.assert_allclose(err, steps["est_x"] - steps["true_x"], rtol=0.0, atol=1e-9)
    as32 = (steps["est_x"].astype(np.float32).astype(float) - steps["true_x"].astype(np.float32).astype(float))
    assert np.max(np.abs(as32 - (steps["est_x"] - steps["true_x"]))) > 1e-3   # what float32 did


def test_crashed_row_has_nulls_and_no_step_parts(tmp_path):
    layout = SweepLayout(tmp_path)
    layout.make_dirs()
    row = run_row(0, "s", 1, None, None, status="crashed: ValueError: x")
    results.write_record(layout, RunRecord(0, row))
    got = results.read_runs(tmp_path).to_pylist()[0]
    assert got["status"] == "crashed: ValueError: x" and got["rmse"] is None and got["reached"] is None
    assert results.read_steps(tmp_path).num_rows == 0
    assert not list(layout.steps_dir.iterdir())


def test_empty_fix_log_is_written(tmp_path, scenario):
    layout = SweepLayout(tmp_path)
    layout.make_dirs()
    rec, result = _record(scenario, 0)
    f = result.fixes
    empty = type(f)(t=np.zeros(0), markers=np.zeros((0, 2), int), ranges=np.zeros(0), rho=np.zeros(0),
                    true_position=np.zeros((0, 2)), snapshot=np.zeros((0, 2)),
                    snapshot_cov=np.zeros((0, 2, 2)),
                    fault_diameter=np.zeros(0), fault_polygons=[], contained=np.zeros(0, bool),
                    predicted_tau=np.zeros(0), static_tau=np.zeros(0), nis=np.zeros(0), n_accepted=np.zeros(0, int))
    rec.fixes = fix_columns(0, empty)
    results.write_record(layout, rec)
    assert results.read_fixes(tmp_path).num_rows == 0
    assert results.read_runs(tmp_path).num_rows == 1


def test_unfinished_parts_are_ignored_then_cleaned(tmp_path, scenario):
    layout = SweepLayout(tmp_path)
    layout.make_dirs()
    done, _ = _record(scenario, 0)
    results.write_record(layout, done)
    # A run killed after its steps part but before its runs part, and a half-written temp file:
    half, _ = _record(scenario, 1)
    pq.write_table(_table(half.steps, STEP_SCHEMA), layout.part(layout.steps_dir, 1))
    (layout.runs_dir / ".run-000002.parquet.tmp123").write_bytes(b"PAR1 trunc")

    assert results.finished_runs(layout) == {0}
    assert set(results.read_steps(tmp_path).column("run").to_pylist()) == {0}
    assert results.read_runs(tmp_path).column("run").to_pylist() == [0]

    assert results.clean_unfinished(layout) == 2
    assert not layout.part(layout.steps_dir, 1).exists()
    assert layout.part(layout.steps_dir, 0).exists() and layout.part(layout.runs_dir, 0).exists()
    assert not list(layout.runs_dir.glob(".*"))


def test_runs_part_is_written_last(tmp_path, scenario, monkeypatch):
    """If writing the fixes part fails, the run must not count as finished."""
    layout = SweepLayout(tmp_path)
    layout.make_dirs()
    rec, _ = _record(scenario, 4)
    real = results.write_atomic

    def failing(path, data):
        if path.parent == layout.fixes_dir:
            raise OutputError(f"{path}: cannot write: disk full")
        real(path, data)

    monkeypatch.setattr(results, "write_atomic", failing)
    with pytest.raises(OutputError, match="disk full"):
        results.write_record(layout, rec)
    assert results.finished_runs(layout) == set()


def test_compact_runs_sorts_by_run(tmp_path, scenario):
    layout = SweepLayout(tmp_path)
    layout.make_dirs()
    for run in (5, 1, 3):
        results.write_record(layout, _record(scenario, run)[0])
    table = results.compact_runs(layout)
    assert table.column("run").to_pylist() == [1, 3, 5]
    assert pq.read_table(layout.runs_parquet).equals(table)


def test_unwritable_directory_is_an_output_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(OutputError, match="cannot create the output directory"):
        SweepLayout(blocker / "sub").make_dirs()


def test_parts_written_before_a_column_was_added_read_back_with_it_null(tmp_path, scenario):
    # a sweep of an earlier pefsim (no lost_guarantee, no excused) still reads, validates and
    # resumes; a column missing that was always there is still a damaged part
    layout = SweepLayout(tmp_path)
    layout.make_dirs()
    rec, _ = _record(scenario, 0)
    results.write_record(layout, rec)
    for folder, name in ((layout.runs_dir, "lost_guarantee"), (layout.steps_dir, "excused"),
                         (layout.fixes_dir, "unplanned")):
        path = layout.part(folder, 0)
        pq.write_table(pq.read_table(path).drop_columns([name]), path)
    runs, steps = results.read_runs(tmp_path), results.read_steps(tmp_path)
    assert runs.column("lost_guarantee").null_count == 1 and steps.column("excused").null_count == steps.num_rows
    fixes = results.read_fixes(tmp_path)
    assert fixes.num_rows > 0 and fixes.column("unplanned").null_count == fixes.num_rows
    assert steps.column("certified").null_count == 0
    path = layout.part(layout.steps_dir, 0)
    pq.write_table(pq.read_table(path).drop_columns(["certified"]), path)
    with pytest.raises(OutputError, match="does not read back"):
        results.read_steps(tmp_path)
