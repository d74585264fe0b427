"""make_schedule: the promised error bound re-computed independently at fine spacing."""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest

import scenarios
from estimators.fault.carried import promised_fault_area
from planner.pef.map import PEF
from planner.schedule.drift import drift_bound
from planner.schedule.promise import POLYGON_TOLERANCE, START_LAG, predict
from planner.schedule.schedule import Schedule, make_schedule
from scenarios.errors import PlanningError

FINE = 0.005  # check spacing [m]


@pytest.fixture(scope="module")
def warehouse():
    sc = scenarios.load("warehouse")
    return sc, PEF(sc)


def straight_driver(sc, odometry_noise=None):
    """``sc`` with a robot whose wheels have no radius error (and, given, that odometry noise).

    Such a robot holds no steady offset from a straight (:func:`planner.schedule.promise.tracking_bound`),
    so its tracking bound is the path's geometry alone: the tests of the schedule's own logic use
    it where a fast drive is needed, at whose lookahead (4.9 m at 6 m/s) the warehouse robot's
    0.002 holds it ~20 cm off the path.
    """
    robot = dataclasses.replace(sc.robot, wheel_radius_error=0.0,
                                odometry_noise=sc.robot.odometry_noise if odometry_noise is None else odometry_noise)
    return dataclasses.replace(sc, robot=robot, robot_actual=robot)


def route(sc, names):
    return np.array([sc.routes.nodes[n] for n in names], dtype=float)


def dense(path, step=0.1):
    """Return ``path`` with vertices every ``step`` metres or less, as the follower is given paths.

    The promise bounds the follower's tracking from the chords it steers along, one lookahead to
    the next vertex: on a path of a few long segments that vertex is metres away.
    """
    out = [path[:1]]
    for a, b in zip(path[:-1], path[1:], strict=True):
        n = max(1, math.ceil(np.hypot(*(b - a)) / step))
        out.append(a + (b - a) * np.arange(1, n + 1)[:, None] / n)
    return np.vstack(out)


def arc_length(path):
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(path, axis=0).T))])


def motion(path, speed):
    """t(s) and s(t) for vertex speeds with constant acceleration between vertices (scalar)."""
    s_v = arc_length(path)
    dur = 2 * np.diff(s_v) / (speed[:-1] + speed[1:])
    t_v = np.concatenate([[0.0], np.cumsum(dur)])

    def t_of(s):
        i = min(int(np.searchsorted(s_v, s, side="right")) - 1, len(dur) - 1)
        v0, v1, ds = speed[i], speed[i + 1], s - s_v[i]
        v = math.sqrt(v0 ** 2 + (v1 ** 2 - v0 ** 2) * ds / (s_v[i + 1] - s_v[i]))
        return t_v[i] + (2 * ds / (v0 + v) if ds > 0 else 0.0)

    def s_of(t):
        if t >= t_v[-1]:
            return s_v[-1]
        i = int(np.searchsorted(t_v, t, side="right")) - 1
        a, tau = (speed[i + 1] - speed[i]) / dur[i], t - t_v[i]
        return s_v[i] + speed[i] * tau + 0.5 * a * tau ** 2

    return t_of, s_of


def turned_between(path, a, b):
    """Absolute heading change at the vertices with a <= s <= b [rad]; b may be an array."""
    s = arc_length(path)
    h = np.arctan2(*np.diff(path, axis=0)[:, ::-1].T)
    turns = np.abs((np.diff(h) + math.pi) % (2 * math.pi) - math.pi)
    sv = s[1:-1]
    b = np.asarray(b, dtype=float)
    return np.sum(np.where((sv >= a) & (sv <= b[..., None]), turns, 0.0), axis=-1)


