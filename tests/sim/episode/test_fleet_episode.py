"""A fleet episode: two robots whose paths cross drive together, one waits, nobody touches anybody."""

from __future__ import annotations

import numpy as np
import pytest

from scenarios import loads
from sim.episode.drive import prepare, run_episode
from sim.episode.fleet import prepare_fleet, run_fleet_episode
from tests.sim.fleets import CROSS, markers_toml


@pytest.fixture(scope="module")
def crossing():
    sc = loads(CROSS, source="cross.toml")
    prepared = prepare_fleet(sc)
    return sc, prepared, run_fleet_episode(sc, seed=5, prepared=prepared)


def test_both_arrive_without_touching_and_one_waits(crossing):
    sc, prepared, res = crossing
    assert res.collisions == 0
    assert [r.name for r in res.robots] == ["east", "north"]
    for r in res.robots:
        s = r.result.summary
        assert s["reached"] and s["collisions"] == 0 and s["robot"] == r.name
        assert s["status"] == "ok" and not s["stuck"] and not s["deadlocked"]   # its waits are legitimate
        assert s["violations"] == 0 and 0.0 < s["arrival"] <= s["duration"] == res.duration
    assert max(r.wait_time for r in res.robots) > 0.5, "the crossing makes one of them wait"
    # the plan's waits ride along for validate's comparison: all of them at least the longest one
    for r, rp in zip(res.robots, prepared.plan.robots, strict=True):
        s = r.result.summary
        assert s["predicted_wait_time"] == rp.timeline.wait_time >= s["predicted_wait"] - 1e-9
    # the closest the two got, over the control steps they shared
    a, b = (r.result.steps.true_pose[:, :2] for r in res.robots)
    n = min(len(a), len(b))
    assert np.hypot(*(a[:n] - b[:n]).T).min() > 2 * sc.robot.radius


def test_robot_zero_draws_what_a_single_robot_draws(crossing):
    sc, prepared, res = crossing
    single = run_episode(sc, 0, seed=5, prepared=prepare(sc, 0, pef=prepared.pef), time_limit=0.5)
    assert np.array_equal(res.robots[0].result.steps.true_pose[0], single.steps.true_pose[0])
    assert not np.array_equal(res.robots[1].result.steps.true_pose[0] - sc.dock("C").pose,
                              res.robots[0].result.steps.true_pose[0] - sc.dock("A").pose)


def test_reservations_run_ahead_of_the_robot(crossing):
    _, _, res = crossing
    for r in res.robots:
        t, a, b = r.reserved.T
        assert len(t) > 100 and np.all(np.diff(t) > 0)
        assert np.all(b >= a - 0.2)   # held up to where it may drive, from just behind itself
        assert np.all(np.diff(b) >= -1e-9)   # a reservation only grows at its front


def test_fix_notes_name_the_robot_that_hid_a_marker(crossing):
    sc, _, res = crossing
    for j, r in enumerate(res.robots):
        notes = r.result.fixes.notes
        assert len(notes) == len(r.result.fixes.t)
        for note in notes:
            assert all(0 <= m < len(sc.markers) and other == 1 - j for m, other in note.hidden.items())
            assert 0.0 <= note.p_block_robot <= 1.0   # the plan's prediction for the fix
        assert r.result.summary["robot_blocked"] >= sum(len(n.hidden) for n in notes)


def test_the_recording_holds_every_robot_and_the_hidden_lines_of_sight(crossing, tmp_path):
    from rerun.chunk import RrdReader

    from interop.recording.fleet import write_fleet_rrd

    sc, _, res = crossing
    path = write_fleet_rrd(tmp_path / "fleet.rrd", sc, res)
    entities = {str(ch.entity_path) for ch in RrdReader(str(path)).store().stream().to_chunks()}
    for name in ("east", "north"):
        assert {f"/world/robots/{name}/true", f"/world/robots/{name}/estimate", f"/world/robots/{name}/fix/rays",
                f"/world/robots/{name}/fix/fault_area", f"/world/robots/{name}/reserved",
                f"/metrics/{name}/error"} <= entities
    hidden = sum(r.result.summary["robot_blocked"] for r in res.robots)
    assert ("/world/blocked" in entities) == (hidden > 0)


def test_a_robot_drives_its_tasks_one_after_another():
    text = CROSS.replace('[[robots]]\nname = "east"\ntasks = [0]', '[[robots]]\nname = "east"\ntasks = [0, 2]')
    text = text.replace('[[tasks]]\nfrom = "A"', '[[docks]]\nname = "E"\npose = [10.5, 10.5, 90.0]\n'
                        '[[tasks]]\nfrom = "A"', 1)
    text = text.replace("[[robots]]", '[[tasks]]\nfrom = "B"\nto = "E"\n[[robots]]', 1)
    sc = loads(text, source="chain.toml")
    prepared = prepare_fleet(sc)
    east = prepared.plan.robots[0]
    assert [(p.start, p.goal) for p in east.plans] == [("A", "B"), ("B", "E")]
    res = run_fleet_episode(sc, seed=5, prepared=prepared)
    assert res.collisions == 0
    s = res.robots[0].result.summary
    assert s["reached"] and s["violations"] == 0
    assert np.hypot(*(res.robots[0].result.steps.true_pose[-1, :2] - sc.dock("E").position)) < 0.1
    # fixes of both tasks, in time order
    t = res.robots[0].result.fixes.t
    assert np.all(np.diff(t) > 0) and s["scheduled_fixes"] == sum(len(p.schedule.fixes) for p in east.plans)


