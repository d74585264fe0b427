"""The motion-aware promise: the moving map, slow-downs, and the construction shared with the simulation."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import scenarios
from estimators.fault.carried import (
    carry,
    promised_diameters,
    promised_fault_area,
    promised_parallelogram,
    promised_parallelogram_best,
    shift_bound,
)
from estimators.fault.exact import exact_fault_area
from planner.pef.map import PEF
from planner.plan import plan_task
from planner.schedule.promise import (
    POLYGON_TOLERANCE,
    SETTLE_LOOKAHEADS,
    START_LAG,
    chord_bound,
    moving_map,
    predict,
    settle_bound,
)
from scenarios.errors import PlanningError


@pytest.fixture(scope="module")
def warehouse():
    sc = scenarios.load("warehouse")
    return sc, PEF(sc)


def test_carry_shifts_markers_so_the_range_holds_at_the_end():
    rng = np.random.default_rng(3)
    markers = rng.uniform(0, 10, (2, 2))
    at = rng.uniform(0, 10, (2, 2))
    end = at[1] + [0.3, -0.1]
    shifted, travelled = carry(markers, at, end)
    # a range taken at p_i to M_i is the same range from the end to the shifted marker
    np.testing.assert_allclose(np.hypot(*(end - shifted).T), np.hypot(*(at - markers).T), rtol=1e-12)
    np.testing.assert_allclose(travelled, np.hypot(*(end - at).T), rtol=1e-12)


def test_a_carried_range_keeps_two_ticks_even_without_travel(warehouse):
    sc, _ = warehouse
    tick = 2 * np.pi * sc.robot.wheel_radius / sc.robot.encoder_ticks
    b = shift_bound(sc.robot, np.array([0.0, 0.02]), 0.003)
    assert b[0] == pytest.approx(2 * tick) and b[1] > b[0]


def test_standstill_promise_is_the_exact_area_with_the_first_range_widened(warehouse):
    sc, _ = warehouse
    p = np.array([3.0, 2.0])
    m = sc.marker_positions()[[1, 5]]
    r = np.hypot(*(p - m).T)
    tick = 2 * np.pi * sc.robot.wheel_radius / sc.robot.encoder_ticks
    widened = exact_fault_area(m, r, sc.sensor.range_bound(r) + [2 * tick, 0.0], p).diameter
    area = promised_fault_area(sc.sensor, sc.robot, m, np.array([p, p]), 0.01)
    assert area.diameter == pytest.approx(widened, rel=1e-9)
    static = float(PEF(sc, model="exact").tau_subset(p[None], np.array([1, 5]))[0])
    assert area.diameter > static  # negative control: the static PEF is not the standstill fix


def test_moving_map_at_zero_speed_is_the_standstill_fix(warehouse):
    sc, pef = warehouse
    static, moving = pef.grid(0.5), moving_map(sc, pef, 0.0, 0.5)
    fin = np.isfinite(static.tau)
    np.testing.assert_array_equal(fin, np.isfinite(moving.tau))
    assert np.all(moving.tau[fin] >= static.tau[fin])
    iy, ix = np.nonzero(fin & (moving.tau < sc.planning.eps_max))
    for c in np.random.default_rng(2).choice(len(iy), 20, replace=False):
        cell = np.array([moving.x[ix[c]], moving.y[iy[c]]])
        pair = moving.best[iy[c], ix[c]]
        exact = promised_fault_area(sc.sensor, sc.robot, sc.marker_positions()[pair], np.array([cell, cell]),
                                    sc.planning.heading_std).diameter
        assert exact == pytest.approx(moving.tau[iy[c], ix[c]], rel=2e-3)  # exact vs parallelogram


def test_moving_map_matches_the_construction_in_every_direction(warehouse):
    """Independent: the exact fault area of the moving fix at each cell, driven four ways.

    The map takes the marker directions at the cell; a fix driven at v moves v * mt (2 cm), so
    a marker's direction is off by delta <= v mt / r and the angle alpha between them by as
    much. The diagonal 2/sin(alpha) sqrt(...) then changes by at most about
    (1 + |cot(alpha)|) delta relative (first order); the exact area differs from its
    parallelogram by O(rho / r) < 0.2 %.
    """
    sc, pef = warehouse
    v, mt = 1.0, sc.sensor.measurement_time
    mm = moving_map(sc, pef, v, 0.5)
    static = pef.grid(0.5)
    iy, ix = np.nonzero(mm.free & (mm.tau < sc.planning.eps_max))
    pick = np.random.default_rng(0).choice(len(iy), 60, replace=False)
    worst, static_worst = 0.0, 0.0
    for c in pick:
        end = np.array([mm.x[ix[c]], mm.y[iy[c]]])
        pair = mm.best[iy[c], ix[c]]
        d = end - sc.marker_positions()[pair]
        r = np.hypot(d[:, 0], d[:, 1])
        sin_a = abs(d[0, 0] * d[1, 1] - d[0, 1] * d[1, 0]) / (r[0] * r[1])
        allowed = (1.0 + np.sqrt(1.0 - sin_a**2) / sin_a) * v * mt / r.min() + 2e-3
        for ang in (0.0, 0.5 * np.pi, np.pi, 1.5 * np.pi):
            start = end - v * mt * np.array([np.cos(ang), np.sin(ang)])
            area = promised_fault_area(sc.sensor, sc.robot, sc.marker_positions()[pair], np.array([start, end]),
                                       sc.planning.heading_std)
            worst = max(worst, abs(area.diameter / mm.tau[iy[c], ix[c]] - 1.0) / allowed)
            static_worst = max(static_worst, abs(area.diameter / static.tau[iy[c], ix[c]] - 1.0))
    assert worst < 1.0
    # negative control: the paper's static map does not describe the moving fix
    assert static_worst > 0.05


def test_compiled_best_order_is_the_vectorised_parallelogram_bit_for_bit(warehouse):
    sc, _ = warehouse
    rng = np.random.default_rng(11)
    mk = rng.uniform(0, 30, (12, 2))
    mk[11] = mk[10] + [5.0, 0.0]  # with pose 2 below: all three collinear, a degenerate fix
    pairs = np.array([(a, b) for a in range(12) for b in range(a + 1, 12)])
    start = rng.uniform(0, 30, (40, 2))
    poses = np.stack([start, start + rng.normal(0, 0.05, (40, 2))], axis=1)        # (n, 2, 2)
    poses[2] = [mk[10] - [3.0, 0.0], mk[10] - [2.9, 0.0]]
    poses[3, 1] = poses[3, 0]                                                        # no travel
    poses[4, 0] = mk[0]                                                              # range 0
    c, j = np.meshgrid(np.arange(len(pairs)), np.arange(40), indexing="ij")
    c, j = c.ravel(), j.ravel()
    hs = sc.planning.heading_std
    tau, flip = promised_parallelogram_best(sc.sensor, sc.robot, mk, pairs, poses, c, j, hs)
    m = mk[pairs[c]]
    fwd = promised_parallelogram(sc.sensor, sc.robot, m, poses[j], hs)
    rev = promised_parallelogram(sc.sensor, sc.robot, m[:, ::-1], poses[j], hs)
    assert np.array_equal(tau, np.minimum(fwd, rev))  # bit for bit, inf included
    assert np.array_equal(flip, rev < fwd)
    assert np.isinf(tau).any() and flip.any() and not flip.all()


@pytest.mark.parametrize("k", [2, 3])
def test_batched_promise_is_the_per_fix_fault_area_bit_for_bit(warehouse, k):
    sc, _ = warehouse
    rng = np.random.default_rng(5 + k)
    n = 12 if k == 2 else 4
    markers = rng.uniform(0, 30, (n, k, 2))
    start = rng.uniform(0, 30, (n, 1, 2))
    poses = start + np.cumsum(rng.normal(0, 0.05, (n, k, 2)), axis=1)
    poses[1] = poses[1, :1]                                                            # standstill
    poses[2] = markers[2].mean(axis=0)             # on the marker line: not the closed form's case
    hs = sc.planning.heading_std
    diameter, empty = promised_diameters(sc.sensor, sc.robot, markers, poses, hs)
    areas = [promised_fault_area(sc.sensor, sc.robot, m, p, hs) for m, p in zip(markers, poses, strict=True)]
    assert np.array_equal(diameter, [a.diameter for a in areas])
    assert np.array_equal(empty, [a.is_empty for a in areas]) and not empty.any()
    # the measurement order matters (the earlier ranges are carried): the check can tell
    reversed_order, _ = promised_diameters(sc.sensor, sc.robot, markers[:, ::-1], poses, hs)
    assert not np.array_equal(reversed_order, diameter)


def test_parallelogram_of_the_construction_tracks_its_exact_area(warehouse):
    sc, _ = warehouse
    rng = np.random.default_rng(1)
    m = sc.marker_positions()
    for _ in range(30):
        i, j = rng.choice(len(m), 2, replace=False)
        end = rng.uniform([2, 2], [28, 18])
        poses = np.array([end - [0.02, 0.0], end])
        lin = float(promised_parallelogram(sc.sensor, sc.robot, m[[i, j]], poses, 0.005))
        exact = promised_fault_area(sc.sensor, sc.robot, m[[i, j]], poses, 0.005).diameter
        if np.isfinite(lin) and lin < 0.1:
            assert exact == pytest.approx(lin, rel=2e-3)


def _variant(sc, **planning):
    return dataclasses.replace(sc, planning=dataclasses.replace(sc.planning, **planning))


def test_schedule_slows_down_where_cruising_breaks_it(warehouse):
    sc, _ = warehouse
    fast = dataclasses.replace(sc, robot=dataclasses.replace(sc.robot, max_speed=2.0))
    plan = plan_task(fast, 0)
    sch = plan.schedule
    assert sch.slowdown_time > 0.0
    assert np.all(sch.speed <= plan.candidates[plan.chosen].speed + 1e-12)
    assert np.min(sch.speed[sch.speed > 0]) >= fast.planning.min_fix_speed - 1e-12
    assert plan.candidates[plan.chosen].slowdown == pytest.approx(sch.slowdown_time)
    assert all(f.predicted_tau * (1 + POLYGON_TOLERANCE) < fast.planning.eps_max for f in sch.fixes)
    assert sch.worst < fast.planning.eps_max
    # negative control: forbidden to slow down (minimum speed = cruising speed), no route is admissible
    with pytest.raises(PlanningError, match="no admissible route"):
        plan_task(_variant(fast, min_fix_speed=2.0), 0)


def test_built_in_plans_promise_every_fix(warehouse):
    sc, _ = warehouse
    for task in range(len(sc.tasks)):
        sch = plan_task(sc, task).schedule
        tau = np.array([f.predicted_tau for f in sch.fixes])
        assert np.all(np.isfinite(tau)) and np.all(tau * (1 + POLYGON_TOLERANCE) < sc.planning.eps_max)
        # every fix promises more than the paper's static PEF: its first range is carried
        static = np.array([f.tau for f in sch.fixes])
        assert np.all(tau > static)


def test_the_promise_holds_for_a_start_up_to_a_control_tick_late():
    # Two flat reflectors a metre either side of an aisle (warehouse-reflectors' fallback pair):
    # the angle between them changes by degrees per centimetre of travel, so a fix started one
    # control tick late (1.7 cm at 1 m/s) realises more than POLYGON_TOLERANCE over the area at
    # the planned poses. predict's bound covers every start up to START_LAG late.
    sc = scenarios.load("warehouse-reflectors")
    at = sc.marker_positions()
    pair = tuple(int(np.flatnonzero(np.all(at == p, axis=1))[0]) for p in ([14.0, 10.0], [14.0, 12.0]))
    m = at[list(pair)]
    assert m.tolist() == [[14.0, 10.0], [14.0, 12.0]]
    path = np.array([[16.0, 11.0], [12.0, 11.0]])
    speed = np.full(2, 1.0)
    start, mt = 1.7, sc.sensor.measurement_time
    pred, poses, _ = predict(sc, path, speed, np.array([0.0, start]), [pair, pair], 0.0)
    np.testing.assert_allclose(poses[1], [[16.0 - start - mt, 11.0], [16.0 - start - 2 * mt, 11.0]], atol=1e-9)
    assert np.all(poses[0] == path[0])  # the standstill fix at s = 0 does not move

    def area(lag):
        at = np.array([[16.0 - start - lag - mt, 11.0], [16.0 - start - lag - 2 * mt, 11.0]])
        return promised_fault_area(sc.sensor, sc.robot, m, at, sc.planning.heading_std).diameter

    late = [area(lag) for lag in np.linspace(0.0, START_LAG, 9)]
    assert pred[1] >= max(late) * (1 - 1e-9)
    # negative control: at the planned poses alone the promise is broken by a late start
    assert max(late) > (1 + POLYGON_TOLERANCE) * area(0.0)


def test_chord_bound_is_the_distance_from_the_chords_shapely_measures():
    """chord_bound: the largest distance of path(s) from the 33 chords path(a) path(a + look) over it."""
    from shapely.geometry import LineString, Point

    rng = np.random.default_rng(11)
    path = np.cumsum(rng.normal(size=(30, 2)), axis=0)
    s_v = np.r_[0.0, np.cumsum(np.hypot(*np.diff(path, axis=0).T))]
    s = rng.uniform(0.0, s_v[-1], 40)
    look = rng.uniform(0.3, 3.0, 40)

    def at(q):
        return np.interp(q, s_v, path[:, 0]), np.interp(q, s_v, path[:, 1])

    got = chord_bound(path, s_v, s, look)
    want = [max(Point(at(si)).distance(LineString([at(a), at(a + li)])) for a in si - li * np.linspace(0, 1, 33))
            for si, li in zip(s, look, strict=True)]
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)
    assert np.all(got > 0.0)  # a random walk turns at every vertex: no chord lies on the path
    # on a straight path every chord is the path itself (to rounding, 1e-15 of its 10 m)
    line = np.column_stack([np.linspace(0.0, 10.0, 11), np.zeros(11)])
    assert np.max(chord_bound(line, np.linspace(0.0, 10.0, 11), s % 9.0, look)) < 1e-13
    # settle_bound is the largest chord bound over the settle window behind s
    back = s[:, None] - SETTLE_LOOKAHEADS * look[:, None] * np.linspace(0.0, 1.0, 25)
    np.testing.assert_array_equal(settle_bound(path, s_v, s, look),
                                  chord_bound(path, s_v, back, np.repeat(look[:, None], 25, axis=1)).max(axis=1))


def _chord_cases():
    """Paths and points that exercise the interpolation's cases: turns, axis-aligned straights, vertices hit exactly."""
    rng = np.random.default_rng(5)
    walk = np.cumsum(rng.normal(size=(60, 2)) * 0.3, axis=0)
    t = np.round(np.linspace(0.0, 10.0, 101), 1)
    ell = np.column_stack([np.minimum(t, 5.0), np.maximum(t - 5.0, 0.0)])
    ell = ell[np.r_[True, np.any(np.diff(ell, axis=0) != 0, axis=1)]]
    arc = 40.0 + 7.0 * np.column_stack([np.cos(np.linspace(0.0, 2.0, 80)), np.sin(np.linspace(0.0, 2.0, 80))])
    for path in (walk, ell, arc):
        s_v = np.r_[0.0, np.cumsum(np.hypot(*np.diff(path, axis=0).T))]
        # before the start, beyond the end, on vertices, unsorted
        s = rng.permutation(np.r_[rng.uniform(-1.0, s_v[-1] + 1.0, 150), s_v[::7], 0.0, s_v[-1]])
        look = np.where(rng.random(s.size) < 0.5, 0.9, rng.uniform(0.3, 2.0, s.size))
        yield path, s_v, s, look