def independent_check(sc, pef, path, speed, sched: Schedule):
    """Worst predicted error re-computed from the fixes alone, at FINE spacing.

    A fix i taken from s_i measures k markers one after another (k * measurement_time); it
    completes at c_i (the first fix at standstill: c_0 = 0). Its promise is the fault area of
    noise-free ranges at the positions of the k measurements (at the schedule's speeds, slow-
    downs included), carried to c_i with the odometry bound; until the next fix completes the
    error is that promise plus the drift since s_i. The static tau each fix reports is checked
    too (largest of tau_subset over its stretch, sampled at FINE). Returns the worst error and
    checks the sensor rate on the way.
    """
    s_v = arc_length(path)
    assert np.all(sched.speed <= speed + 1e-12), "a slow-down may only lower the planned speed"
    speed = sched.speed
    t_of, s_of = motion(path, speed)
    k, mt = sc.sensor.markers_per_fix, sc.sensor.measurement_time
    gap = max(1 / sc.sensor.fix_rate_hz, k * mt)
    xy_of = lambda s: np.column_stack([np.interp(s, s_v, path[:, 0]), np.interp(s, s_v, path[:, 1])])
    fixes = sched.fixes
    assert fixes[0].s == 0.0
    starts = np.array([f.s for f in fixes])
    t_start = np.array([t_of(x) for x in starts])
    t_start[0] = -k * mt
    assert np.all(np.diff(t_start) >= gap * (1 - 1e-6)), "fixes closer than the sensor rate allows"
    comp = np.array([s_of(t) for t in t_start + k * mt])
    comp[0] = 0.0
    worst = 0.0
    for i, f in enumerate(fixes):
        stretch = np.append(np.arange(f.s, comp[i], FINE), comp[i])
        static = float(np.max(pef.tau_subset(xy_of(stretch), np.array(sorted(f.markers)))))
        assert f.tau >= static * (1 - 1e-9) - 1e-12, f"fix {i} reports tau {f.tau} below {static}"
        # the promise bounds a start up to START_LAG late (the robot starts at a control tick)
        taus = []
        for lag in ((0.0, 0.5 * START_LAG, START_LAG) if i else (0.0,)):
            at = np.array([s_of(t) for t in t_start[i] + lag + mt * np.arange(1, k + 1)]) if i else np.zeros(k)
            taus.append(promised_fault_area(sc.sensor, sc.robot, sc.marker_positions()[list(f.markers)], xy_of(at),
                                            sc.planning.heading_std).diameter)
        tau = max(taus)
        assert f.predicted_tau >= tau, f"fix {i}: promise {f.predicted_tau} below the exact area {tau}"
        assert np.allclose(f.poses, xy_of(at if not i else [s_of(t) for t in t_start[i] + mt * np.arange(1, k + 1)]))
        assert f.predicted_tau * (1 + POLYGON_TOLERANCE) < sc.planning.eps_max
        end = comp[i + 1] if i + 1 < len(fixes) else s_v[-1]
        s = np.append(np.arange(comp[i], end, FINE), end)
        turned = turned_between(path, f.s, s)
        err = f.predicted_tau + drift_bound(sc.robot, s - f.s, turned)  # the promise (>= tau) is what holds
        worst = max(worst, float(err.max()))
        if i > 0:
            assert f.switch == (set(f.markers) != set(fixes[i - 1].markers))
            # the estimate's error the promise assumes covers what the fix before certifies
            # until this one completes (its weakest promise plus the drift since it started)
            prev = fixes[i - 1]
            weakest = max([prev.predicted_tau, *[t for t in prev.fallback_tau if math.isfinite(t)]])
            cert = weakest + float(drift_bound(sc.robot, np.array([comp[i] - prev.s]),
                                               turned_between(path, prev.s, np.array([comp[i]])))[0])
            assert f.estimate >= cert * (1 - 1e-9), f"fix {i}: estimate {f.estimate} below the certified {cert}"
            assert f.estimate < sc.planning.eps_max
    return worst


