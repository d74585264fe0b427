"""On drawings and maps not in the repository, the PEF sees what the floor does.

Random DXF drawings and random ROS occupancy maps (fixed seeds) are written into tmp_path,
loaded through ``[floorplan]``, and the planner's visibility on the PEF grid
(:func:`planner.pef.visibility.scenario_visible_grid`) is compared, cell by cell and marker by
marker, with a line of sight computed here from the *raw* geometry the test drew: shapely on
the drawing's shapes in metres, or a walk over the raw occupancy grid. The PEF map's tau is
then compared with tau computed by the planner's scalar models from *this* visibility.

Where the importer may legitimately differ from the raw geometry (simplification, the
circumscribed polygon of a circle, the 1 µm line-of-sight shrink), a cell is left out of the
comparison for a marker only when its answer is not decided by the raw geometry grown and
shrunk by that band: "surely visible" = the segment misses the raw obstacles *grown* by the
band, "surely blocked" = it enters the raw obstacles *shrunk* by it (or the cell is not free, or
out of range). The planner must say visible for every surely visible pair and blocked for every
surely blocked one; the undecided pairs must be few. A negative control per kind (one obstacle
left out of the raw geometry; the raw grid shifted by more than the band) must disagree.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from pathlib import Path

import ezdxf
import numba
import numpy as np
import pytest
import shapely
from scipy import ndimage
from shapely import affinity
from shapely.geometry import LineString, Point, Polygon, box

import scenarios
from planner.pef import scalar
from planner.pef.map import PEF
from planner.pef.visibility import scenario_visible_grid
from scenarios.geometry import CIRCLE_SAGITTA

WALL = 0.2          # floorplan.wall_thickness [m]
SIMPLIFY = 0.02     # floorplan.simplify, the DXF default [m]
MAX_RANGE = 12.0    # sensor.max_range [m]: shorter than the halls, so the range limit shows
LAYERS = ("A-WALL", "A-RACK", "S-COLS")
MARKER_LAYER = "AGV-REFL"
QUAD_SEGS = 64      # our own circles: 256-gons, at most r (1 - cos(pi/256)) < 3e-5 m inside the circle
# The band around the raw geometry within which the importer's obstacles may lie:
# - SIMPLIFY: the reader keeps its polygons within it of the drawing (half flattens arcs and
#   bulges, half is Douglas-Peucker simplification, whose result stays within its tolerance);
# - CIRCLE_SAGITTA: a CIRCLE is planned as its circumscribed polygon, vertices up to 1 mm out;
# - 3e-5: our 256-gon lies that much inside the true circle;
# - 1e-6: line of sight is tested against pieces shrunk by visibility.BOX_SHRINK.
DXF_BAND = SIMPLIFY + CIRCLE_SAGITTA + 3e-5 + 1e-6
NEAR_MARKER = 0.3   # [m] markers keep this far from vertices and other obstacles (see dxf_sure)
GAP = 0.6           # [m] free space kept around each placed obstacle (aisles)
RANGE_EPS = 1e-9    # [m] a distance this close to max_range is undecided (rounding)


# ----------------------------------------------------------------------------- comparison


@dataclass
class Sure:
    """What the raw geometry decides, per marker and cell: shapes (M, ny, nx) bool."""

    visible: np.ndarray
    blocked: np.ndarray      # not free, out of range, or the segment enters an obstacle
    by_obstacle: np.ndarray  # free and in range, but the segment enters an obstacle


def planner_view(sc):
    """Return the PEF map and the planner's visibility on its grid, vis (M, ny, nx).

    Without the plan's line-of-sight margin (``sight=False``): the geometry read from the
    drawing or map is what is compared with the raw file.
    """
    pm = PEF(sc, sight=False).grid()
    vis, free = scenario_visible_grid(sc, pm.x, pm.y, sight=False)
    assert np.array_equal(free, pm.free)
    return pm, vis


def mismatches(vis: np.ndarray, sure: Sure) -> int:
    """Pairs the raw geometry decides and the planner answers otherwise."""
    return int(np.count_nonzero(vis & sure.blocked) + np.count_nonzero(~vis & sure.visible))


def assert_agree(vis: np.ndarray, sure: Sure, max_undecided: float) -> None:
    assert not np.any(sure.visible & sure.blocked), "the band logic is broken: a pair is both"
    bad = np.argwhere((vis & sure.blocked) | (~vis & sure.visible))
    assert len(bad) == 0, f"{len(bad)} (marker, iy, ix) pairs disagree, first {bad[:5].tolist()}"
    n = vis.size
    undecided = n - np.count_nonzero(sure.visible | sure.blocked)
    assert undecided <= max_undecided * n, f"{undecided} of {n} pairs undecided"
    # non-trivial: many pairs seen, many hidden by an obstacle (not only by range or walls' inside)
    assert np.count_nonzero(sure.visible) > 0.08 * n
    assert np.count_nonzero(sure.by_obstacle) > 0.10 * n


def pair_tau(model: int, p, markers, sub, sensor) -> float:
    """Tau of one pair at ``p`` by the planner's scalar model (float64)."""
    scratch = np.empty(4), np.empty(4), np.empty(4)
    return float(scalar.subset_tau(model, float(p[0]), float(p[1]), markers[:, 0].copy(), markers[:, 1].copy(),
                                   np.asarray(sub, dtype=np.int64), sensor.relative_error, sensor.absolute_error,
                                   0.0, 0.0, *scratch))


