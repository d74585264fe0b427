"""A scenario without [[robots]] gives the tables it gave before fleets existed.

What is pinned: the runs row, the step columns and the fix columns of a 3 s episode of task 0
with run 0's seed (:func:`tables`), for paper-two-markers and warehouse, against the reference
``single_robot_tables.npz`` next to this file. Integers, flags and strings are compared exactly,
floats to ``RTOL`` of themselves: a change of summation order passes (the scalar update's loops
moved P by at most 2e-21 m^2), any change of the model does not. Runs-table columns added after
the reference (:data:`ADDED_RUN_COLUMNS`) only watch the episode and may appear; no other may.

The reference is the tables, not their SHA-256: on a machine whose numpy dispatches its float64
transcendental functions to AVX-512 (numpy's ``X86_V4`` features) ``certified`` and
``predicted_tau`` came out 1 ulp off (at most 4.4e-16 relative) from tables written on an
``X86_V3`` machine. The planner computes those columns and nothing in the episode feeds back
into them, so the ulps do not grow.

A change that moves any number of a single-robot episode (the laser's ray ends, the posts, the
random streams, the filter, the schedule) must do so on purpose, say why in its commit and in
CHANGELOG.md, and write the tables again, from the repository root and with numpy's AVX-512
dispatch off, as every earlier version was written::

    export NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL"
    python -m tests.sim.episode.test_single_robot_identity tests/sim/episode/single_robot_tables.npz

History (details in CHANGELOG.md). The fleet work was checked against digests computed by the
same function with commit 3bb1324 (main before fleets): equal. Since then the tables were written
again for changes of single-robot episodes: scheduled fixes near the goal taken there and a
promise derived from the plan's certified estimate error; the filter's consistency on random
worlds (the snapshot's carried shifts and bearings, bounded slip in uniform-noise worlds, the turn
slip per physics step, a process-noise floor of 1e-16 instead of 1e-12 m^2, the encoders'
quantisation as harmonic phasors with a per-run encoder phase, the drive's position loop); the
declared radius containing the body (paper-two-markers' radius 0.2 -> 0.201 m; warehouse equal);
the line-of-sight margin from the plan's certified pose bound, with schedules on a ladder of
certified errors (paper-two-markers keeps its schedule; the runs rows carry the outcome columns); the certified
bound's turning net of the encoders' quantisation (the ``certified`` step column only); the
tracking bound's steady offset from the declared wheel radius error and its corners' tails (the
promises only: ``predicted_tau`` and ``certified`` up to 1.4e-6 m on paper-two-markers, 2.3e-5 m
on warehouse; the same schedules and episodes).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

import scenarios
from sim.episode.drive import run_episode
from sim.montecarlo.rows import fix_columns, run_row, step_columns

REFERENCE = Path(__file__).with_name("single_robot_tables.npz")
NAMES = ("paper-two-markers", "warehouse")
#: float64 results of a few ulps' difference (numpy's SIMD dispatch) pass, a model's change does not
RTOL = 1e-12
#: Runs-table columns written after the reference: what a run did (``sim.episode.outcome``).
#: They only watch the episode; the reference's own columns are compared, and no other column may appear.
ADDED_RUN_COLUMNS = frozenset({"collisions", "contact_t", "contact_x", "contact_y", "contact_s", "contact_with",
                               "stuck", "stall_time", "stuck_bound", "stall_t", "stall_x", "stall_y", "stall_s",
                               "deadlocked"})


def tables(name: str, seconds: float = 3.0) -> dict[str, np.ndarray]:
    """Return a short episode's runs row (as JSON), step and fix columns, keyed ``name/part/column``."""
    sc = scenarios.load(name)
    r = run_episode(sc, 0, seed=np.random.SeedSequence(sc.seed, spawn_key=(0,)), time_limit=seconds)
    out = {f"{name}/run": np.array(json.dumps(run_row(0, "s", 0, r.summary, None), sort_keys=True))}
    for part, cols in (("steps", step_columns(0, r.steps)), ("fixes", fix_columns(0, r.fixes))):
        for k, v in cols.items():
            out[f"{name}/{part}/{k}"] = np.asarray(v)
    return out


def _close(got, want, where: str) -> None:
    if isinstance(want, float):
        assert got == pytest.approx(want, rel=RTOL, abs=0.0), where
    elif isinstance(want, dict):
        assert sorted(got) == sorted(want), where
        for k in want:
            _close(got[k], want[k], f"{where}.{k}")
    else:
        assert got == want, where


def _assert_same_tables(got: dict, want: dict, name: str) -> None:
    """Integers, flags and strings equal; floats to ``RTOL``; the runs row field by field."""
    assert sorted(got) == sorted(want)
    got_run, want_run = json.loads(str(got[f"{name}/run"])), json.loads(str(want[f"{name}/run"]))
    assert set(got_run) - set(want_run) <= ADDED_RUN_COLUMNS, f"{name}/run"
    _close({k: got_run[k] for k in want_run if k in got_run}, want_run, f"{name}/run")
    for key in sorted(want):
        if key.endswith("/run"):
            continue
        g, w = got[key], want[key]
        assert g.dtype == w.dtype and g.shape == w.shape, key
        if w.dtype.kind == "f":
            np.testing.assert_allclose(g, w, rtol=RTOL, atol=0.0, err_msg=key)
        else:
            np.testing.assert_array_equal(g, w, err_msg=key)


def _reference(name: str) -> dict:
    with np.load(REFERENCE, allow_pickle=False) as ref:
        return {k: ref[k] for k in ref.files if k.startswith(name + "/")}


@pytest.mark.parametrize("name", NAMES)
def test_single_robot_tables_are_those_before_fleets(name):
    _assert_same_tables(tables(name), _reference(name), name)


@pytest.mark.parametrize("key", ["warehouse/steps/x_var", "warehouse/fixes/n_accepted"])
def test_a_moved_column_fails(key):
    """Negative control: one step's covariance moved by 1e-9 of itself, or one count by one, fails."""
    want = _reference("warehouse")
    got = dict(want)
    moved = got[key].copy()
    i = len(moved) // 2
    moved[i] = moved[i] * (1.0 + 1e-9) if moved.dtype.kind == "f" else moved[i] + 1
    got[key] = moved
    _assert_same_tables(want, want, "warehouse")
    with pytest.raises(AssertionError):
        _assert_same_tables(got, want, "warehouse")


if __name__ == "__main__":
    # python -m tests.sim.episode.test_single_robot_identity OUT.npz: write the reference tables
    np.savez_compressed(sys.argv[1], **{k: v for name in NAMES for k, v in tables(name).items()})