@pytest.mark.parametrize("policy", ["often", "sparse"])
def test_schedule_keeps_error_under_eps(warehouse, policy):
    sc, pef = warehouse
    path = dense(route(sc, ["A", "C", "e1", "e2", "B"]))
    sched = make_schedule(sc, pef, path, policy=policy)
    speed = np.full(len(path), sc.robot.max_speed)
    worst = independent_check(sc, pef, path, speed, sched)
    assert worst < sc.planning.eps_max
    assert sched.worst < sc.planning.eps_max
    assert sched.s == pytest.approx(arc_length(path))
    assert np.all(sched.predicted_error <= sched.worst) and np.all(sched.predicted_error > 0)
    # the schedule's own worst is the same quantity, sampled more coarsely
    assert sched.worst == pytest.approx(worst, rel=0.02)
    assert all(0 <= m < len(sc.markers) for f in sched.fixes for m in f.markers)


def test_promises_assume_the_estimate_error_the_plan_certifies(warehouse):
    """Each promise is the bound at the fix's certified estimate error: below the one at eps_max."""
    sc, pef = warehouse
    path = dense(route(sc, ["A", "C", "e1", "e2", "B"]))
    sched = make_schedule(sc, pef, path)
    fixes = sched.fixes
    starts = np.array([f.s for f in fixes])
    subsets = [f.markers for f in fixes]
    est = np.array([f.estimate for f in fixes])
    assert np.all(np.isfinite(est)) and np.all(est[1:] < sc.planning.eps_max)
    again, _, _ = predict(sc, path, sched.speed, starts, subsets, est)
    np.testing.assert_allclose(again, [f.predicted_tau for f in fixes], rtol=1e-12)
    # negative control: eps_max as every fix's estimate error (the previous construction) promises more
    at_eps, _, _ = predict(sc, path, sched.speed, starts, subsets, sc.planning.eps_max)
    assert np.all(at_eps[1:] > again[1:])


def test_sparse_uses_fewer_fixes_and_keeping_subsets_fewer_switches(warehouse):
    sc, pef = warehouse
    path = dense(route(sc, ["A", "w1", "w2", "D", "B"]))
    often = make_schedule(sc, pef, path)
    sparse = make_schedule(sc, pef, path, policy="sparse")
    assert len(sparse.fixes) < len(often.fixes)
    # fixing as often as the rate allows keeps the error lower along the path (the worst of
    # both is set by the one stretch whose best fix promises nearly eps_max: 29.99 mm each)
    assert np.mean(often.predicted_error) < np.mean(sparse.predicted_error)
    assert often.worst < sc.planning.eps_max and sparse.worst < sc.planning.eps_max
    eager = make_schedule(sc, pef, path, switch_tolerance=0.0)
    assert sum(f.switch for f in often.fixes) <= sum(f.switch for f in eager.fixes)
    # with no tolerance every fix uses a subset of least tau over its stretch; with it, a kept
    # subset's promise is within 20 % of that one's, compared as the search compares them (at
    # eps_max as the estimate's error, the better order: the final promises are recomputed with
    # each schedule's own certified errors, which differ)
    pairs = [(f, g) for f, g in zip(often.fixes, eager.fixes, strict=False) if f.s == g.s]
    starts = [f.s for f, _ in pairs]
    kept, _, _ = predict(sc, path, often.speed, starts, [f.markers for f, _ in pairs], sc.planning.eps_max)
    best = np.minimum(*(predict(sc, path, often.speed, starts, [order(g.markers) for _, g in pairs],
                                sc.planning.eps_max)[0] for order in (tuple, lambda m: tuple(reversed(m)))))
    assert len(pairs) > 10 and np.all(kept <= best * 1.2 + 1e-12)


