"""Flat reflectors and redundancy against an independent, slow evaluator of the same definitions.

The evaluator below is plain Python with shapely: line of sight by intersecting the segment with
the obstacle polygon shrunk a little, and with it grown by the sight rule's margin unless the
marker is mounted on it (:mod:`planner.pef.sight`), the incidence and mount wedges by their
definition, the parallelogram diagonal
by the paper's eq. 12, and tau_1 by brute force over *every* visible marker removed (not only the
best subset's members, which is the shortcut the kernels take). Cells whose answer depends on a
rounding (a segment grazing a corner, an angle within 1e-9 rad of the limit) are left out of the
comparison, and the test checks they are few.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from shapely.geometry import LineString, MultiPoint, Point, Polygon, box

import scenarios
from planner.pef.map import PEF
from planner.pef.sight import sight_rule
from planner.pef.visibility import scenario_visible_grid, scenario_visible_points
from tests.scenarios.worlds import FLAT_TOML, flat_scenario

OBSTACLE = box(4.5, 3.5, 7.5, 4.5)
RES = 0.25
RULE = sight_rule(flat_scenario().sensor)   # the scenario's map rule
# every face with its outward normal (the obstacle's) or inward one (the workspace's sides)
FACES = [(LineString([(4.5, 3.5), (7.5, 3.5)]), (0.0, -1.0)), (LineString([(7.5, 3.5), (7.5, 4.5)]), (1.0, 0.0)),
         (LineString([(7.5, 4.5), (4.5, 4.5)]), (0.0, 1.0)), (LineString([(4.5, 4.5), (4.5, 3.5)]), (-1.0, 0.0)),
         (LineString([(0.0, 0.0), (12.0, 0.0)]), (0.0, 1.0)), (LineString([(12.0, 0.0), (12.0, 8.0)]), (-1.0, 0.0)),
         (LineString([(12.0, 8.0), (0.0, 8.0)]), (0.0, -1.0)), (LineString([(0.0, 8.0), (0.0, 0.0)]), (1.0, 0.0))]


def _body(at) -> Polygon:
    """Return a marker's body as the kernels see it: the octagon circumscribing its radius."""
    ang = math.pi / 8.0 + np.arange(8) * math.pi / 4.0
    r = RULE.radius / math.cos(math.pi / 8.0)
    return Polygon(np.asarray(at) + r * np.column_stack([np.cos(ang), np.sin(ang)]))


def _blocker(body: Polygon, at):
    """Return what ``body`` needs to decide, for any p, whether it blocks the sight of a marker at ``at``.

    The shapes depend on the body and the marker only, so they are built once per pair (buffers
    are what costs) and :func:`_blocks` tests a point against them.
    """
    if body.buffer(RULE.grow, join_style=2).intersects(Point(at)):
        # the marker's mount: the segment must not enter it
        return "mount", body.buffer(-1e-7, join_style=2), body.buffer(-1e-4, join_style=2)
    # some position within the margin sees the marker through the body grown by the reach: the
    # fan from the marker over the disc of the margin meets it (the kernels widen the shadow's
    # half-planes, a mitred superset: cells where the two differ, near the shadow's corners, are
    # unsure)
    grown = body.buffer(RULE.reach, join_style=2)
    mk = np.asarray(at)
    far = [mk + (np.asarray(v) - mk) * 100.0 for v in grown.exterior.coords]
    shadow = MultiPoint(list(grown.exterior.coords) + far).convex_hull
    return "shadow", grown, shadow.buffer(RULE.margin, join_style=2, mitre_limit=1e6)


def _blocks(blocker, p, at, fan) -> tuple[bool, bool]:
    """Whether a body blocks the line of sight from p to a marker at ``at``, and whether that is unsure.

    ``blocker`` is the body's :func:`_blocker`; ``fan`` the convex hull of the disc of the margin
    around p and the marker.
    """
    kind, a, b = blocker
    if kind == "mount":
        seg = LineString([p, at])
        tight = seg.intersects(a)
        loose = seg.intersects(b)
        return tight, tight != loose
    tight = fan.intersects(a)
    loose = b.contains(Point(p))
    return tight, tight != loose


_GEOMETRY: dict = {}


