"""A fix's lines of sight are held to its own pose bound.

The PEF judges visibility with one margin for the whole floor; a fix's promise covers true
positions up to its own pose bound, which can be larger. :func:`planner.schedule.sightcheck.unseen`
refuses a measurement whose marker the laser may lose within that bound, and the schedule plans
around it. Checked against the PyBullet laser on a world written for the purpose, and on the
built-in plans the check changed (their negative control: the same plans made without the check
count on fixes it refuses).
"""

from __future__ import annotations

import numpy as np
import pytest

import pefsim
import scenarios
from planner.schedule import promise
from planner.schedule.sightcheck import unseen
from sim.physics.laser import LaserSensor
from sim.physics.world import PhysicsWorld

# a wall end (x 1.5-2.5, y 0-5) and a post M 8 m away whose line of sight from P = (1, 5.25)
# passes 0.25 m above the wall's top face
WORLD = """
name = "grazing"
[workspace]
size = [10.0, 10.0]
[[obstacles]]
center = [2.0, 2.5]
size = [1.0, 5.0]
[[markers]]
id = "M"
position = [9.0, 5.25]
[[markers]]
id = "N"
position = [9.0, 9.0]
[sensor]
relative_error = 1.0e-4
absolute_error = 0.002
max_range = 15.0
[planning]
eps_max = 0.03
"""
P = (1.0, 5.25)


@pytest.fixture(scope="module")
def grazing():
    return scenarios.loads(WORLD, "grazing.toml")


def _laser_sees(sc, xy) -> bool:
    with PhysicsWorld(sc) as w:
        laser = LaserSensor(w, sc.sensor_actual, sc.marker_positions(), sc.marker_normals())
        w.reset((xy[0], xy[1], 0.0))
        return bool(laser.visible_all()[0])


def test_a_line_of_sight_that_grazes_a_wall_within_the_pose_bound_is_refused(grazing):
    pose = np.array([[P]])
    assert not unseen(grazing, [(0,)], pose, np.array([[0.1]]))[0]
    assert unseen(grazing, [(0,)], pose, np.array([[0.3]]))[0]
    # the laser agrees: it sees M from P and from 0.1 m below, and loses it from 0.3 m below,
    # a position the larger bound admits
    assert _laser_sees(grazing, P)
    assert _laser_sees(grazing, (P[0], P[1] - 0.1))
    assert not _laser_sees(grazing, (P[0], P[1] - 0.3))


def test_every_measurement_of_a_fix_counts_and_an_unbounded_pose_is_refused(grazing):
    # fix 0 measures N then M from P: M's bound decides; fix 1 has no finite bound
    poses = np.array([[P, P], [P, P]])
    got = unseen(grazing, [(1, 0), (1, 0)], poses, np.array([[0.1, 0.3], [0.1, np.inf]]))
    assert got.tolist() == [True, True]
    got = unseen(grazing, [(1, 0), (0, 1)], poses, np.array([[0.3, 0.1], [0.1, 0.3]]))
    assert got.tolist() == [False, False]


def _refused(sc, plan) -> list[str]:
    """Return the plan's fixes and fallbacks whose promise, recomputed with the check, is none."""
    path, speed = np.asarray(plan.path, float), np.asarray(plan.schedule.speed, float)
    out = []
    for n, f in enumerate(plan.schedule.fixes):
        rows = [(f.markers, "fix")] + [(fb, f"fallback {q}") for q, (fb, t) in
                                       enumerate(zip(f.fallbacks, f.fallback_tau, strict=True))
                                       if fb and np.isfinite(t)]
        for subset, what in rows:
            pred, _, _ = promise.predict(sc, path, speed, np.array([f.s]), [subset], np.array([f.estimate]))
            if not np.isfinite(pred[0]):
                out.append(f"fix {n} {what} {subset} at s = {f.s:.2f} m")
    return out


@pytest.mark.e2e
def test_the_plan_counts_on_no_line_of_sight_its_pose_bounds_may_lose():
    sc = pefsim.load("warehouse-reflectors")
    plan = pefsim.plan(sc, 0)
    assert len(plan.schedule.fixes) > 100
    assert _refused(sc, plan) == []


@pytest.mark.e2e
def test_negative_control_the_plan_made_without_the_check_counts_on_lines_it_may_lose(monkeypatch):
    sc = pefsim.load("warehouse-reflectors")
    with monkeypatch.context() as m:
        m.setattr(promise, "unseen", lambda scenario, subsets, poses, delta: np.zeros(len(subsets), bool))
        plan = pefsim.plan(sc, 0)
    assert _refused(sc, plan)


def test_seen_within_remembers_rows_by_point_and_margin(grazing):
    """Rows asked again (the same point at the same margin step) are the rows computed afresh.

    Points near the grazing line of sight at margins either side of its 0.25 m clearance, asked
    in two overlapping calls; each answer is compared with a call on an emptied memo. Negative
    control: a memo that forgot the margin in its key answers the second call with the first
    call's rows, which the comparison catches.
    """
    from planner.schedule import sightcheck

    pts = np.array([P, (1.0, 5.3), (1.2, 5.25), (0.8, 5.2)])
    first, second = np.full(4, 0.1), np.array([0.1, 0.4, 0.1, 0.4])

    def fresh(points, delta):
        sightcheck._SEEN.clear()
        return sightcheck.seen_within(grazing, points, delta)

    want1, want2 = fresh(pts, first), fresh(pts[::-1], second[::-1])
    assert (want1 != want2[::-1]).any()  # the margin decides a line of sight here
    sightcheck._SEEN.clear()
    np.testing.assert_array_equal(sightcheck.seen_within(grazing, pts, first), want1)
    np.testing.assert_array_equal(sightcheck.seen_within(grazing, pts[::-1], second[::-1]), want2)
    # negative control: a memo whose rows ignore the margin (every row filed under each step too)
    sightcheck._SEEN.clear()
    sightcheck.seen_within(grazing, pts, first)
    for memo in sightcheck._SEEN.values():
        for rows in memo.values():
            steps = {step for step, _ in rows}
            for (_, name), row in list(rows.items()):
                for step in steps | {int(np.ceil(0.4 / sightcheck.MARGIN_STEP - 1e-9))}:
                    rows[(step, name)] = row
    wrong = sightcheck.seen_within(grazing, pts[::-1], second[::-1])
    assert (wrong != want2).any()