def test_speed_profile_with_stops(warehouse):
    sc, pef = warehouse
    corner = route(sc, ["A", "C", "e1"])
    # densify, slow down to a stop at the corner C and at the goal
    s = arc_length(corner)
    fine_s = np.linspace(0, s[-1], 200)
    fine_s = np.unique(np.append(fine_s, s))
    path = np.column_stack([np.interp(fine_s, s, corner[:, 0]), np.interp(fine_s, s, corner[:, 1])])
    speed = np.clip(np.minimum(np.abs(fine_s - s[1]), s[-1] - fine_s), 0.0, sc.robot.max_speed)
    speed[0] = 0.3
    sched = make_schedule(sc, pef, path, speed)
    worst = independent_check(sc, pef, path, speed, sched)
    assert worst < sc.planning.eps_max


def parse_stretch(msg):
    m = re.search(r"from s = ([\d.]+) m .* to s = ([\d.]+) m the predicted error reaches ([\d.e+-]+|inf) m",
                  msg)
    assert m, msg
    return float(m.group(1)), float(m.group(2)), float(m.group(3))


def test_blind_stretch_is_named():
    # the steady offset of a wheel radius error would leave 3 mm of this eps_max: a robot without
    sc = straight_driver(scenarios.load("paper-two-markers"))
    sc = dataclasses.replace(sc, sensor=dataclasses.replace(sc.sensor, max_range=4.0),
                             planning=dataclasses.replace(sc.planning, eps_max=0.01))
    pef = PEF(sc)
    path = np.array([[2.5, 0.5], [2.5, 4.8]])
    with pytest.raises(PlanningError, match="no measurement schedule") as exc:
        make_schedule(sc, pef, path)
    a, b, err = parse_stretch(str(exc.value))
    assert "fewer than 2 markers visible" in str(exc.value)
    # independent: where the markers drop out of range along the path (about s = 2.62 m)
    y = np.linspace(0.5, 4.8, 4301)
    n_vis = pef.visible(np.column_stack([np.full_like(y, 2.5), y])).sum(axis=1)
    s_blind = float(y[np.argmax(n_vis < 2)] - 0.5)
    assert 2.0 < s_blind < 3.0
    # the last fix is taken before the blind point; dead-reckoning from it, the error crosses
    # eps_max at the named start of the stretch (re-computed here from the named fix)
    m = re.search(r"last usable fix at s = ([\d.]+) m with tau ([\d.e+-]+) m", str(exc.value))
    s_fix, tau_fix = float(m.group(1)), float(m.group(2))
    assert s_fix <= s_blind <= b
    eps = sc.planning.eps_max
    # candidate starts are sampled a quarter of a fix gap apart (2.5 cm at 0.5 m/s): the
    # crossing lies within one sample before the named start
    before, after = (tau_fix + drift_bound(sc.robot, a - s_fix + ds) for ds in (-0.03, 0.01))
    assert before < eps <= after
    assert err >= eps


def test_drift_limited_stretch_is_named(warehouse):
    sc, pef = warehouse
    sc = straight_driver(sc, odometry_noise=0.015)  # the drift from noise alone exceeds eps at 6 m/s
    path = route(sc, ["A", "C"])
    fast = np.full(len(path), 6.0)  # 1.2 m between fixes: drift alone exceeds eps
    no_slowing = dataclasses.replace(sc, planning=dataclasses.replace(sc.planning, min_fix_speed=6.0))
    with pytest.raises(PlanningError) as exc:
        make_schedule(no_slowing, pef, path, fast)
    a, b, err = parse_stretch(str(exc.value))
    assert 0.0 <= a <= b and err >= sc.planning.eps_max
    # independently: the first fix's tau plus drift reaches eps before the next fix completes
    tau0 = float(pef.at(path[:1]).tau[0])
    reach = 6.0 * (1 / sc.sensor.fix_rate_hz + 2 * sc.sensor.measurement_time)
    assert tau0 + drift_bound(sc.robot, reach) >= sc.planning.eps_max
    assert a <= reach
    # at a walking pace the same path is fine
    make_schedule(sc, pef, path, np.full(len(path), 0.5))
    # and allowed to slow down, the planner finds that pace where it needs it, at a cost in time
    slowed = make_schedule(sc, pef, path, fast)
    assert slowed.slowdown_time > 0.0 and slowed.worst < sc.planning.eps_max
    assert slowed.speed.min() >= sc.planning.min_fix_speed and slowed.speed.max() <= 6.0