def eq12(p, m1, m2, sensor) -> float:
    """Compute the paper's long diagonal (eq. 12) of the parallelogram of markers m1, m2 at p, in numpy."""
    d1, d2 = p - m1, p - m2
    r1, r2 = np.hypot(*d1), np.hypot(*d2)
    rho1, rho2 = sensor.relative_error * r1 + sensor.absolute_error, sensor.relative_error * r2 + sensor.absolute_error
    sin_a = abs(d1[0] * d2[1] - d1[1] * d2[0]) / (r1 * r2)
    cos_a = abs(d1 @ d2) / (r1 * r2)
    return 2.0 / sin_a * math.sqrt(rho1 ** 2 + rho2 ** 2 + 2 * rho1 * rho2 * cos_a)


def assert_tau_agrees(sc, pm, sure: Sure, rng: np.random.Generator, n: int = 300) -> None:
    """Check the PEF map's tau, on cells decided for every marker, against tau from our visibility."""
    decided = (sure.visible | sure.blocked).all(axis=0) & pm.free
    cells = np.argwhere(decided)
    pick = cells[rng.choice(len(cells), size=min(n, len(cells)), replace=False)]
    markers = sc.marker_positions()
    assert sc.sensor.markers_per_fix == 2 and pm.model.value == "parallelogram"
    finite = 0
    for iy, ix in pick:
        p = np.array([pm.x[ix], pm.y[iy]])
        seen = np.flatnonzero(sure.visible[:, iy, ix])
        taus = [pair_tau(scalar.PARALLELOGRAM, p, markers, s, sc.sensor) for s in itertools.combinations(seen, 2)]
        want = min(taus, default=math.inf)
        got = pm.tau[iy, ix]
        if math.isinf(want):
            assert math.isinf(got), (p, got)
            continue
        finite += 1
        # the grid kernel ranks pairs in float32 and recomputes the winner in float64: a near tie
        # may pick the other pair of the tie, within float32's resolution of the best
        assert got == pytest.approx(want, rel=1e-6), (p, got, want)
        s = min(itertools.combinations(seen, 2),
                key=lambda s: pair_tau(scalar.PARALLELOGRAM, p, markers, s, sc.sensor))
        assert eq12(p, markers[s[0]], markers[s[1]], sc.sensor) == pytest.approx(want, rel=1e-9)
    assert finite > 0.3 * len(pick), (finite, len(pick))  # mostly cells where a fix is possible


# ----------------------------------------------------------------------------- DXF drawings


@dataclass
class Drawing:
    """The raw geometry of a generated drawing, in metres."""

    shapes: list[tuple[str, shapely.Geometry]]  # (what, solid region) in drawing order
    markers: np.ndarray                          # (M, 2)


def _rect(length, width):
    return box(-length / 2, -width / 2, length / 2, width / 2)


