"""Recordings: read the .rrd back and check entities, values, times, placement and blueprint."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest
import rerun as rr
from rerun.chunk import RrdReader
from scipy import stats

import scenarios
from interop import recording
from interop.recording import entities as E
from interop.recording import episode as recording_episode
from interop.recording.geometry import covariance_ellipses, level_contours, strip_polygons
from scenarios.errors import OutputError
from sim.episode.types import EpisodeResult, FixLog, StepLog
from tests.interop.recording.readback import Readback


@pytest.fixture(autouse=True)
def _strict_rerun():
    # API misuse must fail the test instead of becoming a warning; restored afterwards.
    before = rr.strict_mode()
    rr.set_strict_mode(True)
    yield
    rr.set_strict_mode(before)


# --------------------------------------------------------------------------------------------
# synthetic inputs


def synthetic_episode(scenario, n_steps: int = 600, n_fixes: int = 30, seed: int = 1) -> EpisodeResult:
    """Build an EpisodeResult with the real shapes: a straight drive from dock A to dock B."""
    rng = np.random.default_rng(seed)
    a, b = np.array(scenario.dock("A").position), np.array(scenario.dock("B").position)
    t = np.arange(n_steps) * 0.05
    s = np.linspace(0.0, 1.0, n_steps)
    xy = a + s[:, None] * (b - a)
    theta = np.full(n_steps, math.atan2(*(b - a)[::-1])) + 0.05 * np.sin(t)
    true_pose = np.column_stack([xy, theta])
    est_pose = true_pose + rng.normal(0.0, [0.004, 0.004, 0.002], size=(n_steps, 3))
    root = rng.normal(size=(n_steps, 3, 3)) * 0.003
    est_cov = root @ np.swapaxes(root, 1, 2) + np.eye(3) * 1e-6
    error = np.hypot(*(true_pose[:, :2] - est_pose[:, :2]).T)
    predicted_tau = 0.01 + 0.005 * s
    predicted_tau[:5] = np.inf  # no fix yet: the schedule promises nothing
    steps = StepLog(t=t, true_pose=true_pose, est_pose=est_pose, est_cov=est_cov, error=error,
                    predicted_tau=predicted_tau, pef_tau=predicted_tau * 0.8,
                    nees=rng.chisquare(3, n_steps))

    k = scenario.sensor.markers_per_fix
    step_of_fix = np.linspace(10, n_steps - 1, n_fixes).astype(int)
    true_position = true_pose[step_of_fix, :2]
    mpos = scenario.marker_positions()
    dist = np.linalg.norm(true_position[:, None, :] - mpos[None], axis=-1)
    markers = np.argsort(dist, axis=1)[:, :k]
    r_true = np.take_along_axis(dist, markers, axis=1)
    rho = scenario.sensor.range_bound(r_true)
    ranges = r_true + rng.uniform(-1, 1, size=r_true.shape) * rho
    # Fault polygons of varying vertex counts (regular n-gons around the truth).
    polys = []
    for f in range(n_fixes):
        n = 4 + f % 5
        ang = np.linspace(0, 2 * np.pi, n, endpoint=False)
        ring = true_position[f] + 0.002 * np.column_stack([np.cos(ang), np.sin(ang)])
        polys.append(np.vstack([ring, ring[:1]]))
    polys[5] = np.zeros((0, 2))  # inconsistent measurements: empty fault area, nan diameter
    diameter = np.full(n_fixes, 0.004)
    diameter[5] = np.nan
    fixes = FixLog(t=t[step_of_fix], markers=markers, ranges=ranges, rho=rho, true_position=true_position,
                   snapshot=true_position + rng.normal(0, 0.001, true_position.shape),
                   snapshot_cov=np.tile(np.eye(2) * 1e-6, (n_fixes, 1, 1)),
                   fault_diameter=diameter, fault_polygons=polys,
                   contained=np.arange(n_fixes) % 7 != 3, predicted_tau=np.full(n_fixes, 0.005),
                   static_tau=np.full(n_fixes, 0.004),
                   nis=rng.chisquare(k, n_fixes), n_accepted=np.full(n_fixes, k))
    plan = synthetic_plan(scenario, xy)
    return EpisodeResult(scenario_name=scenario.name, task_index=0, seed=seed,
                         eps_max=scenario.planning.eps_max, steps=steps, fixes=fixes, plan=plan,
                         summary={"reached": True, "rmse": float(np.sqrt(np.mean(error ** 2)))})


def synthetic_plan(scenario, path_xy: np.ndarray) -> SimpleNamespace:
    """Stand-in for planner.plan.Plan with the attribute names recording uses."""
    a, b = path_xy[0], path_xy[-1]
    detour = np.array([a, [a[0], b[1]], b])
    candidates = [SimpleNamespace(polyline=np.array([a, b]), admissible=True, id="direct"),
                  SimpleNamespace(polyline=detour, admissible=False, id="detour")]
    fixes = tuple(SimpleNamespace(position=tuple(p), markers=(0, 1), tau=0.01, switch=i == 2)
                  for i, p in enumerate(path_xy[::100]))
    return SimpleNamespace(candidates=candidates, chosen=0, path=path_xy,
                           schedule=SimpleNamespace(fixes=fixes))


def synthetic_pef_map(scenario) -> SimpleNamespace:
    """Build a PefMap-like namespace.

    tau grows with the distance from an off-centre point (so no flip maps the map onto
    itself) and is inf in the lower-left corner.
    """
    w, h = scenario.workspace.size
    nx, ny = 60, 40
    x = (np.arange(nx) + 0.5) * w / nx
    y = (np.arange(ny) + 0.5) * h / ny
    X, Y = np.meshgrid(x, y)
    centre = (0.4 * w, 0.35 * h)
    tau = 0.005 + 0.003 * np.hypot(X - centre[0], Y - centre[1])
    tau[:5, :5] = np.inf
    return SimpleNamespace(x=x, y=y, tau=tau, cell_size=(w / nx, h / ny), centre=centre)


# --------------------------------------------------------------------------------------------
# reading back


@pytest.fixture(scope="module")
def warehouse():
    return scenarios.load("warehouse")


@pytest.fixture(scope="module")
def episode(warehouse):
    return synthetic_episode(warehouse)


@pytest.fixture(scope="module")
def pef_map(warehouse):
    return synthetic_pef_map(warehouse)


@pytest.fixture(scope="module")
def episode_rrd(tmp_path_factory, warehouse, episode, pef_map):
    before = rr.strict_mode()
    rr.set_strict_mode(True)
    try:
        path = recording.write_episode_rrd(tmp_path_factory.mktemp("rrd") / "episode.rrd", warehouse, episode,
                                           pef_map=pef_map)
    finally:
        rr.set_strict_mode(before)
    return path


@pytest.fixture(scope="module")
def readback(episode_rrd):
    return Readback(episode_rrd)


# --------------------------------------------------------------------------------------------
# the recording


def test_every_contract_entity_is_present(readback):
    expected = set(E.STATIC_ENTITIES + E.MAP_ENTITIES + E.PLAN_ENTITIES + E.EPISODE_ENTITIES)
    missing = sorted(expected - set(readback.chunks))
    assert not missing, f"entities missing from the recording: {missing}"


def test_one_fault_area_polygon_per_fix_with_its_vertices(readback, episode):
    times, rows = readback.column(E.FIX_FAULT_AREA, "LineStrips2D:strips")
    assert len(rows) == len(episode.fixes.t)
    np.testing.assert_array_equal(times, np.round(episode.fixes.t * 1e9).astype(np.int64))
    for row, poly in zip(rows, episode.fixes.fault_polygons, strict=True):
        assert len(row) == 1  # one polygon per fix
        np.testing.assert_allclose(np.array(row[0]).reshape(-1, 2), poly, atol=1e-5)  # float32 in the file
    _, colors = readback.column(E.FIX_FAULT_AREA, "LineStrips2D:colors")
    red = int.from_bytes(bytes([*E.NOT_CONTAINED, 255]), "big")
    assert [c[0] == red for c in colors] == list(~episode.fixes.contained)


def test_error_series_equals_the_episode_values_and_times(readback, episode):
    times, rows = readback.column(E.ERROR, "Scalars:scalars")
    np.testing.assert_array_equal(times, np.round(episode.steps.t * 1e9).astype(np.int64))
    np.testing.assert_array_equal(np.array(rows)[:, 0], episode.steps.error)  # float64, exact


def test_predicted_tau_inf_becomes_a_gap_and_eps_max_spans_the_run(readback, episode):
    _, rows = readback.column(E.PREDICTED_TAU, "Scalars:scalars")
    values = np.array(rows)[:, 0]
    finite = np.isfinite(episode.steps.predicted_tau)
    assert np.isnan(values[~finite]).all()
    np.testing.assert_array_equal(values[finite], episode.steps.predicted_tau[finite])
    times, rows = readback.column(E.EPS_MAX, "Scalars:scalars")
    assert np.array(rows)[:, 0].tolist() == [episode.eps_max] * 2
    assert times.tolist() == [0, round(episode.steps.t[-1] * 1e9)]


def test_rays_join_the_true_position_to_each_measured_marker(readback, episode, warehouse):
    _, rows = readback.column(E.FIX_RAYS, "LineStrips2D:strips")
    k = episode.fixes.markers.shape[1]
    assert len(rows) == len(episode.fixes.t) and all(len(r) == k for r in rows)
    f = 7
    ray = np.array(rows[f])  # (k, 2, 2)
    np.testing.assert_allclose(ray[:, 0], np.repeat(episode.fixes.true_position[f:f + 1], k, 0), atol=1e-5)
    np.testing.assert_allclose(ray[:, 1], warehouse.marker_positions()[episode.fixes.markers[f]], atol=1e-5)


def test_heatmap_pixel_lands_on_its_cell(readback, pef_map, warehouse):
    (row,) = readback.column(E.PEF, "DepthImage:buffer", timeline=None)[1]
    (fmt,) = readback.column(E.PEF, "DepthImage:format", timeline=None)[1]
    (tr,) = readback.column(E.PEF, "Transform3D:translation", timeline=None)[1]
    (sc,) = readback.column(E.PEF, "Transform3D:scale", timeline=None)[1]
    width, height = fmt[0]["width"], fmt[0]["height"]
    assert (height, width) == pef_map.tau.shape
    image = np.frombuffer(bytes(row[0]), dtype=np.float32).reshape(height, width)
    translation, scale = np.array(tr[0]), np.array(sc[0])
    cap = 2.0 * warehouse.planning.eps_max
    # An image pixel (col, row) covers [col, col+1) x [row, row+1): its centre is at +0.5.
    for r, c in [(3, 50), (37, 2), (20, 31)]:
        centre_m = translation[:2] + scale[:2] * (np.array([c, r]) + 0.5)
        np.testing.assert_allclose(centre_m, [pef_map.x[c], pef_map.y[r]], atol=1e-5)
        assert image[r, c] == pytest.approx(min(pef_map.tau[r, c], cap), rel=1e-6)
    # Negative control: the image convention with row 0 at the top would put this cell elsewhere.
    r, c = 3, 50
    assert image[height - 1 - r, c] != pytest.approx(image[r, c], rel=1e-3)
    assert np.all(image[:5, :5] == np.float32(cap))  # tau = inf shows as the cap


def test_no_fix_cells_are_drawn_apart_from_bad(readback, pef_map):
    """τ = ∞ cells (racks, cells seeing no usable subset) get their own colour over the heatmap, not its "bad" end."""
    (row,) = readback.column(E.PEF_NO_FIX, "Image:buffer", timeline=None)[1]
    (fmt,) = readback.column(E.PEF_NO_FIX, "Image:format", timeline=None)[1]
    width, height = fmt[0]["width"], fmt[0]["height"]
    layer = np.frombuffer(bytes(row[0]), dtype=np.uint8).reshape(height, width, 4)
    inf = ~np.isfinite(pef_map.tau)
    assert inf.any() and (~inf).any()
    assert np.all(layer[inf] == np.array(E.NO_FIX_CELL, dtype=np.uint8))
    assert np.all(layer[~inf, 3] == 0)  # cells with a fix show the heatmap through
    # the heatmap's top colour (viridis at the cap, where finite bad tau ends up) is far from it
    from matplotlib import colormaps

    top = np.array(colormaps["viridis"](1.0)[:3]) * 255.0
    assert np.abs(top - np.array(E.NO_FIX_CELL[:3])).max() > 100
    # negative control: a layer from finite tau paints nothing
    from interop.recording.static import no_fix_layer

    assert not no_fix_layer(np.where(inf, 1.0, pef_map.tau))[..., 3].any()


def test_world_is_flipped_once_for_the_y_down_2d_view(readback):
    (sc,) = readback.column(E.WORLD, "Transform3D:scale", timeline=None)[1]
    assert sc[0] == [1.0, -1.0, 1.0]


def test_region_contour_lies_on_eps_max(readback, pef_map, warehouse):
    _, rows = readback.column(E.REGION, "LineStrips2D:strips", timeline=None)
    pts = np.concatenate([np.array(s) for s in rows[0]])
    radius = (warehouse.planning.eps_max - 0.005) / 0.003  # where the synthetic tau reaches eps_max
    dist = np.hypot(pts[:, 0] - pef_map.centre[0], pts[:, 1] - pef_map.centre[1])
    assert np.abs(dist - radius).max() < 0.1  # linear interpolation on a 0.5 m grid of a cone


def test_blueprint_is_stored_with_map_and_plots(episode_rrd):
    reader = RrdReader(episode_rrd)
    (entry,) = reader.blueprints()
    assert entry.application_id == E.APPLICATION_ID
    views, contents = {}, []
    for chunk in reader.stream(store=entry).to_chunks():
        batch = chunk.to_record_batch()
        if "ViewBlueprint:class_identifier" in batch.schema.names:
            views[batch.column("ViewBlueprint:class_identifier").to_pylist()[0][0]] = chunk.entity_path
        if "ViewContents:query" in batch.schema.names:
            contents.extend(batch.column("ViewContents:query").to_pylist()[0])
    assert {"2D", "TimeSeries", "TextLog", "TextDocument"} <= set(views)
    assert "/world/**" in contents
    assert {f"/{E.ERROR}", f"/{E.PREDICTED_TAU}", f"/{E.EPS_MAX}", f"/{E.NEES}", f"/{E.NIS}"} <= set(contents)


def test_rerun_rrd_verify_accepts_the_file(episode_rrd):
    env = {**os.environ, "CI": "1"}  # the CLI stays silent about analytics where CI is set
    done = subprocess.run([sys.executable, "-m", "rerun", "rrd", "verify", str(episode_rrd)],
                          capture_output=True, text=True, env=env, timeout=60)
    assert done.returncode == 0, done.stderr


def test_episode_without_fixes_records_its_steps(tmp_path, warehouse):
    ep = synthetic_episode(warehouse, n_steps=20, n_fixes=6)
    arrays = {name: None if value is None else value[:0] for name, value in vars(ep.fixes).items()
              if name != "fault_polygons"}
    ep.fixes = FixLog(**arrays, fault_polygons=[])  # every per-fix array cut to F = 0
    back = Readback(recording.write_episode_rrd(tmp_path / "nofix.rrd", warehouse, ep))
    _, rows = back.column(E.ERROR, "Scalars:scalars")
    assert np.array(rows)[:, 0].tolist() == ep.steps.error.tolist()
    assert E.FIX_FAULT_AREA not in back.chunks


def test_events_warn_where_error_first_exceeds_eps_max_and_log_every_fix(tmp_path, warehouse):
    ep = synthetic_episode(warehouse, n_steps=200, n_fixes=10)
    ep.steps.error[:] = 0.5 * ep.eps_max
    ep.steps.error[[50, 51, 52, 120]] = 2.0 * ep.eps_max  # two excursions above eps_max
    back = Readback(recording.write_episode_rrd(tmp_path / "events.rrd", warehouse, ep))
    times, texts = back.column(E.EVENTS, "TextLog:text")
    _, levels = back.column(E.EVENTS, "TextLog:level")
    rows = zip(times, texts, levels, strict=True)
    violations = [(int(t), lv[0]) for t, tx, lv in rows if tx[0].startswith("error")]
    assert violations == [(round(ep.steps.t[i] * 1e9), "WARN") for i in (50, 120)]  # rising edges only
    assert sum(tx[0].startswith("fix ") for tx in texts) == 10


def test_static_recording_has_no_timeline_data(tmp_path, warehouse, pef_map, episode):
    path = recording.write_static_rrd(tmp_path / "static.rrd", warehouse, pef_map=pef_map, plan=episode.plan)
    back = Readback(path)
    assert set(E.STATIC_ENTITIES + E.MAP_ENTITIES + E.PLAN_ENTITIES) <= set(back.chunks)
    assert all(c.is_static for chunks in back.chunks.values() for c in chunks)
    _, labels = back.column(E.MARKERS, "Points2D:labels", timeline=None)
    assert labels[0] == warehouse.marker_ids()
    _, sched = back.column(E.SCHEDULE, "Points2D:positions", timeline=None)
    assert len(sched[0]) == len(episode.plan.schedule.fixes)
    _, text = back.column(E.PLAN_TEXT, "TextDocument:text", timeline=None)
    assert "| **direct (chosen)** | yes |" in text[0][0] and "| detour | no |" in text[0][0]


@pytest.mark.parametrize("make_path", [
    lambda d: d / "missing-dir" / "x.rrd",
    lambda d: d,                                         # a directory
    lambda d: (d / "plain-file").joinpath("x.rrd"),      # parent is a file
], ids=["missing-dir", "is-dir", "parent-is-file"])
def test_unwritable_path_raises_output_error_before_any_work(tmp_path, warehouse, episode, make_path):
    (tmp_path / "plain-file").write_text("")
    path = make_path(tmp_path)
    with pytest.raises(OutputError, match=r": cannot write recording: "):
        recording.write_episode_rrd(path, warehouse, episode)
    assert not (tmp_path / "missing-dir").exists()


def test_the_check_before_the_work_leaves_the_path_as_it_was(tmp_path):
    # a run whose task does not plan fails after this check: it must not leave an empty recording
    # where none was, nor empty one the user already had (opening for writing truncates it)
    new, old = tmp_path / "new.rrd", tmp_path / "old.rrd"
    old.write_bytes(b"an earlier recording")
    assert recording.check_writable(new) == new and recording.check_writable(old) == old
    assert not new.exists()
    assert old.read_bytes() == b"an earlier recording"


# --------------------------------------------------------------------------------------------
# geometry (independent cross-checks)


def test_covariance_ellipse_is_the_p_level_contour():
    rng = np.random.default_rng(5)
    root = rng.normal(size=(20, 2, 2))
    cov = root @ np.swapaxes(root, 1, 2) + 0.01 * np.eye(2)
    centers = rng.normal(size=(20, 2))
    p = 0.95
    rings = covariance_ellipses(centers, cov, p)
    d = rings - centers[:, None, :]
    maha = np.einsum("tsi,tij,tsj->ts", d, np.linalg.inv(cov), d)
    # scipy's quantile is independent of the closed form used in the module
    np.testing.assert_allclose(maha, stats.chi2.ppf(p, 2), rtol=1e-9)
    assert not np.allclose(maha, stats.chi2.ppf(0.5, 2), rtol=1e-2)  # another level is distinguishable


def test_nees_reference_constant_is_the_chi2_quantile():
    assert recording_episode.CHI2_3DOF_975 == pytest.approx(stats.chi2.ppf(0.975, 3), rel=1e-12)


def test_strip_polygon_of_two_markers_is_the_papers_parallelogram():
    rng = np.random.default_rng(9)
    pos = rng.uniform(2, 8, size=(50, 2))
    mk = rng.uniform(0, 10, size=(50, 2, 2))
    rho = rng.uniform(0.001, 0.003, size=(50, 2))
    rings = strip_polygons(pos, mk, rho)
    u = (pos[:, None] - mk) / np.linalg.norm(pos[:, None] - mk, axis=-1, keepdims=True)
    sin_a = np.abs(u[:, 0, 0] * u[:, 1, 1] - u[:, 0, 1] * u[:, 1, 0])
    for ring, s, r in zip(rings, sin_a, rho, strict=True):
        x, y = ring[:-1, 0], ring[:-1, 1]
        area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
        assert len(ring) == 5
        assert area == pytest.approx(4 * r[0] * r[1] / s, rel=1e-9)  # docs/design.md §1 (paper eq. 10)


def test_local_strip_polygons_agree_with_estimators_linearized():
    from estimators.fault import linearized

    rng = np.random.default_rng(3)
    pos = rng.uniform(2, 8, size=(10, 2))
    mk = rng.uniform(0, 10, size=(10, 3, 2))
    rho = rng.uniform(0.001, 0.003, size=(10, 3))
    for ring, p, m, r in zip(strip_polygons(pos, mk, rho), pos, mk, rho, strict=True):
        u, _ = linearized.unit_rows(m, p)
        ref = linearized.strip_polygon(u, r)
        x, y = ring[:-1, 0], ring[:-1, 1]
        area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
        assert area == pytest.approx(ref.area, rel=1e-9)


def test_level_contours_in_tiles_trace_the_same_lines_and_reuse_unchanged_tiles(monkeypatch):
    """With a cache the grid is traced in tiles: the same lines (broken at tile borders); an edit re-traces its tile."""
    from interop.recording import geometry

    monkeypatch.setattr(geometry, "CONTOUR_TILE", 16)
    x = np.linspace(-5, 5, 101)
    X, Y = np.meshgrid(x, x)
    z = np.hypot(X, Y)
    z[0, 0] = np.inf

    def length(lines):
        return sum(float(np.hypot(*np.diff(line, axis=0).T).sum()) for line in lines)

    cache: dict = {}
    (whole,) = level_contours(x, x, z, 3.0)
    tiled = level_contours(x, x, z, 3.0, cache=cache)
    assert len(tiled) > 1 and len(cache) == 49  # 7 x 7 tiles of 16 cells (17 with the shared border)
    assert length(tiled) == pytest.approx(length([whole]), rel=1e-12)
    np.testing.assert_allclose(np.hypot(*np.vstack(tiled).T), 3.0, atol=5e-3)
    before = dict(cache)
    z2 = z.copy()
    z2[50:54, 76:79] = 10.0  # a bump just inside the circle's right, in tile (48, 64) only (cols 64..80)
    again = level_contours(x, x, z2, 3.0, cache=cache)
    changed = [k for k in cache if cache[k] is not before[k]]
    assert changed == [(48, 64)]
    assert length(again) != pytest.approx(length(tiled), rel=1e-6)  # the changed tile was traced anew
    assert length(again) == pytest.approx(length(level_contours(x, x, z2, 3.0)), rel=1e-12)


def test_level_contours_trace_a_known_circle():
    x = np.linspace(-5, 5, 101)
    X, Y = np.meshgrid(x, x)
    z = np.hypot(X, Y)
    z[0, 0] = np.inf
    (line,) = level_contours(x, x, z, 3.0)
    np.testing.assert_allclose(np.hypot(*line.T), 3.0, atol=5e-3)