@pytest.mark.parametrize("reach", [0.0, SETTLE_LOOKAHEADS])
def test_chord_kernel_is_the_interpolating_form_bit_for_bit(reach):
    """The chord kernel's own interpolation and its skipped hypot calls give np.interp's form's bits.

    The identity tables hash promises bit for bit, so nothing looser than equality is asserted.
    Negative control: slopes one ulp off (``np.nextafter``) change some bound's bits, so the
    comparison sees a change in the interpolation's last bit.
    """
    from planner.schedule.promise import _CHORDS_CHUNK, _chords_kernel, _chords_kernel_interp

    back = np.linspace(0.0, 1.0, 25) if reach else np.zeros(1)
    frac = np.linspace(0.0, 1.0, 33)
    moved = 0
    for path, s_v, s, look in _chord_cases():
        px, py = np.ascontiguousarray(path[:, 0]), np.ascontiguousarray(path[:, 1])
        chunks = -(-s.size // _CHORDS_CHUNK)
        want, got, off = np.empty(s.size), np.empty(s.size), np.empty(s.size)
        _chords_kernel_interp(0, chunks, px, py, s_v, s, look, reach, back, frac, want)
        slope_x, slope_y = np.diff(px) / np.diff(s_v), np.diff(py) / np.diff(s_v)
        _chords_kernel(0, chunks, px, py, s_v, s, look, reach, back, frac, got, slope_x, slope_y)
        np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64))
        _chords_kernel(0, chunks, px, py, s_v, s, look, reach, back, frac, off,
                       np.nextafter(slope_x, np.inf), np.nextafter(slope_y, np.inf))
        moved += int(np.sum(off.view(np.int64) != want.view(np.int64)))
    assert moved > 0