def _ell(rng):
    a, d = rng.uniform(2.0, 4.0), rng.uniform(2.0, 3.0)
    b, c = rng.uniform(0.6, 1.0), rng.uniform(0.6, 1.0)
    g = Polygon([(0, 0), (a, 0), (a, b), (c, b), (c, d), (0, d)])
    return affinity.translate(g, -a / 2, -d / 2)


def _u_shape(rng):
    a, d, t = rng.uniform(2.5, 4.0), rng.uniform(1.5, 2.5), rng.uniform(0.5, 0.8)
    g = Polygon([(0, 0), (a, 0), (a, d), (a - t, d), (a - t, t), (t, t), (t, d), (0, d)])
    return affinity.translate(g, -a / 2, -d / 2)


BLOCK_T = Polygon([(-1.0, -0.3), (1.0, -0.3), (1.0, 0.3), (0.3, 0.3), (0.3, 1.2), (-0.3, 1.2), (-0.3, 0.3),
                   (-1.0, 0.3)])  # block UNIT's outline (concave) [m, block frame]
BLOCK_CIRCLE = ((1.6, 0.0), 0.2)  # block UNIT's circle: centre, radius [m, block frame]


def random_drawing(rng: np.random.Generator, path: Path, per_m: float, insunits: int) -> Drawing:
    """Write a random hall as DXF (``per_m`` drawing units per metre) and return its raw geometry."""
    doc = ezdxf.new("R2018")
    doc.header["$INSUNITS"] = insunits
    for name in (*LAYERS, MARKER_LAYER):
        doc.layers.add(name)
    msp = doc.modelspace()

    def u(pts):
        return [(float(x) * per_m, float(y) * per_m) for x, y in pts]

    def wall(a, b):  # a centre line and what the importer documents it as: square caps, thickness WALL
        msp.add_line(*u([a, b]), dxfattribs={"layer": "A-WALL"})
        return LineString([a, b]).buffer(WALL / 2, cap_style="square", join_style="mitre")

    w, h = rng.uniform(20.0, 25.0), rng.uniform(13.0, 16.0)
    shapes: list[tuple[str, shapely.Geometry]] = []
    corners = [(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)]
    for a, b in zip(corners, corners[1:] + corners[:1], strict=True):
        shapes.append(("wall", wall(a, b)))
    # a slanted partition wall from the south wall into the hall
    x0 = rng.uniform(0.35, 0.65) * w
    shapes.append(("partition", wall((x0, 0.0), (x0 + rng.uniform(-1.5, 1.5), rng.uniform(0.25, 0.4) * h))))

    room = box(WALL / 2 + GAP, WALL / 2 + GAP, w - WALL / 2 - GAP, h - WALL / 2 - GAP)
    taken = shapes[-1][1].buffer(GAP)

    def place(g):
        nonlocal taken
        for _ in range(500):
            yaw, c = rng.uniform(0.0, 180.0), (rng.uniform(0, w), rng.uniform(0, h))
            moved = affinity.translate(affinity.rotate(g, yaw, origin=(0, 0)), *c)
            if room.contains(moved) and not taken.intersects(moved):
                taken = taken.union(moved.buffer(GAP))
                return moved, yaw, c
        raise AssertionError("no room left in the random hall: change the seed or the sizes")

    for what in ("rack", "rack", "rack", "ell", "u"):
        g = {"rack": lambda: _rect(rng.uniform(3.0, 6.0), rng.uniform(0.8, 1.4)), "ell": lambda: _ell(rng),
             "u": lambda: _u_shape(rng)}[what]()
        g, _, _ = place(g)
        msp.add_lwpolyline(u(g.exterior.coords[:-1]), close=True, dxfattribs={"layer": "A-RACK"})
        shapes.append((what, g))
    # a rack with a round end: a closed LWPOLYLINE whose bulge 1 is a half circle (flattened by the reader)
    length, width = rng.uniform(3.0, 5.0), rng.uniform(0.8, 1.2)
    corners = np.array([(-length / 2, -width / 2), (length / 2, -width / 2), (length / 2, width / 2),
                        (-length / 2, width / 2)])
    g = shapely.union_all([Polygon(corners), Point(length / 2, 0).buffer(width / 2, quad_segs=QUAD_SEGS)])
    g, yaw, c = place(g)
    turn = np.deg2rad(yaw)
    rot = np.array([[math.cos(turn), -math.sin(turn)], [math.sin(turn), math.cos(turn)]])
    moved = corners @ rot.T + c
    msp.add_lwpolyline([(*u([v])[0], 0.0, 0.0, 1.0 if i == 1 else 0.0) for i, v in enumerate(moved)],
                       format="xyseb", close=True, dxfattribs={"layer": "A-RACK"})
    shapes.append(("round", g))
    # a ring wall: two nested closed outlines (even-odd: the band between them is solid)
    outer = _rect(rng.uniform(3.0, 4.0), rng.uniform(2.5, 3.2))
    moved, yaw, c = place(outer)
    inner = affinity.translate(affinity.rotate(outer.buffer(-0.15, join_style="mitre"), yaw, origin=(0, 0)), *c)
    for ring in (moved, inner):
        msp.add_lwpolyline(u(ring.exterior.coords[:-1]), close=True, dxfattribs={"layer": "A-WALL"})
    shapes.append(("ring", moved.difference(inner)))
    for _ in range(3):  # round columns
        r = rng.uniform(0.15, 0.35)
        g, _, c = place(Point(0, 0).buffer(r, quad_segs=QUAD_SEGS))
        msp.add_circle(u([c])[0], r * per_m, dxfattribs={"layer": "S-COLS"})
        shapes.append(("column", g))
    # an INSERT of a block (concave outline + circle on layer 0), rotated and scaled
    blk = doc.blocks.new("UNIT")
    blk.add_lwpolyline(u(BLOCK_T.exterior.coords[:-1]), close=True, dxfattribs={"layer": "0"})
    blk.add_circle(u([BLOCK_CIRCLE[0]])[0], BLOCK_CIRCLE[1] * per_m, dxfattribs={"layer": "0"})
    scale = rng.uniform(0.8, 1.5)
    unit = shapely.union_all([BLOCK_T, Point(BLOCK_CIRCLE[0]).buffer(BLOCK_CIRCLE[1], quad_segs=QUAD_SEGS)])
    g, yaw, c = place(affinity.scale(unit, scale, scale, origin=(0, 0)))
    msp.add_blockref("UNIT", u([c])[0], dxfattribs={"layer": "S-COLS", "rotation": yaw, "xscale": scale,
                                                    "yscale": scale})
    shapes.append(("block", g))

    markers = _face_markers(rng, shapes, w, h)
    refl = doc.blocks.new("REFL")
    refl.add_circle((0, 0), 0.025 * per_m)
    refl.add_attdef("ID", (0, 0), dxfattribs={"height": 0.05 * per_m})
    for i, m in enumerate(markers):
        if i % 3 == 0:  # some as INSERTs of a reflector block with an ID, the rest as POINTs
            msp.add_blockref("REFL", u([m])[0], dxfattribs={"layer": MARKER_LAYER}).add_auto_attribs({"ID": f"X{i}"})
        else:
            msp.add_point(u([m])[0], dxfattribs={"layer": MARKER_LAYER})
    doc.saveas(path)
    return Drawing(shapes=shapes, markers=markers)