def _geometry(sc) -> list[tuple]:
    """Per marker: whether it is mounted on the obstacle, its blockers, and the faces whose wedge applies.

    Memoised on the markers' positions (every scenario of this module has the same markers).
    """
    key = tuple(tuple(m.position) for m in sc.markers)
    if key not in _GEOMETRY:
        out = []
        for m in sc.markers:
            mounted = OBSTACLE.buffer(RULE.grow, join_style=2).intersects(Point(m.position))
            # the obstacle, and the other markers' bodies (octagons around them)
            blockers = [_blocker(body, m.position)
                        for body in [OBSTACLE] + [_body(o.position) for o in sc.markers if o is not m]]
            faces = [normal for line, normal in FACES
                     if line.distance(Point(m.position)) <= RULE.radius
                     and (mounted or not line.within(OBSTACLE.boundary))]
            out.append((blockers, faces))
        _GEOMETRY[key] = out
    return _GEOMETRY[key]


def _visibility(sc, p, flat: bool = True):
    """Slow visibility of every marker from point p: (bool (M,), ambiguous (bool))."""
    out, ambiguous = [], False
    if OBSTACLE.intersects(Point(p)):
        return [False] * len(sc.markers), False
    lim = math.degrees(sc.sensor.max_incidence)
    disc = Point(p).buffer(RULE.margin)
    for m, (blockers, faces) in zip(sc.markers, _geometry(sc), strict=True):
        mx, my = m.position
        dx, dy = p[0] - mx, p[1] - my
        if math.hypot(dx, dy) > sc.sensor.max_range - RULE.margin:
            out.append(False)
            continue
        ok = True
        fan = disc.union(Point(m.position)).convex_hull
        for blocker in blockers:
            blocked, unsure = _blocks(blocker, p, m.position, fan)
            ok &= not blocked
            ambiguous |= unsure
        for nx, ny in faces:
            # the mount wedge: p at least offset + slope r in front of the face
            slack = dx * nx + dy * ny - RULE.offset - RULE.slope * math.hypot(dx, dy)
            ambiguous |= abs(slack) < 1e-9
            ok = ok and slack >= 0.0
        if ok and flat and m.kind is scenarios.MarkerKind.FLAT:
            # the incidence wedge, at every point within the margin
            cos_lim = math.cos(math.radians(lim))
            slack = (dx * math.cos(m.facing) + dy * math.sin(m.facing) - RULE.margin * (1.0 + cos_lim)
                     - cos_lim * math.hypot(dx, dy))
            ambiguous |= abs(slack) < 1e-9
            ok = ok and slack >= 0.0
        out.append(ok)
    return out, ambiguous


def _diagonal(sc, p, a, b) -> float:
    """Paper eq. 12: long diagonal of the parallelogram of markers a, b seen from p [m]."""
    u = [np.subtract(p, sc.markers[i].position) for i in (a, b)]
    r = [float(np.hypot(*v)) for v in u]
    if min(r) == 0.0:
        return math.inf
    rho = [sc.sensor.relative_error * ri + sc.sensor.absolute_error for ri in r]
    cos_a = float(np.dot(u[0], u[1])) / (r[0] * r[1])
    sin_a = math.sqrt(max(0.0, 1.0 - cos_a * cos_a))
    if sin_a == 0.0:
        return math.inf
    return 2.0 / sin_a * math.sqrt(rho[0] ** 2 + rho[1] ** 2 + 2 * rho[0] * rho[1] * abs(cos_a))


def _best(sc, p, seen) -> float:
    pairs = [_diagonal(sc, p, a, b) for a, b in itertools.combinations(seen, 2)]
    return min(pairs, default=math.inf)


def _slow_map(sc, redundancy: int, flat: bool = True):
    """Tau (or tau_1 by brute force) on the cell centres; and the ambiguous cells."""
    nx, ny = round(12.0 / RES), round(8.0 / RES)
    xs, ys = (np.arange(nx) + 0.5) * RES, (np.arange(ny) + 0.5) * RES
    tau = np.full((ny, nx), np.inf)
    amb = np.zeros((ny, nx), bool)
    for iy, y in enumerate(ys):
        for ix, x in enumerate(xs):
            vis, amb[iy, ix] = _visibility(sc, (x, y), flat)
            seen = [i for i, v in enumerate(vis) if v]
            t = _best(sc, (x, y), seen)
            if redundancy == 1:
                t = max([t] + [_best(sc, (x, y), [i for i in seen if i != j]) for j in seen])
            tau[iy, ix] = t
    return tau, amb