def test_chords_on_an_axis_aligned_straight_are_zero_and_no_looser_than_the_kernel():
    """Points whose chords all lie on one axis-aligned leg get the bound 0; the others the kernel's bits.

    An L of two axis-aligned legs sampled 0.1 m apart: on a leg every chord lies on the path (the
    exact bound is 0, the kernel's np.interp arithmetic gives 0 or rounding), near the corner the
    kernel's value is kept bit for bit. Negative control: one vertex of the first leg moved
    1e-9 m off its line, the points whose window holds it are computed again (and are > 0).
    """
    from planner.schedule.promise import _CHORDS_CHUNK, _chords, _chords_kernel_interp

    t = np.round(np.linspace(0.0, 20.0, 201), 1)
    ell = np.column_stack([np.minimum(t, 10.0) + 3.7, np.maximum(t - 10.0, 0.0) - 1.3])
    ell = ell[np.r_[True, np.any(np.diff(ell, axis=0) != 0, axis=1)]]
    s_v = np.r_[0.0, np.cumsum(np.hypot(*np.diff(ell, axis=0).T))]
    s = np.linspace(0.05, s_v[-1] - 0.05, 400)
    look = np.full(s.size, 0.9)
    back = np.linspace(0.0, 1.0, 25)

    def kernel(path):
        out = np.empty(s.size)
        _chords_kernel_interp(0, -(-s.size // _CHORDS_CHUNK), np.ascontiguousarray(path[:, 0]),
                              np.ascontiguousarray(path[:, 1]), s_v, s, look, SETTLE_LOOKAHEADS, back,
                              np.linspace(0.0, 1.0, 33), out)
        return out

    got, want = _chords(ell, s_v, s, look, SETTLE_LOOKAHEADS, back), kernel(ell)
    # zeroed: exactly the points whose vertices one spacing either side of [s - 4 look, s + look]
    # lie on one leg (the path's ends clamp, on the same leg)
    leg = [np.all(ell[(s_v >= a - 0.1) & (s_v <= b + 0.1), i] == c)
           for a, b in zip(s - (SETTLE_LOOKAHEADS + 1.0) * look, s + look, strict=True)
           for i, c in ((1, ell[0, 1]), (0, ell[-1, 0]))]
    on_leg = np.array(leg).reshape(-1, 2).any(axis=1)
    zeroed = (got == 0.0) & (want != 0.0)
    assert on_leg.sum() > 200 and np.all(got[on_leg] == 0.0) and not zeroed[~on_leg].any()
    assert np.all(got <= want)
    corner = (s > 10.2) & (s < 12.0)  # the settle window behind holds the corner
    assert np.all(want[corner] > 1e-3)
    np.testing.assert_array_equal(got[~on_leg], want[~on_leg])
    # negative control: a vertex 1e-9 m off the first leg's line
    bent = ell.copy()
    bent[40, 1] += 1e-9
    got_bent, want_bent = _chords(bent, s_v, s, look, SETTLE_LOOKAHEADS, back), kernel(bent)
    near = on_leg & (s - (SETTLE_LOOKAHEADS + 1.0) * look + 0.2 < s_v[40]) & (s_v[40] < s + look - 0.2)
    assert near.any() and np.all(got_bent[near] > 0.0)
    np.testing.assert_array_equal(got_bent[near], want_bent[near])