def _face_markers(rng, shapes, w, h) -> np.ndarray:
    """Reflectors on faces: the walls' inner faces and the racks' and ring's long faces.

    Each sits on a straight stretch of the union's boundary, at least NEAR_MARKER from every
    vertex of it and from every other obstacle, so near the marker the importer's face is the
    drawn one (no vertex to simplify away, no circle to circumscribe).
    """
    union = shapely.union_all([g for _, g in shapes])
    verts = shapely.points(shapely.get_coordinates(union.boundary))
    cands = []
    half = WALL / 2
    for _ in range(3):
        cands += [(rng.uniform(1, w - 1), half), (w - half, rng.uniform(1, h - 1)), (rng.uniform(1, w - 1), h - half),
                  (half, rng.uniform(1, h - 1))]
    for what, g in shapes:
        if what in ("rack", "ring", "u"):
            ring = g.exterior.coords
            for a, b in zip(ring[:-1], ring[1:], strict=True):
                t = rng.uniform(0.35, 0.65)
                cands.append((a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])))
    out = []
    for p in cands:
        pt = Point(p)
        on = [g for _, g in shapes if g.boundary.distance(pt) < 1e-9]
        others = [g for _, g in shapes if g.boundary.distance(pt) >= 1e-9]
        if (union.boundary.distance(pt) > 1e-9 or union.buffer(-1e-6).contains(pt) or len(on) != 1
                or shapely.distance(verts, pt).min() < NEAR_MARKER
                or min(g.distance(pt) for g in others) < NEAR_MARKER):
            continue
        if all(math.dist(p, q) > 2.0 for q in out):
            out.append(p)
    rng.shuffle(out)
    assert len(out) >= 6, len(out)
    return np.array(out[:10])