def test_start_without_enough_markers():
    sc = scenarios.load("paper-two-markers")
    sc = dataclasses.replace(sc, sensor=dataclasses.replace(sc.sensor, max_range=1.0))
    with pytest.raises(PlanningError, match=r"from s = 0.00 m .*no usable fix at the start"):
        make_schedule(sc, PEF(sc), np.array([[2.5, 2.5], [3.0, 3.0]]))


def test_single_point_path(warehouse):
    sc, pef = warehouse
    sched = make_schedule(sc, pef, route(sc, ["A"]))
    assert len(sched.fixes) == 1 and sched.fixes[0].tau == pytest.approx(pef.at(route(sc, ["A"])).tau[0])
    # the error until the end is the standstill fix's promise (its first range carried over sub-tick motion)
    assert sched.predicted_error == pytest.approx([sched.fixes[0].predicted_tau])
    assert sched.fixes[0].predicted_tau > sched.fixes[0].tau


class _FourTimes:
    """Kinematics whose times are four times too long: a slow-down's cost overstated (negative control)."""

    def __init__(self, s_v, v):
        from planner.schedule.pathtime import Kinematics

        self.t_v = 4.0 * Kinematics(s_v, v).t_v


def _pruned_outcomes(sc, pef, path, v, beats):
    """``{beat: slow-down time or None (the search gave up)}`` of the slow-down search of one rung."""
    from planner.schedule.drift import DEFAULT_INCREMENT, K_SIGMA
    from planner.schedule.schedule import _schedule_for

    out = {}
    for beat in beats:
        try:
            out[beat] = _schedule_for(sc, pef, path, v, 2, None, "often", 0.2, K_SIGMA, 0.0, DEFAULT_INCREMENT,
                                      None, 1.0, True, beat=beat).slowdown_time
        except PlanningError as exc:
            assert "already found" in str(exc)
            out[beat] = None
    return out


def test_a_slow_down_search_gives_up_only_where_its_schedule_would_not_be_taken(warehouse, monkeypatch):
    """A rung's slow-down search gives up early only where its schedule would not be taken.

    Given the slow-down ``beat`` of a schedule already found, it stops only when the schedule it
    would find slows the drive by at least ``beat`` (make_schedule takes the one that slows
    least, and the smaller rung on a tie); elsewhere it returns that very schedule.

    Negative control: the cost of the speeds tried overstated four times (a prune that is not
    proven) gives up where the schedule would have been taken.
    """
    from planner.schedule import schedule as schedule_module

    sc, pef = warehouse
    sc = straight_driver(sc, odometry_noise=0.015)
    sc = dataclasses.replace(sc, planning=dataclasses.replace(sc.planning, eps_max=0.03))
    path = route(sc, ["A", "C"])
    fast = np.full(len(path), 6.0)  # slow-downs needed (test_drift_limited_stretch_is_named)
    full = _pruned_outcomes(sc, pef, path, fast, [None])[None]
    assert full > 0.0
    beats = [0.5 * full, full, 1.01 * full, 1.5 * full]

    def sound(got):
        return all(got[b] == full if got[b] is not None else full >= b for b in beats)

    got = _pruned_outcomes(sc, pef, path, fast, beats)
    assert sound(got)
    assert got[0.5 * full] is None and got[1.5 * full] == full  # it did give up, and did not always
    monkeypatch.setattr(schedule_module, "Kinematics", _FourTimes)
    # it gives up at 1.5 x the schedule's own slow-down, which make_schedule would have taken
    assert _pruned_outcomes(sc, pef, path, fast, [1.5 * full])[1.5 * full] is None, "cannot fail"