def _agree(fast, slow, amb) -> np.ndarray:
    """Cells where fast and slow differ (both inf, or within 1e-5 relative), ambiguous ones aside."""
    both_inf = np.isinf(fast) & np.isinf(slow)
    close = np.isclose(fast, slow, rtol=1e-5, atol=0.0)
    return ~(both_inf | close) & ~amb


@pytest.fixture(scope="module")
def slow():
    sc = flat_scenario()
    return {r: _slow_map(sc, r) for r in (0, 1)} | {"posts": _slow_map(sc, 0, flat=False)}


def test_flat_markers_parse_with_their_normals():
    sc = flat_scenario()
    assert [m.kind.value for m in sc.markers] == ["post", "post", "flat", "flat", "flat", "flat", "post"]
    n = sc.marker_normals()
    assert n[0] == pytest.approx([0.0, 0.0])
    assert n[2] == pytest.approx([0.0, -1.0])
    assert n[4] == pytest.approx([-1.0, 0.0])
    assert sc.sensor.max_incidence == pytest.approx(math.radians(50.0))


@pytest.mark.parametrize("bad, match", [
    ('facing_deg = -90.0\n[[markers]]\nid = "X"\nposition = [1.0, 1.0]\nkind = "flat"\n',
     r"markers\[6\]\.facing_deg: expected the normal's direction"),
    ('facing_deg = -90.0\nkind2 = 1\n', r"kind2"),
])
def test_flat_marker_without_facing_or_unknown_key_is_one_line_error(bad, match):
    text = FLAT_TOML.replace('facing_deg = -90.0\n[[markers]]\nid = "P3"', bad + '[[markers]]\nid = "P3"', 1)
    with pytest.raises(scenarios.ScenarioError, match=match):
        flat_scenario(text=text)


def test_bad_incidence_and_redundancy_values_name_key_and_value():
    with pytest.raises(scenarios.ScenarioError, match=r"sensor\.max_incidence_deg.*95"):
        flat_scenario(text=FLAT_TOML.replace("max_incidence_deg = 50.0", "max_incidence_deg = 95.0"))
    with pytest.raises(scenarios.ScenarioError, match=r"planning\.redundancy.*-1"):
        flat_scenario(-1)
    with pytest.raises(scenarios.ScenarioError, match=r"sensor\.block_probability.*1\.5"):
        flat_scenario(text=FLAT_TOML.replace("[planning]", "block_probability = 1.5\n[planning]"))


def test_grid_and_points_visibility_agree_with_flat_markers():
    sc = flat_scenario()
    pm = PEF(sc).grid(RES)
    vis_g, _ = scenario_visible_grid(sc, pm.x, pm.y)
    pts = np.column_stack([np.tile(pm.x, pm.y.size), np.repeat(pm.y, pm.x.size)])
    vis_p, _ = scenario_visible_points(sc, pts)
    assert np.array_equal(vis_g.reshape(len(sc.markers), -1), vis_p)
    # the flat marker on the obstacle's lower face is not seen from above the obstacle
    assert not vis_g[2][pm.y > 4.5].any()
    assert vis_g[2][pm.y < 3.0].any()


def test_flat_pef_map_agrees_with_slow_evaluator_cell_by_cell(slow):
    tau, amb = slow[0]
    pm = PEF(flat_scenario()).grid(RES)
    assert amb.mean() < 0.02
    bad = _agree(pm.tau, tau, amb)
    assert not bad.any(), f"{bad.sum()} cells differ, first at {np.argwhere(bad)[:3].tolist()}"
    # negative control: ignoring the incidence limit changes the map where the check looks
    posts, amb_p = slow["posts"]
    assert _agree(pm.tau, posts, amb | amb_p).sum() > 20


def test_redundancy_1_map_agrees_with_brute_force_over_every_marker_removed(slow):
    tau1, amb = slow[1]
    pm = PEF(flat_scenario(1)).grid(RES)
    assert pm.redundancy == 1
    bad = _agree(pm.tau, tau1, amb)
    assert not bad.any(), f"{bad.sum()} cells differ, first at {np.argwhere(bad)[:3].tolist()}"
    # the points path gives the same tau_1
    pts = np.column_stack([np.tile(pm.x, pm.y.size), np.repeat(pm.y, pm.x.size)])
    assert np.array_equal(PEF(flat_scenario(1)).at(pts).tau.reshape(pm.tau.shape), pm.tau)
    # negative control: the plain map is not tau_1 (the check would catch a no-op redundancy)
    tau0, _ = slow[0]
    assert _agree(PEF(flat_scenario(0)).grid(RES).tau, tau1, amb).sum() > 20
    assert np.array_equal(pm.tau_plain, PEF(flat_scenario(0)).grid(RES).tau)