def dxf_sure(shapes, markers, x, y, max_range, band) -> Sure:
    """Decide visibility on the raw shapes by shapely, leaving the band undecided.

    Near a marker (within NEAR_MARKER) the grown obstacles would swallow the marker itself;
    there the raw shapes are taken as they are, shrunk by half the planner's 1 µm, which
    holds because the marker's face is straight and drawn exactly there (see _face_markers).
    """
    raw = shapely.union_all(list(shapes))
    grown, shrunk, exact = raw.buffer(band), raw.buffer(-band), raw.buffer(-0.5e-6)
    xx, yy = np.meshgrid(x, y)
    pts = np.column_stack([xx.ravel(), yy.ravel()])
    shapely.prepare(shrunk)
    shapely.prepare(grown)
    free_sure = ~shapely.intersects_xy(grown, pts[:, 0], pts[:, 1])
    nonfree_sure = shapely.intersects_xy(shrunk, pts[:, 0], pts[:, 1])
    vis, blk, obs = [], [], []
    for m in markers:
        segs = shapely.linestrings(np.stack([pts, np.broadcast_to(m, pts.shape)], axis=1))
        disc = Point(m).buffer(NEAR_MARKER)
        near = shapely.union(shapely.difference(grown, disc), shapely.intersection(exact, disc))
        shapely.prepare(near)
        d = np.hypot(*(pts - m).T)
        enters_shrunk = shapely.intersects(shrunk, segs)
        clear_grown = ~shapely.intersects(near, segs)
        in_range, out_range = d <= max_range - RANGE_EPS, d > max_range + RANGE_EPS
        vis.append(free_sure & in_range & clear_grown)
        blk.append(nonfree_sure | out_range | enters_shrunk)
        obs.append(free_sure & in_range & enters_shrunk)
    shape = (len(markers), len(y), len(x))
    return Sure(*(np.array(a).reshape(shape) for a in (vis, blk, obs)))


DRAWINGS = [(11, 1000.0, 4), (12, 1000.0, 4), (13, 1000.0, 4), (14, 1.0, 6)]  # seed, units per m, $INSUNITS


def load_drawing(tmp_path, seed, per_m, insunits):
    rng = np.random.default_rng(seed)
    drawing = random_drawing(rng, tmp_path / "floor.dxf", per_m, insunits)
    (tmp_path / "floor.toml").write_text(
        f'name = "sight-{seed}"\n[floorplan]\nfile = "floor.dxf"\nobstacle_layers = {list(LAYERS)!r}\n'
        f'marker_layer = "{MARKER_LAYER}"\nwall_thickness = {WALL}\nsimplify = {SIMPLIFY}\n'
        f'[sensor]\nmax_range = {MAX_RANGE}\n[planning]\neps_max = 0.05\nresolution = 0.1\n'.replace("'", '"'),
        encoding="utf-8")
    sc = scenarios.load(tmp_path / "floor.toml")
    # the scenario's markers are ours, in its order (POINTs named R1.., INSERTs by their ID)
    got = sc.marker_positions()
    order = [int(np.argmin(np.hypot(*(drawing.markers - p).T))) for p in got]
    assert sorted(order) == list(range(len(drawing.markers)))
    np.testing.assert_allclose(got, drawing.markers[order], atol=1e-9)
    return sc, drawing, drawing.markers[order], rng


@pytest.mark.parametrize(("seed", "per_m", "insunits"), [
    pytest.param(*d, id=i, marks=[pytest.mark.e2e] if i in ("mm-12", "mm-13") else [])  # two more random drawings
    for d, i in zip(DRAWINGS, ["mm-11", "mm-12", "mm-13", "m-14"], strict=True)])
