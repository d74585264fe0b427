"""Blocking prediction: the ray's low part, a body on it, the timing spread, and the schedule's use of it."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.special import ndtr

from planner.fleet.blocking import (
    FINE_DT,
    POS_SD,
    STAND_BACK,
    STAND_SD,
    TimingModel,
    Track,
    block_probability,
    combine,
    lag_difference,
    low_segment,
    tie,
)
from planner.fleet.zones import Timeline


def _timeline(xy, t, waiting=None, holder=None):
    xy = np.asarray(xy, float)
    return Timeline(t=np.asarray(t, float), s=np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))]),
                    xy=xy, waiting=np.zeros(len(t), bool) if waiting is None else np.asarray(waiting, bool),
                    wait_time=0.0, end_time=float(t[-1]), holder=None if holder is None else np.asarray(holder, int))


def _track(xy, t, radius=0.4, height=0.5, waiting=None):
    return Track.of(_timeline(xy, t, waiting), 0.0, radius, height)


def test_the_low_part_of_a_ray_is_where_it_passes_below_the_body_top():
    o, m = np.array([[0.0, 0.0]]), np.array([[10.0, 0.0]])
    # laser 0.5 m, reflector 0.3 m: a 0.5 m body is above the whole ray
    a, b, some = low_segment(o, 0.5, m, np.array([0.3]), 0.5)
    assert some[0] and np.allclose(a, [[0, 0]]) and np.allclose(b, [[10, 0]])
    # a 0.4 m body: the ray is below 0.4 m from half way on
    a, b, some = low_segment(o, 0.5, m, np.array([0.3]), 0.4)
    assert some[0] and np.allclose(a, [[5, 0]]) and np.allclose(b, [[10, 0]])
    # a 0.25 m body is below the whole ray; a reflector above every robot (NaN) is never low
    assert not low_segment(o, 0.5, m, np.array([0.3]), 0.25)[2][0]
    assert not low_segment(o, 0.5, m, np.array([np.nan]), 5.0)[2][0]
    # a reflector above the laser: low from the laser up to where the ray passes the top
    a, b, some = low_segment(o, 0.5, m, np.array([1.5]), 1.0)
    assert some[0] and np.allclose(a, [[0, 0]]) and np.allclose(b, [[5, 0]])


def test_a_body_standing_on_the_ray_hides_it_and_beside_it_does_not():
    t = np.arange(0.0, 10.0, 0.1)
    on = _track(np.tile([5.0, 0.2], (len(t), 1)), t)
    edge = _track(np.tile([5.0, 0.45], (len(t), 1)), t)
    off = _track(np.tile([5.0, 1.0], (len(t), 1)), t)   # 1 m off the ray, radius 0.4
    args = (np.array([[0.0, 0.0]]), 0.5, np.array([[10.0, 0.0]]), np.array([0.3]), np.array([4.0]),
            np.zeros(1), np.full(1, 2e-8))
    # where it stands is spread by POS_SD across the shadow's edge
    assert block_probability(on, *args)[0] == pytest.approx(ndtr(0.2 / POS_SD))
    assert block_probability(edge, *args)[0] == pytest.approx(ndtr(-0.05 / POS_SD))
    assert block_probability(off, *args)[0] == 0.0


def test_a_body_inside_the_ray_s_box_but_far_from_the_ray_hides_nothing():
    # the diagonal ray's bounding box holds the body, 5.7 m off the ray: a window with no sample
    # in reach (this used to raise an IndexError on an empty set of pairs)
    t = np.arange(0.0, 10.0, 0.1)
    corner = _track(np.tile([9.0, 1.0], (len(t), 1)), t)
    p = block_probability(corner, np.array([[0.0, 0.0]]), 0.5, np.array([[10.0, 10.0]]), np.array([0.3]),
                          np.array([4.0]), np.zeros(1), np.full(1, 0.04))
    assert p.shape == (1,) and p[0] == 0.0


def test_a_crossing_hides_the_ray_for_the_timing_spread_s_share_of_its_passage():
    # a body crossing the ray at right angles at v = 1 m/s, on it from t = 4.6 s to 5.4 s (radius 0.4)
    v, r, sd = 1.0, 0.4, 0.3
    t = np.arange(0.0, 10.0 + 1e-9, 0.1)
    track = _track(np.column_stack([np.full(len(t), 5.0), -5.0 + v * t]), t, radius=r)
    when = np.array([3.0, 4.5, 5.0, 5.6, 7.0])
    p = block_probability(track, np.zeros((5, 2)), 0.5, np.tile([10.0, 0.0], (5, 1)), np.full(5, 0.3), when,
                          np.zeros(5), np.full(5, sd**2))
    # crossing at right angles, the position spread along the motion adds (POS_SD / v)^2 to the timing's
    total = math.hypot(sd, POS_SD / v)
    exact = ndtr((5.0 + r / v - when) / total) - ndtr((5.0 - r / v - when) / total)
    # each end of the passage is sampled to half a refined step: error at most 2 x dt/2 x max density
    bound = FINE_DT / (total * math.sqrt(2 * math.pi))
    assert np.all(np.abs(p - exact) <= bound)
    assert p[2] > 0.75 and p[0] < 1e-6


def test_a_fix_s_rays_count_once_when_the_body_hides_several():
    t = np.arange(0.0, 10.0, 0.1)
    track = _track(np.column_stack([np.full(len(t), 5.0), -5.0 + t]), t)
    origin = np.zeros((2, 2))
    target = np.array([[10.0, 0.0], [10.0, 0.5]])   # two markers, both rays crossed at about 5 s
    kw = dict(shift_mean=np.zeros(2), shift_var=np.full(2, 0.04))
    each = block_probability(track, origin, 0.5, target, np.full(2, 0.3), np.full(2, 5.2), **kw)
    both = block_probability(track, origin, 0.5, target, np.full(2, 0.3), np.full(2, 5.2), group=np.zeros(2, int), **kw)
    assert both.shape == (1,)
    # one lag for both rays: at least the likelier ray's, at most what independent rays would give
    assert 0.0 < each.max() - 1e-12 <= both[0] <= combine(each) + 1e-12


def test_a_robot_waiting_for_another_takes_its_lag_from_the_release():
    """Robot 1 waits (2-3 s) for robot 0: from its release its lag is robot 0's plus the restart.

    Against robot 0 measuring later, the difference is robot 0's drift since the release and the
    restart: its variance is ``release_var + var_rate * (robot 0's driving since)``, not two
    independent lags' sum. A wait for a robot that had long gone (its own lag, less the wait,
    later than the holder's) keeps the robot's own lag.
    """
    t = np.arange(0.0, 6.0 + 1e-9, 0.1)
    waiting = (t > 2.0 + 1e-9) & (t < 3.0 + 1e-9)
    x1 = np.where(t < 2.0, t, np.where(t < 3.0, 2.0, t - 1.0))
    tl0 = _timeline(np.column_stack([t, np.full(len(t), 5.0)]), t)
    tl1 = _timeline(np.column_stack([x1, np.zeros(len(t))]), t, waiting, np.where(waiting, 0, -1))
    model = TimingModel(lag0=1.0, lag_rate=0.01, release_lag=0.7, base_var=0.3, var_rate=0.02, release_var=0.05)
    tracks = tie([Track.of(tl, 0.0, 0.4, 0.5) for tl in (tl0, tl1)], [tl0, tl1], model)
    when = np.array([1.0, 5.0])
    mean, var = lag_difference(tracks, 0, 1, when, model)
    # before the wait: two own lags, independent, the same drive
    assert mean[0] == pytest.approx(0.0, abs=1e-9) and var[0] == pytest.approx(2 * (0.3 + 0.02 * 1.0), abs=1e-3)
    # at 5 s robot 1 (released at 3 s, driven 1.9 s since) follows robot 0's lag at 3 s
    d0_rel, d0, d1_since = 3.0, 5.0, 1.9
    assert mean[1] == pytest.approx(0.01 * (d0 - d0_rel) - 0.7 - 0.01 * d1_since, abs=2e-3)
    assert var[1] == pytest.approx(0.02 * (d0 - d0_rel) + 0.05 + 0.02 * d1_since, abs=3e-3)
    # robot 0 leaving at 2.95 s, robot 1 losing 2 s per second driven: at the wait robot 1 is
    # 4 s late, later than robot 0's release (0.1 s late) plus the restart by more than the wait:
    # it did not stop, its own lag goes on
    late = TimingModel(lag0=0.0, lag_rate=2.0, release_lag=0.7, base_var=0.3, var_rate=0.0, release_var=0.05)
    tracks = tie([Track.of(tl0, 2.95, 0.4, 0.5), Track.of(tl1, 0.0, 0.4, 0.5)], [tl0, tl1], late)
    assert np.all(tracks[1].root == -1)
    # and the plan's 1 s wait is lag made up: at 5 s robot 1 has driven 4 s (8 s late) less 1 s,
    # robot 0 2.1 s (4.2 s late)
    mean, _ = lag_difference(tracks, 0, 1, np.array([5.0]), late)
    assert mean[0] == pytest.approx(4.2 - 7.0, abs=0.11)
    # with robot 0 leaving on time it would have waited
    assert np.any(tie([Track.of(tl, 0.0, 0.4, 0.5) for tl in (tl0, tl1)], [tl0, tl1], late)[1].root == 0)


def test_with_a_timing_spread_a_waiting_robot_stands_where_the_plan_has_it_against_its_holder():
    """Robot 1 waits (2-3 s) for robot 0; with a declared spread (``tie_wait``) it is tied from the wait's start.

    During the wait it stands until robot 0 has passed, whenever it arrived: against robot 0 its
    lag is robot 0's at the release plus the restart (variance ``release_var`` and robot 0's drift
    over the 0.5 s to the release), not its own lag (two independent lags: ``2 base_var`` and
    more). Afterwards the difference is the restart and both drifts, the speed factor's part
    growing with the square of the time driven. Negative control: without ``tie_wait`` the wait
    is the robot's own lag.
    """
    t = np.arange(0.0, 6.0 + 1e-9, 0.1)
    waiting = (t > 2.0 + 1e-9) & (t < 3.0 + 1e-9)
    x1 = np.where(t < 2.0, t, np.where(t < 3.0, 2.0, t - 1.0))
    tl0 = _timeline(np.column_stack([t, np.full(len(t), 5.0)]), t)
    tl1 = _timeline(np.column_stack([x1, np.zeros(len(t))]), t, waiting, np.where(waiting, 0, -1))
    model = TimingModel(lag0=1.0, lag_rate=0.01, release_lag=0.7, base_var=0.3, var_rate=0.02, release_var=0.05,
                        var_quad=0.001, tie_wait=True)
    tracks = tie([Track.of(tl, 0.0, 0.4, 0.5) for tl in (tl0, tl1)], [tl0, tl1], model)
    mean, var = lag_difference(tracks, 0, 1, np.array([2.5, 5.0]), model)
    assert mean[0] == pytest.approx(-0.01 * 0.5 - 0.7, abs=2e-3)
    assert var[0] == pytest.approx(0.05 + 0.02 * 0.5 + 0.001 * 0.5**2, abs=2e-3)
    d1_since = 1.9
    assert mean[1] == pytest.approx(0.01 * 2.0 - 0.7 - 0.01 * d1_since, abs=2e-3)
    assert var[1] == pytest.approx(0.05 + 0.02 * d1_since + 0.001 * d1_since**2 + 0.02 * 2.0 + 0.001 * 2.0**2,
                                   abs=3e-3)
    loose = replace(model, tie_wait=False)
    _, var = lag_difference(tie([Track.of(tl, 0.0, 0.4, 0.5) for tl in (tl0, tl1)], [tl0, tl1], loose), 0, 1,
                            np.array([2.5]), loose)
    assert var[0] > 2 * 0.3


def test_a_waiting_robot_is_placed_where_the_simulated_one_stands():
    # it stops STAND_BACK short of the timeline's place, spread STAND_SD; driving, POS_SD at its place;
    # on its start dock it is where the dock is, spread STAND_SD
    t = np.arange(0.0, 6.0 + 1e-9, 0.1)
    waiting = (t > 2.0 + 1e-9) & (t < 3.0 + 1e-9)
    x1 = np.where(t < 2.0, t, np.where(t < 3.0, 2.0, t - 1.0))
    path = np.column_stack([np.arange(0.0, 5.0 + 1e-9, 0.1), np.zeros(51)])
    tl = _timeline(np.column_stack([x1, np.zeros(len(t))]), t, waiting)
    tr = Track.of(tl, 0.0, 0.4, 0.5).stand_back(tl, path, path[:, 0])
    k = tr.sample(np.array([2.5, 1.0, 0.0]))
    assert tr.xy[k[0], 0] == pytest.approx(2.0 - STAND_BACK) and tr.pos_sd[k[0]] == STAND_SD
    assert tr.xy[k[1], 0] == pytest.approx(1.0) and tr.pos_sd[k[1]] == POS_SD
    assert tr.xy[k[2], 0] == 0.0 and tr.pos_sd[k[2]] == STAND_SD      # on its start dock


@pytest.fixture(scope="module")
def docks():
    from planner.pef.map import PEF
    from planner.plan import plan_task
    from scenarios import load

    sc = load("paper-docks")
    pef = PEF(sc)
    return sc, pef, plan_task(sc, 0, pef=pef)


def test_the_schedule_avoids_a_marker_others_hide_and_is_unchanged_without_blocking(docks):
    from planner.routes.smoothing import speed_profile
    from planner.schedule.schedule import make_schedule

    sc, pef, plan = docks
    cand = plan.candidates[plan.chosen]
    base = speed_profile(cand.path, sc.robot)
    alone = make_schedule(sc, pef, cand.path.points, base)
    assert [(f.s, f.markers) for f in alone.fixes] == [(f.s, f.markers) for f in plan.schedule.fixes]
    used = {m for f in alone.fixes for m in f.markers}
    hidden = max(used, key=lambda m: sum(m in f.markers for f in alone.fixes))

    def block(s, xy):
        p = np.zeros((len(sc.markers), len(s)))
        p[hidden] = 0.9
        return p

    aware = make_schedule(sc, pef, cand.path.points, base, block=block, block_limit=0.025, protect=False)
    before = sum(hidden in f.markers for f in alone.fixes)
    after = sum(hidden in f.markers for f in aware.fixes)
    assert after < before
    assert aware.worst < sc.planning.eps_max
