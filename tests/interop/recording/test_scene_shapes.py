"""Figures and recordings draw polygon obstacles with their holes, and the workspace at its origin."""

from __future__ import annotations

import dataclasses

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from interop.recording.geometry import rectangle_ring
from tests.scenarios.worlds import hall, shifted
from validation.report.scene import OBSTACLE_STYLE, draw_scene


def _pixel(fig, ax, p) -> np.ndarray:
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    img = np.asarray(canvas.buffer_rgba())[..., :3]
    x, y = ax.transData.transform(p)
    return img[img.shape[0] - int(round(y)), int(round(x))]


def test_a_ring_is_filled_around_its_hole_and_a_u_around_its_cup():
    sc = hall()
    fig = Figure(figsize=(8, 6), dpi=80)
    ax = fig.add_subplot()
    draw_scene(ax, sc, labels=False, docks=False)
    grey = np.array([int(OBSTACLE_STYLE["facecolor"][i:i + 2], 16) for i in (1, 3, 5)])
    solid = [(15.9, 12.2), (10.0, 3.5), (3.0, 11.5)]          # ring, U's bar, pillar
    empty = [(17.25, 12.25), (10.0, 7.0), (3.0, 9.0)]        # the ring's hole, the cup, beside the pillar
    for p in solid:
        assert np.abs(_pixel(fig, ax, p).astype(int) - grey).max() < 10, p
    for p in empty:
        assert _pixel(fig, ax, p).min() > 240, p


def test_the_workspace_is_drawn_at_its_origin():
    sc = shifted("paper-docks", 250.0, -80.0)
    fig = Figure()
    ax = fig.add_subplot()
    draw_scene(ax, sc)
    x0, y0, x1, y1 = sc.workspace.bounds
    lo, hi = ax.get_xlim()
    assert lo < x0 < x1 < hi and (x0, y0) == (250.0, -80.0)
    assert rectangle_ring(*sc.workspace.size, sc.workspace.origin)[2].tolist() == [x1, y1]


def test_the_recording_holds_every_ring_of_every_obstacle_in_the_users_frame(tmp_path):
    from interop import recording
    from interop.recording import entities as E
    from tests.interop.recording.readback import Readback

    sc = hall()
    back = Readback(recording.write_static_rrd(tmp_path / "static.rrd", sc))
    _, strips = back.column(E.OBSTACLES, "LineStrips2D:strips", timeline=None)
    rings = [np.asarray(r) for r in strips[0]]
    # The U, the pillar, the ring's outer face and its hole: closed strips on the faces.
    assert len(rings) == 4 and all(np.array_equal(r[0], r[-1]) for r in rings)
    hole = min(rings, key=lambda r: np.ptp(r, axis=0).prod())
    assert np.allclose(hole.min(axis=0), [16.5, 11.8]) and np.allclose(hole.max(axis=0), [18.0, 12.7])
    far = shifted("paper-docks", 250.0, -80.0)
    back = Readback(recording.write_static_rrd(tmp_path / "far.rrd", far))
    _, ws = back.column(E.WORKSPACE, "LineStrips2D:strips", timeline=None)
    assert np.allclose(np.asarray(ws[0][0]).min(axis=0), [250.0, -80.0])


def test_flat_reflectors_are_drawn_facing_out_in_figures_and_recordings(tmp_path):
    from interop import recording
    from interop.recording import entities as E
    from tests.interop.recording.readback import Readback
    from tests.scenarios.worlds import flat_scenario

    sc = flat_scenario()
    flat = [m for m in sc.markers if m.kind.value == "flat"]
    back = Readback(recording.write_static_rrd(tmp_path / "static.rrd", sc))
    _, vectors = back.column(E.MARKER_FACING, "Arrows2D:vectors", timeline=None)
    got = np.asarray(vectors[0], float)
    want = np.array([m.normal for m in flat]) * 2.0 * sc.robot.radius
    assert np.allclose(got, want)
    # negative control: a scenario of posts logs no facing at all
    posts = dataclasses.replace(sc, markers=tuple(m for m in sc.markers if m.kind.value == "post"))
    back = Readback(recording.write_static_rrd(tmp_path / "posts.rrd", posts))
    assert not back.chunks.get(E.MARKER_FACING)
    # the figure draws each face and its two wedge edges: three lines per flat marker
    fig = Figure()
    ax = fig.add_subplot()
    draw_scene(ax, sc, labels=False, docks=False)
    assert len(ax.lines) == 3 * len(flat)