def test_dxf_visibility_and_tau_agree_with_the_raw_drawing(tmp_path, seed, per_m, insunits):
    sc, drawing, markers, rng = load_drawing(tmp_path, seed, per_m, insunits)
    pm, vis = planner_view(sc)
    sure = dxf_sure([g for _, g in drawing.shapes], markers, pm.x, pm.y, MAX_RANGE, DXF_BAND)
    assert_agree(vis, sure, max_undecided=0.05)
    assert_tau_agrees(sc, pm, sure, rng)


def test_dxf_negative_control_a_dropped_rack_disagrees(tmp_path):
    sc, drawing, markers, _ = load_drawing(tmp_path, *DRAWINGS[0])
    pm, vis = planner_view(sc)
    shapes = [g for _, g in drawing.shapes]
    rack = max((i for i, (what, _) in enumerate(drawing.shapes) if what == "rack"), key=lambda i: shapes[i].area)
    sure = dxf_sure(shapes[:rack] + shapes[rack + 1:], markers, pm.x, pm.y, MAX_RANGE, DXF_BAND)
    assert mismatches(vis, sure) > 50


# ----------------------------------------------------------------------------- ROS maps

RES = 0.05                   # map resolution [m/cell]
MAP_ORIGIN = (-3.2, 1.5)     # map origin [m]
FREE, OCCUPIED, UNKNOWN = 254, 0, 205
# A segment that passes more than the band from every obstacle cell misses the traced and
# simplified polygons (within floorplan.simplify of the cells' union, plus the 1 µm shrink);
# one that touches a cell at least that deep inside the obstacle cells enters them. Growing /
# shrinking the obstacle cells by k whole cells (Chebyshev) covers every point within k cells
# (Euclidean), so k = ceil((simplify + 1e-6) / RES) cells decides all the rest: 2 cells (0.1 m)
# at the reader's default simplify = RES, 1 cell at simplify = 0.02. (The "half a cell" of a
# point-sampled grid does not arise: the walk tests every cell a segment touches.)


def band_cells(simplify: float) -> int:
    """Return k, the band in whole map cells for a simplification tolerance [m]."""
    return math.ceil((simplify + 1e-6) / RES)


K = band_cells(RES)  # markers keep clear of the widest band used


def _desaddle(obst: np.ndarray) -> np.ndarray:
    """Fill one free cell of every diagonal-only touch, as the reader does, so the raw map has none.

    (The reader's own saddle rule is tested in test_floorplan_rosmap; here the raw grid is what
    both sides read.)
    """
    obst = obst.copy()
    while True:
        a, b, c, d = obst[:-1, :-1], obst[:-1, 1:], obst[1:, :-1], obst[1:, 1:]
        s = (a & d & ~b & ~c) | (b & c & ~a & ~d)
        if not s.any():
            return obst
        r, k = np.nonzero(s)
        obst[r, k] = True
        obst[r, k + 1] = True


def random_map(rng: np.random.Generator, h: int = 150, w: int = 210) -> np.ndarray:
    """Make a random map image (H, W) uint8, row 0 at the top: walls, rectangles, blobs, unknown."""
    img = np.full((h, w), FREE, dtype=np.uint8)
    img[:, :8] = UNKNOWN                     # unmapped space west of the west wall
    img[:3, :] = img[-3:, :] = OCCUPIED
    img[:, 8:11] = img[:, -3:] = OCCUPIED
    rr, cc = np.mgrid[0:h, 0:w]
    for _ in range(7):
        r0, c0 = rng.integers(10, h - 30), rng.integers(15, w - 30)
        img[r0:r0 + rng.integers(3, 25), c0:c0 + rng.integers(3, 25)] = OCCUPIED
    for _ in range(4):
        r0, c0, rad = rng.integers(15, h - 15), rng.integers(20, w - 15), rng.uniform(2.5, 8.0)
        img[(rr - r0) ** 2 + (cc - c0) ** 2 <= rad ** 2] = OCCUPIED
    for _ in range(3):
        r0, c0 = rng.integers(10, h - 20), rng.integers(15, w - 20)
        img[r0:r0 + rng.integers(3, 12), c0:c0 + rng.integers(3, 12)] = UNKNOWN
    obst = _desaddle(img != FREE)
    img[obst & (img == FREE)] = OCCUPIED
    return img


