"""A scenario without [[robots]] gives the tables it gave before fleets existed, bit for bit.

The fleet work was checked against digests computed with the code of commit 3bb1324 (main before
it), by the same function, on a 3 s episode of task 0 with run 0's seed: equal. The same wave then
changed single-robot episodes on purpose twice (each scheduled fix near the goal is taken there;
the promise is derived from the plan's certified estimate error, which moves the schedules), so the
digests below are those of the merge of the three; a change that moves any number of a
single-robot episode again (the laser's ray ends, the posts, the streams) must say why here.

Issue 23 (coverage of random-7-008): the snapshot's carried-shift variance counts the slip of the
odometry reads a shift actually spans (``WheelOdometry.slip_weight``) instead of n equal
increments. Only the fixes' snapshot position, error and covariance moved (steps and every other
fix column hashed equal before and after, on both scenarios).

Issue 23 again: the snapshot turns a fix's shifts into the world frame with the filter's heading
from before the fix's first update (the heading after them is correlated with the fix's own range
noise), and its covariance counts the errors the carried ranges share
(``estimators.fault.carried.shift_cov``); the fault area keeps the heading after the updates.
Only the fixes' snapshot position, error and covariance moved; steps and every other fix column
(fault diameter, containment, promise) hashed equal before and after, on both scenarios and on
warehouse-reflectors. (Per-column hashes against commit f3437d7; the digests first pinned with this
change came from a tree that also turned the fault area with the pre-fix heading, whose
``fault_diameter`` differs.) The sight check of the schedule (``planner.schedule.sightcheck``) moved
no column of either episode.

Issue 23 (containment of random-23-037): a bounded-noise world's floor slips within a bound
(uniform draws of the declared std, ``WheelOdometry(bounded=True)``): both scenarios are uniform,
so the odometry readings, and with them every column, moved.

Issue 23 (random-23-029's corner): the filter's turn slip per read follows the physics steps
the read spans (``sim.physics.turn_lag``): a fix's reads between control ticks moved the
estimate, and with it every column.

Issue 23 (random-23-029's heading): the process noise's numerical floor went from 1e-12 to
1e-16 m^2 per wheel and read (``estimators.motion.VARIANCE_FLOOR``): the filter's covariance, and
with it every column that depends on the estimate, moved.

The scalar update's products are loops instead of numba's BLAS-backed ``@`` (9 s of compilation
on a cold cache, 1.4 s now), and it writes one triangle of P into both: the sums run in another
order, so covariances moved in their last bits (paper-two-markers, seed 5: at most 2e-21 m^2 in
P and 7e-15 in the NEES; the estimate equal), and with them the hashes.

Issue 23 (random-23-016's N-run tests and coverage): the encoder residuals are the phasors of
their first 8 harmonics, turned at each read by the wheels' commanded turn
(``estimators.encoder_phase``), and the snapshot weighs a fix's shifts and carried bearings
with the count errors of their fractional turns (``estimators.fault.carried.count_cov``): the
estimate, its covariance and the snapshot moved, and with them every column. (The scalar
update's Joseph form is expanded to O(n^2) for the larger state, equal in exact arithmetic.)

Issue 23 (the runs of a sweep made the same quantisation errors): each run draws its encoders'
phase on the wheels from its start stream (``sim.episode.drive.encoder_phases``, after the
start pose, whose draw is unchanged), and the filter starts with the residuals unknown: the
counts, the estimate and everything after them moved.

Issue 23 (five random worlds overconfident): the filter no longer turns the residuals by the
commanded turn; each read's new residual is independent of the last, and the state holds one
residual per wheel instead of 17 (``estimators.motion_quantised``). The covariance moved; over
20 s of both scenarios the estimate is bit for bit that of the 17-entry blocks with their
phasors renewed at every read, the covariance within 1e-19 of it.

Issue 23 (random-23-008's N-run NEES, -030's cross-track): each residual keeps, across a read,
the sawtooth's correlation over the read's predicted fractional turn (an AR(1),
``estimators.motion_quantised.read_correlation``): the estimate and its covariance moved.

Issue 23 (random-23-000's NEES, -030's cross-track): each wheel's last 8 residuals are states, a
new one predicted from them with the sawtooth's covariances over the predicted turns, averaged
over a tracking error that grows with the lag (``estimators.motion_quantised``): the estimate and
its covariance moved. (The gate's rule for two markers in a row does not act in these 3 s.)
Since then the reference is the tables themselves (``single_robot_tables.npz``, written by this
module run as a script), not their SHA-256: on a machine whose numpy dispatches its float64
transcendental functions to AVX-512 (numpy's ``X86_V4`` features; the digests were pinned on an
``X86_V3`` machine) ``certified`` and ``predicted_tau`` came out 1 ulp off (at most 4.4e-16
relative; with ``NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL"`` the same machine gave the pinned
digests). The planner computes those columns and nothing in the episode feeds back into them, so
the ulps do not grow. Integers, flags and strings are compared exactly; floats to ``RTOL``: the
summation-order changes above (2e-21 m^2 in P) pass it, any change of the model does not.

Issue 23 (random-23-016's and -033's NIS, pessimistic): the drive holds each wheel to its
command's integral (``sim.physics.robot.DRIVE_GAIN``), and the filter carries each wheel's
residual as the phasors of its first 8 harmonics, constant in the commanded frame, and a
remainder (``estimators.motion_quantised``): the motion, the counts, the estimate and every
column after them moved. The tables were written again (with ``NPY_DISABLE_CPU_FEATURES="X86_V4
AVX512_ICL"``, as before). Then a read of span 0 (the first read of an episode, reads at the
goal) keeps the residual blocks instead of drawing a fresh residual difference: the estimate's
covariance from the first read on moved, and with it every column; written again the same way.

Issue 45 (the declared radius contains the simulated body, ``scenarios.body``): paper-two-markers'
wheels reach 0.20005 m, so its radius went from 0.2 to 0.201 m, and the chassis, fitted inside
the radius, from 0.2260 to 0.2296 m long: its inertia moved the true pose by at most 0.4 um and
the heading by 1.8 urad in these 3 s, and with them every column; warehouse's tables stayed equal
bit for bit. Written again the same way.

The line-of-sight margin from the plan's certified pose bound, and schedules searched on a fixed
ladder of certified errors (``planner.schedule``): where no rung plans at speed the one that slows
the drive least is taken, which for paper-two-markers is its eps_max rung, the schedule it had
before the ladder: its steps and fixes are equal to those before the ladder; the runs rows carry
the outcome columns. Written again the same way.
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
#: Runs-table columns written after the reference: what a run did (``sim.episode.outcome``, issue 45).
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