def _one_by_one(sc, pef, path, v):
    """make_schedule's slow-down searches as they were: rungs in increasing order, each cut only by the least so far.

    Returns the schedule (or the error) and the number of attempts; the rungs here have no
    schedule at speed, so the at-speed ladder is left out (its failures are re-made, not reused).
    """
    from planner.pef.sight import estimate_floor
    from planner.schedule.drift import DEFAULT_INCREMENT, K_SIGMA
    from planner.schedule.pathtime import Kinematics
    from planner.schedule.schedule import SLOWDOWN_SHARE, _at, _schedule_for, rungs

    s_v = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(path, axis=0).T))])
    allowed = SLOWDOWN_SHARE * Kinematics(s_v, v).t_v[-1]
    tau = pef.at(path).tau
    floor = max(estimate_floor(sc.sensor) * (1.0 + POLYGON_TOLERANCE), float(np.max(tau)))
    slow, failed = None, None
    for rung in rungs(sc.planning.eps_max, floor):
        try:
            sched = _schedule_for(_at(sc, rung), pef, path, v, 2, None, "often", 0.2, K_SIGMA, 0.0,
                                  DEFAULT_INCREMENT, None, 1.0, True,
                                  beat=None if slow is None else slow.slowdown_time)
        except PlanningError as exc:
            failed = exc
            continue
        if sched.slowdown_time <= allowed:
            return sched
        if slow is None or sched.slowdown_time < slow.slowdown_time:
            slow = sched
    if slow is None:
        raise failed
    return slow


def _counted(monkeypatch, fn, *args):
    """Return ``fn(*args)`` and the slow-down attempts it made."""
    from planner.schedule import schedule as schedule_module

    n = [0]
    attempt = schedule_module._attempt

    def counting(*a, **kw):
        n[0] += not kw.get("prove", False)
        return attempt(*a, **kw)

    monkeypatch.setattr(schedule_module, "_attempt", counting)
    out = fn(*args)
    monkeypatch.setattr(schedule_module, "_attempt", attempt)
    return out, n[0]


def test_the_least_slow_down_is_searched_from_the_largest_rung_with_the_same_answer(warehouse, monkeypatch):
    """The slow-down searches give the schedule the rungs searched one by one in increasing order give.

    The warehouse's A-C at 6 m/s has no schedule at speed; the 20 mm rung's search crawls (a
    ~476 s slow-down), the 30 mm one slows by ~28 s, the 50 mm one by ~4 s, none within the
    allowance. Searched from the largest rung down (each cut once it costs more than the least
    so far), the 20 mm rung is cut after a few attempts: the same schedule, compared whole
    (fixes, speeds, errors: exact, no tolerance), from fewer attempts.

    Negative control: the first rung's schedule (what searching in increasing order without
    the least-slow-down rule returns) differs from the one chosen, so the comparison can fail.
    """
    sc, pef = warehouse
    sc = straight_driver(sc, odometry_noise=0.015)
    sc = dataclasses.replace(sc, planning=dataclasses.replace(sc.planning, eps_max=0.05))
    path = route(sc, ["A", "C"])
    fast = np.full(len(path), 6.0)
    want, n_old = _counted(monkeypatch, _one_by_one, sc, pef, path, fast)
    got, n_new = _counted(monkeypatch, make_schedule, sc, pef, path, fast)
    assert repr(got) == repr(want) and got.speed.tobytes() == want.speed.tobytes()
    assert got.slowdown_time > 0.0
    assert n_new < n_old, (n_new, n_old)
    from planner.schedule.drift import DEFAULT_INCREMENT, K_SIGMA
    from planner.schedule.schedule import _at, _schedule_for

    first = _schedule_for(_at(sc, 0.02), pef, path, fast, 2, None, "often", 0.2, K_SIGMA, 0.0, DEFAULT_INCREMENT,
                          None, 1.0, True)
    assert repr(first) != repr(got), "the first rung's schedule is the one chosen: the test could not fail"