def map_markers(rng, obst: np.ndarray, n: int = 8) -> np.ndarray:
    """Reflector positions [m]: centres of free cells K + 2 cells from the nearest obstacle cell.

    Close to a wall as reflectors are, but outside the band (K cells), so the marker's own
    segment ends are decided.
    """
    near = ndimage.binary_dilation(obst, np.ones((2 * K + 5, 2 * K + 5), bool))
    clear = ~ndimage.binary_dilation(obst, np.ones((2 * K + 3, 2 * K + 3), bool))
    rows, cols = np.nonzero(near & clear)
    out: list[tuple[float, float]] = []
    for i in rng.permutation(len(rows)):
        p = (MAP_ORIGIN[0] + (cols[i] + 0.5) * RES, MAP_ORIGIN[1] + (rows[i] + 0.5) * RES)
        if all(math.dist(p, q) > 1.5 for q in out):
            out.append(p)
        if len(out) == n:
            break
    return np.array(out)


@numba.njit(cache=False)  # no on-disk cache: a test writes nothing outside tmp_path
def _touches(ax, ay, bx, by, grid):
    """Tell whether segment a-b (cell units) touches a True cell; cell (r, c) is [c, c+1] x [r, r+1], closed."""
    h, w = grid.shape
    if ax > bx:
        ax, ay, bx, by = bx, by, ax, ay
    for c in range(max(math.ceil(ax) - 1, 0), min(math.floor(bx), w - 1) + 1):
        xl, xr = max(ax, c), min(bx, c + 1.0)
        if xl > xr:
            continue
        if bx == ax:
            y1, y2 = ay, by
        else:
            t = (by - ay) / (bx - ax)
            y1, y2 = ay + t * (xl - ax), ay + t * (xr - ax)
        yl, yr = min(y1, y2), max(y1, y2)
        for r in range(max(math.ceil(yl) - 1, 0), min(math.floor(yr), h - 1) + 1):
            if grid[r, c]:
                return True
    return False


@numba.njit(cache=False)
def _walk_all(px, py, mx, my, grid, out):
    for n in range(px.size):
        out[n] = _touches(px[n], py[n], mx, my, grid)


def walk(pts_cells: np.ndarray, m_cells, grid: np.ndarray) -> np.ndarray:
    """Tell for every point (cell units, (N, 2)) whether its segment to ``m_cells`` touches a True cell."""
    out = np.empty(len(pts_cells), dtype=np.bool_)
    _walk_all(np.ascontiguousarray(pts_cells[:, 0]), np.ascontiguousarray(pts_cells[:, 1]), float(m_cells[0]),
              float(m_cells[1]), grid, out)
    return out


@numba.njit(cache=False)
def _touch_points(px, py, grid, out):
    for n in range(px.size):
        out[n] = _touches(px[n], py[n], px[n], py[n], grid)