def test_fallback_subset_avoids_its_blocked_marker_and_gives_the_tau_without_it():
    sc = flat_scenario(1)
    pef = PEF(sc)
    pts = np.array([[2.0, 2.0], [9.0, 6.5], [6.0, 1.0], [1.0, 6.0]])
    r = pef.at(pts)
    plain = PEF(sc, redundancy=0)
    for n, p in enumerate(pts):
        vis, _ = _visibility(sc, p)
        for j in range(2):
            blocked = r.best[n, j]
            fb = r.fallback[n, j]
            if fb[0] < 0:
                continue
            assert blocked not in fb
            seen = [i for i, v in enumerate(vis) if v and i != blocked]
            assert plain.tau_subset(p, fb)[0] == pytest.approx(_best(sc, p, seen), rel=1e-5)


def test_redundancy_2_is_the_worst_over_every_pair_removed():
    sc = flat_scenario(2)
    pts = np.array([[2.0, 2.0], [9.0, 6.5], [6.0, 1.0], [3.0, 6.0], [10.0, 1.0]])
    got = PEF(sc).at(pts).tau
    for n, p in enumerate(pts):
        vis, _ = _visibility(sc, p)
        seen = [i for i, v in enumerate(vis) if v]
        want = max([_best(sc, p, seen)] + [_best(sc, p, [i for i in seen if i not in d])
                                           for d in itertools.combinations(seen, 2)])
        assert got[n] == pytest.approx(want, rel=1e-5) or (math.isinf(got[n]) and math.isinf(want))


def test_tau_subset_of_every_pair_agrees_with_the_slow_evaluator_incidence_included():
    # the schedule scores its candidate subsets with tau_subset: a flat marker outside its
    # incidence wedge must give inf there too, or the plan schedules markers the laser cannot see
    sc = flat_scenario()
    pef = PEF(sc)
    xs, ys = np.meshgrid(np.arange(0.3, 12.0, 0.7), np.arange(0.3, 8.0, 0.7))
    pts = np.column_stack([xs.ravel(), ys.ravel()])
    looks = [_visibility(sc, p) for p in pts]
    looks_posts = [_visibility(sc, p, flat=False)[0] for p in pts]
    wedge_only = 0
    for a, b in itertools.combinations(range(len(sc.markers)), 2):
        got = pef.tau_subset(pts, np.array([a, b]))
        for n, p in enumerate(pts):
            vis, amb = looks[n]
            if amb:
                continue
            want = _diagonal(sc, p, a, b) if vis[a] and vis[b] else math.inf
            # (collinear pairs are 1e13 one way and inf the other: both past any eps_max)
            assert min(got[n], 1e6) == pytest.approx(min(want, 1e6), rel=1e-5), (a, b, p)
            posts = looks_posts[n]
            wedge_only += bool(posts[a] and posts[b] and not (vis[a] and vis[b]))
    # the incidence limit decides many of these: the check would catch a tau_subset that ignores it
    assert wedge_only > 50


def test_tau_subset_sees_flat_markers_only_within_their_incidence_limit():
    sc = flat_scenario()
    pef = PEF(sc)
    pm = pef.grid(RES)
    pts = np.column_stack([np.tile(pm.x, pm.y.size), np.repeat(pm.y, pm.x.size)])
    vis = np.asarray(pef.visible(pts), dtype=bool)                 # (N, M), incidence included
    pairs = np.array(list(itertools.combinations(range(len(sc.markers)), 2)))
    tau = pef.tau_subset(pts, pairs)                               # (C, N)
    both = vis[:, pairs[:, 0]].T & vis[:, pairs[:, 1]].T
    assert not np.isfinite(tau[~both]).any()                       # a hidden marker gives no fix
    # where the plain map picks a pair, that pair's tau is the map's
    best, flat_tau = pm.best.reshape(-1, 2), pm.tau.ravel()
    row = {tuple(p): i for i, p in enumerate(pairs.tolist())}
    got = np.array([tau[row[tuple(b)], n] if b[0] >= 0 else np.inf for n, b in enumerate(best.tolist())])
    assert np.array_equal(got, flat_tau)
