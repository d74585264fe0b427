"""Episodes: every built-in task reaches its goal; determinism; TUM output; bad input."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

import scenarios
from estimators import motion_quantised
from interop.export.tum import read_tum
from sim.episode.drive import prepare, run_episode
from tests.sim.episode.digest import digest

#: episodes on the big floors (a hall, the warehouse's second task and its reflector variant): the e2e tier
LONG_TASKS = {("hall", 0), ("hall", 1), ("warehouse-reflectors", 0), ("warehouse-reflectors", 1), ("warehouse", 1)}
#: a fleet's tasks driven one robot at a time: the e2e tier (tests/sim/episode/test_fleet_episode.py drives the
#: fleet itself, a crossing in the fast tier)
FLEETS = {name for name in scenarios.builtin_names() if scenarios.load(name).robots}
TASKS = [pytest.param(name, i, id=f"{name}-{i}",
                      marks=[pytest.mark.e2e] if (name, i) in LONG_TASKS or name in FLEETS else [])
         for name in scenarios.builtin_names() for i in range(len(scenarios.load(name).tasks))]


@pytest.fixture(scope="module")
def prepared():
    cache = {}

    def get(name, task):
        if (name, task) not in cache:
            s = scenarios.load(name)
            cache[(name, task)] = (s, prepare(s, task))
        return cache[(name, task)]
    return get


@pytest.mark.parametrize("name,task", TASKS)
def test_every_builtin_task_reaches_its_goal(prepared, name, task):
    s, p = prepared(name, task)
    r = run_episode(s, task, seed=11, prepared=p)
    goal = np.array(s.dock(s.tasks[task].goal).position)
    assert r.summary["reached"], r.summary
    assert np.hypot(*(r.steps.true_pose[-1, :2] - goal)) < 0.05 + s.planning.eps_max
    assert r.summary["fixes"] > 0 and len(r.fixes.fault_polygons) == r.summary["fixes"]
    # with the declared sensor equal to the actual one, bounded noise: containment at every fix
    assert r.fixes.contained.all()
    assert r.summary["violations"] == 0, r.summary


def test_same_seed_same_arrays_after_world_reset(prepared):
    from sim.physics.world import PhysicsWorld

    s, p = prepared("paper-two-markers", 0)
    with PhysicsWorld(s) as world:
        a = run_episode(s, 0, seed=3, prepared=p, world=world)
        other = run_episode(s, 0, seed=4, prepared=p, world=world)
        b = run_episode(s, 0, seed=3, prepared=p, world=world)
    fresh = run_episode(s, 0, seed=3, prepared=p)
    assert digest(a) == digest(b) == digest(fresh)
    # negative control: another seed gives other numbers
    assert digest(other) != digest(a)
    n = min(len(a.steps.t), len(other.steps.t))  # runs may end a step apart
    diff = np.flatnonzero(np.any(a.steps.est_pose[:n] != other.steps.est_pose[:n], axis=1))
    assert diff.size > 0


SCRIPT = """
import hashlib, numpy as np, scenarios
from sim.episode.drive import run_episode
from tests.sim.episode.digest import digest
r = run_episode(scenarios.load("paper-two-markers"), 0, seed=np.random.SeedSequence(5, spawn_key=(2,)))
print(digest(r))
"""


@pytest.mark.e2e  # two new processes, each importing everything and driving an episode
def test_same_seed_same_arrays_in_fresh_processes():
    out = [subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, check=True).stdout
           for _ in range(2)]
    assert out[0] == out[1] and len(out[0].strip()) == 64


def test_tum_files_reproduce_the_rmse(tmp_path):
    from cli import main

    assert main(["run", "paper-two-markers", "--seed", "2", "--tum", str(tmp_path), "--json"]) == 0
    gt, est = read_tum(tmp_path / "groundtruth.txt"), read_tum(tmp_path / "estimate.txt")
    assert np.array_equal(gt[:, 0], est[:, 0]) and gt.shape[1] == 8
    rmse = np.sqrt(np.mean(np.sum((gt[:, 1:3] - est[:, 1:3]) ** 2, axis=1)))
    s = scenarios.load("paper-two-markers")
    r = run_episode(s, 0, seed=2)
    assert rmse == pytest.approx(r.summary["rmse"], rel=1e-6, abs=1e-9)
    # unit quaternions about z
    assert np.allclose(np.linalg.norm(est[:, 4:8], axis=1), 1.0)


HIDDEN = """
name = "hidden"
[workspace]
size = [10.0, 10.0]
[[obstacles]]
center = [5.0, 2.0]
size = [0.4, 3.9]
[[markers]]
id = "M1"
position = [9.0, 1.0]
[[markers]]
id = "M2"
position = [9.0, 3.0]
[[markers]]
id = "M3"
position = [9.0, 9.0]
[[markers]]
id = "M4"
position = [1.0, 9.0]
[sensor]
max_range = 6.0
[planning]
eps_max = 0.05
[[docks]]
name = "A"
pose = [2.0, 2.0, 0.0]
[[docks]]
name = "B"
pose = [8.0, 6.0, 0.0]
[[tasks]]
from = "A"
to = "B"
"""


def _cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "cli", *args], capture_output=True, text=True, cwd=cwd)


@pytest.mark.parametrize("case,text,args,pattern", [
    ("unknown task", None, ["--task", "5"], r"task 5: expected a task index in 0\.\.0"),
    ("no markers at start", HIDDEN, [], r"hidden\.toml: tasks\[0\] \(A -> B\): 0 marker\(s\) visible from dock A"),
    ("dock unreachable", HIDDEN.replace("max_range = 6.0", "max_range = 20.0").replace(
        'center = [5.0, 2.0]\nsize = [0.4, 3.9]', 'center = [5.0, 9.0]\nsize = [0.4, 0.4]\n[[obstacles]]\n'
                                       'center = [8.0, 7.5]\nsize = [3.0, 0.3]\n[[obstacles]]\n'
                                       'center = [8.0, 4.5]\nsize = [3.0, 0.3]\n[[obstacles]]\n'
                                       'center = [6.6, 6.0]\nsize = [0.3, 3.2]').replace(
        "[sensor]", '[[markers]]\nid = "M5"\nposition = [10.0, 5.0]\n[[markers]]\nid = "M6"\n'
                    'position = [10.0, 7.0]\n[sensor]'),
     [], r"hidden\.toml: tasks\[0\] \(A -> B\): .*B"),
])
def test_bad_input_is_one_line_exit_2(tmp_path, case, text, args, pattern):
    import re

    path = "paper-two-markers"
    if text is not None:
        path = str(tmp_path / "hidden.toml")
        (tmp_path / "hidden.toml").write_text(text)
    p = _cli("run", path, *args)
    assert p.returncode == 2, (p.stdout, p.stderr)
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in p.stderr, p.stderr
    assert re.search(pattern, lines[0]), lines[0]


def test_ekf_cross_checks_against_snapshot_fixes(prepared):
    """The EKF beats and agrees with the snapshot fixes.

    At each fix the filter, which fuses the fix with everything before it, must be closer to the
    truth than the fix alone, and the two must agree within the snapshot's own covariance.
    """
    s, p = prepared("paper-docks", 0)
    r = run_episode(s, 0, seed=11, prepared=p)
    f, st = r.fixes, r.steps
    idx = np.searchsorted(st.t, f.t, side="left")  # first control step at or after the fix
    keep = idx < len(st.t)
    idx = idx[keep]
    ekf_err = st.est_pose[idx, :2] - st.true_pose[idx, :2]
    snap_err = f.snapshot[keep] - f.true_position[keep]
    assert np.mean(np.sum(ekf_err**2, axis=1)) < np.mean(np.sum(snap_err**2, axis=1))
    d = ekf_err - snap_err  # errors, not positions: the step may come up to 1/60 s after the fix
    m2 = np.einsum("fi,fi->f", d, np.linalg.solve(f.snapshot_cov[keep], d[:, :, None])[:, :, 0])
    # Cov(ekf - snapshot) = P_snapshot - P_ekf <= P_snapshot, so m2 is at most chi2(2)-like; its
    # 99.9 % quantile is 13.8. With ~100 fixes, allow at most 1 exceedance (P(>=2) < 0.5 %).
    assert np.sum(m2 > 13.8) <= 1, np.sort(m2)[-5:]


def test_bearings_taken_while_turning_keep_the_truth_in_the_fault_area():
    """Bearings taken while turning still bound the truth.

    Each bearing is measured at its own heading; carried to the fix time, the realised fault
    area must still hold the truth (bounded noise), and the per-fix bookkeeping adds up.
    """
    text = scenarios.load("paper-docks").text.replace('noise = "uniform"',
                                                       'noise = "uniform"\nbearing_error_deg = 0.05')
    s = scenarios.loads(text, source="paper-docks-bearings.toml")
    r = run_episode(s, 0, seed=0)
    assert r.summary["reached"] and r.summary["fixes"] > 50
    assert r.fixes.contained.all(), np.flatnonzero(~r.fixes.contained)
    done = r.summary["fixes"] + r.summary["skipped_fixes"] + r.summary["merged_fixes"]
    assert done == r.summary["scheduled_fixes"] and r.summary["unreached_fixes"] == 0


def test_fixes_the_follower_stops_short_of_are_taken_at_the_goal(prepared):
    """The follower is done 5 cm before the path's end; the schedule's fixes beyond are taken at the goal."""
    s, p = prepared("paper-two-markers", 0)
    r = run_episode(s, 0, seed=5, prepared=p)
    sched = p.plan.schedule.fixes
    beyond = sum(f.s > p.plan.s[-1] - 0.05 for f in sched)  # 0.05 m: PurePursuit.goal_tolerance
    assert beyond > 0  # else this test tests nothing
    assert r.summary["fixes"] == len(sched) and r.summary["merged_fixes"] == r.summary["skipped_fixes"] == 0
    goal = np.array(s.dock(s.tasks[0].goal).position)
    held = np.hypot(*(r.fixes.true_position[-beyond:] - goal).T)
    assert np.all(held < 0.05 + s.planning.eps_max), held
    assert r.fixes.t[-1] <= r.steps.t[-1]   # the episode ends after its last fix


def test_fixes_after_the_time_limit_are_counted_unreached(prepared):
    s, p = prepared("paper-two-markers", 0)
    r = run_episode(s, 0, seed=5, prepared=p, time_limit=3.0)
    sm = r.summary
    assert not sm["reached"] and sm["unreached_fixes"] > 0
    assert sm["fixes"] + sm["merged_fixes"] + sm["skipped_fixes"] + sm["unreached_fixes"] == sm["scheduled_fixes"]


def test_a_measurement_on_a_control_tick_reads_the_odometry_once(monkeypatch):
    """No physics step is read twice: a measurement falling due on a control tick uses the tick's read.

    A second read at the same step reports zero travel, and the filter's predict would renew each
    wheel's quantisation residual where the encoder's is unchanged (random-23-016:
    a fix's measurements 0.015 s apart fell on control ticks). With ``measurement_time`` one
    control period every measurement of a fix falls on a tick. The control tick reads in
    compiled code, a measurement's own read through ``WheelOdometry.update``: both are recorded
    with the physics step they read at.
    """
    from sim.episode.control_tick import ControlTick
    from sim.physics.odometry import WheelOdometry
    from sim.physics.world import PhysicsWorld

    current, reads = {"world": None}, []
    step, update, tick = PhysicsWorld.step, WheelOdometry.update, ControlTick.__call__

    def stepping(self, n=1):
        current["world"] = self
        return step(self, n)

    def recorded(kind, f):
        def read(self, *args, **kwargs):
            if current["world"] is not None:
                reads.append((current["world"].steps, kind))
            return f(self, *args, **kwargs)
        return read

    monkeypatch.setattr(PhysicsWorld, "step", stepping)
    monkeypatch.setattr(WheelOdometry, "update", recorded("measurement", update))
    monkeypatch.setattr(ControlTick, "__call__", recorded("tick", tick))
    text = scenarios.load("paper-two-markers").text.replace("measurement_time = 0.02",
                                                             f"measurement_time = {4 / 240!r}")
    sc = scenarios.loads(text, source="tick-aligned.toml")
    r = run_episode(sc, 0, seed=np.random.SeedSequence(sc.seed, spawn_key=(0,)), time_limit=3.0)
    assert len(r.fixes.t) >= 5
    steps = np.array([s for s, _ in reads])
    assert sum(kind == "tick" for _, kind in reads) > 100
    assert np.all(np.diff(steps) > 0), f"steps read twice: {np.unique(steps[1:][np.diff(steps) == 0])[:5]}"


def test_each_run_draws_its_encoder_phases_and_the_filter_is_not_told():
    # An incremental encoder counts from wherever its wheel stopped: the run's phase is drawn from
    # its start stream (after the start pose), and the filter starts with the residuals unknown,
    # each at the variance of a residual uniform over a tick (tick^2 / 12).
    from sim.episode.driver import encoder_phases, episode_localizer
    from sim.episode.driver import streams as _streams

    phases = [encoder_phases(_streams(np.random.SeedSequence(7, spawn_key=(k,)))[0]) for k in range(400)]
    again = encoder_phases(_streams(np.random.SeedSequence(7, spawn_key=(0,)))[0])
    np.testing.assert_array_equal(phases[0], again)
    p = np.array(phases)
    assert p.shape == (400, 2) and np.all((p >= 0.0) & (p < 1.0))
    # uniform: each decile of each wheel's phase holds 40 +- 3.4 sigma of 400 draws (p < 1e-3 each)
    def uniform(p):
        counts = np.stack([np.histogram(p[:, w], bins=10, range=(0.0, 1.0))[0] for w in range(2)])
        return bool(np.all(np.abs(counts - 40) < 3.4 * math.sqrt(400 * 0.1 * 0.9)))

    assert uniform(p), p
    assert not uniform(np.full_like(p, 0.5))   # negative control: every run at one phase, as before
    sc = scenarios.load("paper-two-markers")
    loc = episode_localizer(sc, np.zeros(3), np.eye(3) * 1e-6)
    tick = 2 * math.pi * sc.robot.wheel_radius / sc.robot.encoder_ticks
    assert np.all(loc.full_x[4:] == 0.0)
    assert loc.full_x.size == 4 + 2 * motion_quantised.BLOCK
    np.testing.assert_allclose(np.diag(loc.full_P)[4:], tick**2 / 12 * np.tile(motion_quantised.block_prior(), 2),
                               rtol=1e-12)