def touch_points(pts_cells: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Tell for every point (cell units, (N, 2)) whether it lies in (or on) a True cell."""
    out = np.empty(len(pts_cells), dtype=np.bool_)
    _touch_points(np.ascontiguousarray(pts_cells[:, 0]), np.ascontiguousarray(pts_cells[:, 1]), grid, out)
    return out


def grid_sure(obst: np.ndarray, origin, markers, x, y, max_range, k: int) -> Sure:
    """Decide visibility by walking the raw grid (row 0 at the bottom), band = ``k`` cells."""
    grown = ndimage.binary_dilation(obst, np.ones((2 * k + 1, 2 * k + 1), bool))
    shrunk = ndimage.binary_erosion(obst, np.ones((2 * k + 1, 2 * k + 1), bool), border_value=0)
    xx, yy = np.meshgrid(x, y)
    pts = np.column_stack([xx.ravel(), yy.ravel()])
    cells = (pts - origin) / RES
    free_sure = ~touch_points(cells, grown)
    nonfree_sure = touch_points(cells, shrunk)
    vis, blk, obs = [], [], []
    for m in markers:
        mc = (m - origin) / RES
        d = np.hypot(*(pts - m).T)
        enters = walk(cells, mc, shrunk)
        clear = ~walk(cells, mc, grown)
        in_range, out_range = d <= max_range - RANGE_EPS, d > max_range + RANGE_EPS
        vis.append(free_sure & in_range & clear)
        blk.append(nonfree_sure | out_range | enters)
        obs.append(free_sure & in_range & enters)
    shape = (len(markers), len(y), len(x))
    return Sure(*(np.array(a).reshape(shape) for a in (vis, blk, obs)))


UNDECIDED = {1: 0.15, 2: 0.30}  # allowed undecided fraction by band [cells]: shadow edges x 2k cells
MAP_RANGE = 7.0  # sensor.max_range [m] for the 10.5 x 7.5 m maps


def load_map(tmp_path, seed, suffix, simplify):
    from PIL import Image

    rng = np.random.default_rng(seed)
    img = random_map(rng)
    Image.fromarray(img).save(tmp_path / f"floor{suffix}")
    if suffix == ".pgm":
        assert (tmp_path / "floor.pgm").read_bytes()[:2] == b"P5"
    (tmp_path / "floor.yaml").write_text(
        f"image: floor{suffix}\nresolution: {RES}\norigin: [{MAP_ORIGIN[0]}, {MAP_ORIGIN[1]}, 0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n", encoding="utf-8")
    obst = (img != FREE)[::-1]  # row 0 = the bottom of the map; unknown (205) is an obstacle too
    markers = map_markers(rng, obst)
    mk = "".join(f'[[markers]]\nid = "M{i}"\nposition = [{float(x)!r}, {float(y)!r}]\n'
                 for i, (x, y) in enumerate(markers))
    tol = "" if simplify is None else f"simplify = {simplify}\n"
    (tmp_path / "floor.toml").write_text(
        f'name = "map-{seed}"\n[floorplan]\nfile = "floor.yaml"\n{tol}{mk}'
        f'[sensor]\nmax_range = {MAP_RANGE}\n[planning]\neps_max = 0.05\nresolution = 0.1\n', encoding="utf-8")
    sc = scenarios.load(tmp_path / "floor.toml")
    np.testing.assert_array_equal(sc.marker_positions(), markers)
    assert sc.workspace.bounds == pytest.approx((MAP_ORIGIN[0], MAP_ORIGIN[1], MAP_ORIGIN[0] + img.shape[1] * RES,
                                                 MAP_ORIGIN[1] + img.shape[0] * RES))
    return sc, obst, markers, rng


MAPS = [(21, ".pgm", None), (22, ".png", None), (23, ".pgm", 0.02)]  # seed, image, floorplan.simplify


@pytest.mark.parametrize(("seed", "suffix", "simplify"), MAPS, ids=["pgm-21", "png-22", "pgm-23-fine"])
def test_rosmap_visibility_and_tau_agree_with_the_raw_grid(tmp_path, seed, suffix, simplify):
    sc, obst, markers, rng = load_map(tmp_path, seed, suffix, simplify)
    pm, vis = planner_view(sc)
    k = band_cells(RES if simplify is None else simplify)
    assert sc.floorplan.simplify == (RES if simplify is None else simplify)
    sure = grid_sure(obst, np.array(MAP_ORIGIN), markers, pm.x, pm.y, MAP_RANGE, k)
    assert_agree(vis, sure, max_undecided=UNDECIDED[k])
    assert_tau_agrees(sc, pm, sure, rng)


def test_rosmap_negative_control_a_shifted_grid_disagrees(tmp_path):
    sc, obst, markers, _ = load_map(tmp_path, *MAPS[0])
    k = band_cells(RES)
    pm, vis = planner_view(sc)
    # shifted by one cell more than the band: every obstacle edge moves out of the undecided zone
    shifted = np.zeros_like(obst)
    shifted[:, K + 1:] = obst[:, :-(K + 1)]
    sure = grid_sure(shifted, np.array(MAP_ORIGIN), markers, pm.x, pm.y, MAP_RANGE, k)
    assert mismatches(vis, sure) > 50
    # and the same grid unshifted agrees: the disagreement is the shift's
    assert mismatches(vis, grid_sure(obst, np.array(MAP_ORIGIN), markers, pm.x, pm.y, MAP_RANGE, k)) == 0
