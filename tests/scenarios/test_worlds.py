"""The random-world generator (scenarios.worlds): deterministic, loadable, honest, spanning its ranges.

Pure draws, no planning: the plannability loop is tested in ``tests/sim/test_random_worlds.py``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import tomli_w

import scenarios
from scenarios import worlds as W

N_DRAWS = 200


def _rng(i: int, seed: int = 3) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(i,)))


@pytest.fixture(scope="module")
def draws() -> list[tuple[W.DrawnWorld, scenarios.Scenario]]:
    out = []
    for i in range(N_DRAWS):
        d = W.draw_world(_rng(i), f"w{i}")
        out.append((d, scenarios.loads(tomli_w.dumps(d.data), source=f"w{i}.toml")))
    return out


def test_same_generator_state_gives_the_same_bytes():
    for i in range(20):
        a = tomli_w.dumps(W.draw_world(_rng(i), "x").data)
        b = tomli_w.dumps(W.draw_world(_rng(i), "x").data)
        assert a == b, f"draw {i} differs"
    # negative control: another stream gives another world
    assert tomli_w.dumps(W.draw_world(_rng(0), "x").data) != tomli_w.dumps(W.draw_world(_rng(0, seed=4), "x").data)


def test_every_draw_loads_and_is_honest(draws):
    for d, sc in draws:
        assert "actual" not in d.data["sensor"] and "actual" not in d.data["robot"]
        assert sc.sensor_actual == sc.sensor and sc.robot_actual == sc.robot
        assert len(sc.tasks) >= 1 and len(sc.markers) >= sc.sensor.markers_per_fix
        lo, hi = W.EPS_FACTOR_RANGE
        assert lo <= d.eps_factor <= hi


def test_draws_span_the_stated_ranges(draws):
    sensors = [sc.sensor for _, sc in draws]
    robots = [sc.robot for _, sc in draws]
    kinds = {d.summary[0].split()[1] for d, _ in draws}
    assert kinds == set(W.KINDS)
    assert {s.markers_per_fix for s in sensors} == {2, 3, 4}
    assert {sc.planning.pef_model.value for _, sc in draws} == {"exact", "parallelogram", "strips", "gdop"}
    assert {s.noise.value for s in sensors} == {"uniform", "gaussian"}
    bearings = [s.bearing_error for s in sensors]
    assert min(bearings) == 0.0 and max(bearings) > 0.0

    def spans(values, lo, hi, reach=0.15):
        """All within [lo, hi], and both ends approached within ``reach`` of the (log) range."""
        v = np.asarray(values, float)
        assert v.min() >= lo and v.max() <= hi, (v.min(), v.max(), lo, hi)
        return v.min() <= lo + reach * (hi - lo) and v.max() >= hi - reach * (hi - lo)

    assert spans(np.log([s.relative_error for s in sensors]), *np.log(W.RE_RANGE))
    assert spans(np.log([s.absolute_error for s in sensors]), *np.log(W.RHO0_RANGE))
    assert spans([r.max_speed for r in robots], *W.SPEED_RANGE)
    assert spans(np.log([r.encoder_ticks for r in robots]), *np.log(W.TICKS_RANGE))
    assert spans([r.odometry_noise for r in robots], *W.SLIP_RANGE)
    origins = np.array([sc.workspace.origin for _, sc in draws])
    assert (np.abs(origins).max(axis=1) == 0).any()
    assert np.abs(origins).max() > 1e5 and np.abs(origins).max() <= W.FAR_ORIGIN
    red = np.array([sc.planning.redundancy for _, sc in draws])
    block = np.array([s.block_probability for s in sensors])
    assert set(red) == {0, 1}
    assert (block[red == 1] > 0).all() and (block[red == 0] == 0).all()
    kinds_m = {m.kind.value for _, sc in draws for m in sc.markers}
    assert kinds_m == {"post", "flat"}
    obstacle_keys = {frozenset(o) for d, _ in draws for o in d.data["obstacles"]}
    assert {frozenset({"center", "size"}), frozenset({"polygon"}), frozenset({"polygon", "holes"}),
            frozenset({"center", "radius"})} <= obstacle_keys


def test_flat_reflectors_face_into_the_open(draws):
    """Check that a flat reflector sits on a wall and faces away from it.

    A step along its normal is free, a step against it is in the wall (an obstacle or outside the workspace: the
    negative control).
    """
    checked = 0
    for _, sc in draws[:40]:
        x0, y0 = sc.workspace.origin
        w, h = sc.workspace.size
        for m in sc.markers:
            if m.kind.value != "flat":
                continue
            p = np.asarray(m.position) + 0.05 * np.array([math.cos(m.facing), math.sin(m.facing)])
            assert x0 < p[0] < x0 + w and y0 < p[1] < y0 + h, (sc.name, m.id)
            assert not any(o.contains(p) for o in sc.obstacles), (sc.name, m.id)
            q = np.asarray(m.position) - 0.05 * np.array([math.cos(m.facing), math.sin(m.facing)])
            inside = x0 < q[0] < x0 + w and y0 < q[1] < y0 + h
            assert not inside or any(o.contains(q) for o in sc.obstacles), (sc.name, m.id)
            checked += 1
    assert checked > 0