@pytest.mark.e2e
def test_the_built_in_fleet_drives_without_a_collision():
    from scenarios import load

    sc = load("warehouse-fleet")
    res = run_fleet_episode(sc, seed=np.random.SeedSequence(sc.seed, spawn_key=(0,)))
    assert res.collisions == 0
    assert all(r.result.summary["reached"] for r in res.robots)
    # the traffic-aware schedule keeps its own markers clear of the others (robot_blocked counts
    # those); every other line of sight a robot hid is noted per fix
    hidden = sum(len(n.sight_hidden) for r in res.robots for n in r.result.fixes.notes if n is not None)
    assert hidden > 0, "the robots hide reflectors"
    assert max(r.wait_time for r in res.robots) > 1.0, "the routes cross"


def test_pefsim_run_prints_every_robot(tmp_path, capsys):
    import json

    import cli

    path = tmp_path / "cross.toml"
    path.write_text(CROSS)
    assert cli.main(["run", str(path), "--json", "--tum", str(tmp_path / "tum")]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["collisions"] == 0 and [r["robot"] for r in out["robots"]] == ["east", "north"]
    assert all(r["reached"] for r in out["robots"])
    # each robot's trajectories in a folder named for it, a row per logged step
    for r in out["robots"]:
        for name in ("groundtruth.txt", "estimate.txt"):
            lines = (tmp_path / "tum" / r["robot"] / name).read_text().splitlines()
            assert len([x for x in lines if not x.startswith("#")]) == r["steps"]
    assert cli.main(["run", str(path), "--task", "1"]) == 2
    assert "task: " in capsys.readouterr().err


@pytest.mark.e2e   # a sweep, its report's figures and the validation: ~40 s
def test_mc_and_validate_a_fleet(tmp_path, capsys):
    import json

    import cli
    from sim.montecarlo import results

    path = tmp_path / "cross.toml"
    path.write_text(CROSS)
    out = tmp_path / "mc"
    assert cli.main(["mc", str(path), "--runs", "1", "--workers", "1", "--out", str(out), "--rrd-every", "1",
                     "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert (summary["runs"], summary["robots"], summary["collisions"]) == (2, 2, 0)
    runs = results.read_runs(out)
    assert runs.column("robot").to_pylist() == ["east", "north"]
    assert (out / "recordings" / "run-000000.rrd").stat().st_size > 0
    code = cli.main(["validate", "--from", str(out), "--json"])
    report = json.loads(capsys.readouterr().out)
    assert code in (0, 1) and {c["name"] for c in report["checks"]} >= {"containment", "promise", "plan"}


# Two robots swap the ends of a 2 m wide, 14 m long corridor (the head-on case of zone control,
# driven in physics), the second at half the speed.
CORRIDOR = """
name = "corridor"
seed = 2
[workspace]
size = [20.0, 8.0]
[[obstacles]]
center = [10.0, 1.5]
size = [14.0, 3.0]
[[obstacles]]
center = [10.0, 6.5]
size = [14.0, 3.0]
""" + markers_toml({"W": (0.0, 4.0), "E": (20.0, 4.0), "SW": (0.0, 0.0), "NE": (20.0, 8.0), "NW": (0.0, 8.0),
                    "SE": (20.0, 0.0), "M0": (6.0, 3.0), "M1": (10.0, 5.0), "M2": (14.0, 3.0),
                    "M3": (8.0, 5.0), "M4": (12.0, 3.0)}) + """[sensor]
[robot]
[planning]
eps_max = 0.05
resolution = 0.2
[[docks]]
name = "A"
pose = [1.2, 1.2, 90.0]
[[docks]]
name = "B"
pose = [18.8, 6.8, 90.0]
[[docks]]
name = "C"
pose = [18.8, 1.2, 90.0]
[[docks]]
name = "D"
pose = [1.2, 6.8, 90.0]
[[tasks]]
from = "A"
to = "B"
[[tasks]]
from = "C"
to = "D"
[[robots]]
name = "fast"
tasks = [0]
[[robots]]
name = "slow"
tasks = [1]
max_speed = 0.5
"""


@pytest.mark.e2e   # two episodes' worth of driving: ~10 s
def test_head_on_in_a_corridor_at_different_speeds():
    sc = loads(CORRIDOR, source="corridor.toml")
    prepared = prepare_fleet(sc)
    res = run_fleet_episode(sc, seed=1, prepared=prepared)
    assert res.collisions == 0 and all(r.result.summary["reached"] for r in res.robots)
    a, b = (r.result.steps.true_pose[:, :2] for r in res.robots)
    n = min(len(a), len(b))
    assert np.hypot(*(a[:n] - b[:n]).T).min() > 2 * sc.robot.radius
    # the slow one waits at its end of the corridor while the fast one passes: the fast one is in
    # the corridor for at least 14 m / 1 m/s = 14 s from about 1 s after the start, the slow one
    # reaches its end after at least 3 m / 0.5 m/s = 6 s: it waits at least 9 s, less its braking
    slow = res.robots[1]
    assert slow.name == "slow" and slow.wait_time > 5.0 and res.robots[0].wait_time < slow.wait_time
