"""Which markers can be measured from which points: range limit and line of sight.

A marker is visible from a point when the point is in free space (inside the closed
workspace rectangle and not inside any obstacle, boundary included), the range is at most
``max_range``, the segment point-marker does not cross the *interior* of any obstacle and,
for a flat marker with unit normal ``n``, the point lies in its incidence wedge: the angle
between ``p - M`` and ``n`` is at most ``max_incidence`` (:func:`facing_ok`; a post has
``n = 0`` and no wedge). Both paths apply the wedge with the same per-cell predicate, so
they agree on its boundary too.

Obstacles of every shape arrive as convex pieces (:meth:`scenarios.Scenario.obstacle_pieces`,
kernels in :mod:`planner.pef.convex`). Markers sit on the walls or on obstacle faces. To let a
marker on a face be seen from the open side but not through its own obstacle, line of sight
is tested against every piece *shrunk* by :data:`BOX_SHRINK` (1 micrometre) on each face: a
segment that ends on a face (or grazes an edge) does not enter the shrunk piece, one that
passes through it does. Where two pieces of one obstacle meet, their cut is moved *out* by as
much, so the pieces overlap and even a segment running along the cut is blocked: the split is
invisible. Free space uses the pieces at full size.

That is the margin-free geometry (``rule=None``). What a plan counts on is stricter, the rule of
:mod:`planner.pef.sight` (``rule=SightRule``, what :func:`scenario_visible_points` and
:func:`scenario_visible_grid` apply): every piece but a marker's mount grown by the physics ray's
reach and its shadow widened by the robot's margin (:func:`shadow_table`, the same half-planes
for points and grid rows), the reflectors' bodies as pieces of the others' lines of sight, a
wedge in front of each mount face, and the range and incidence limits held within the margin.

Two paths give the same answer (a test checks it):

- :func:`visible_points`: arbitrary points, a Cyrus-Beck segment/piece clip for every point,
  marker and piece; O(N M P V).
- :func:`visible_grid`: cell centres of a regular grid. The *shadow* of a convex piece seen
  from a marker (the points whose segment to the marker enters it) is convex: the cone from
  the marker over the piece's silhouette, beyond the edges turned to the marker. It is an
  intersection of half-planes, so each grid row meets it in one interval, which is cleared in
  one sweep; cost O(M P V ny) plus the cells cleared.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

import numpy as np

from jit import compiled
from planner.pef.convex import PieceArrays, inside_closed, piece_arrays, segment_enters, shadow_halfplanes
from planner.pef.sight import SightRule, sight_rule
from planner.pef.threads import run_ranges
from scenarios.obstacles import ConvexPieces, pack_pieces
from scenarios.schema import Scenario

#: Obstacle pieces are shrunk by this much on each side for line-of-sight tests [m].
BOX_SHRINK = 1e-6

_PREPARED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def prepare(obstacles) -> PieceArrays:
    """Return the kernels' form of a set of obstacles, cached per :class:`~scenarios.ConvexPieces` object.

    Parameters
    ----------
    obstacles : scenarios.ConvexPieces, PieceArrays, or ndarray of shape (B, 4, 2)
        Convex pieces (``Scenario.obstacle_pieces()``), already prepared pieces, or box
        corners counter-clockwise [m] (``Scenario.obstacle_corners()``).

    Returns
    -------
    PieceArrays
        Edge half-planes, shrunk by :data:`BOX_SHRINK` for line of sight.
    """
    if isinstance(obstacles, PieceArrays):
        return obstacles
    if not isinstance(obstacles, ConvexPieces):
        corners = np.asarray(obstacles, float).reshape(-1, 4, 2)
        obstacles = pack_pieces([_Corners(c) for c in corners])
    got = _PREPARED.get(obstacles)
    if got is None:
        got = _PREPARED[obstacles] = piece_arrays(obstacles, BOX_SHRINK)
    return got


class _Corners:
    """Box corners standing in for an obstacle in :func:`pack_pieces`."""

    kind = "box"

    def __init__(self, corners: np.ndarray) -> None:
        self._c = corners

    def pieces(self) -> tuple[np.ndarray, ...]:
        return (self._c,)


@compiled.njit(cache=True)
def _is_free(px, py, x0, y0, x1, y1, planes, count, bbox):
    if px < x0 or px > x1 or py < y0 or py > y1:
        return False
    for p in range(count.size):
        if bbox[p, 0] <= px <= bbox[p, 2] and bbox[p, 1] <= py <= bbox[p, 3]:
            if inside_closed(px, py, planes, count, p):
                return False
    return True


@compiled.njit(cache=True)
def facing_ok(dx, dy, nx, ny, cos_inc, offset):
    """Tell whether offset (dx, dy) = p - M [m] lies in the wedge of normal (nx, ny).

    The wedge is ``d.n >= offset + |d| cos_inc``: with ``offset = 0`` a flat marker's incidence
    wedge ``angle(d, n) <= max_incidence`` (``cos_inc = cos(max_incidence)``), with an offset
    the mount wedge of :mod:`planner.pef.sight`. Squared (no square root) it is ``d.n - offset
    >= 0`` and ``(d.n - offset)^2 >= |d|^2 cos_inc^2``, exact for ``cos_inc >= 0``.
    ``n = (0, 0)`` (a free-standing post) passes everywhere.
    """
    if nx == 0.0 and ny == 0.0:
        return True
    dot = dx * nx + dy * ny - offset
    return dot >= 0.0 and dot * dot >= (dx * dx + dy * dy) * (cos_inc * cos_inc)


@compiled.njit(cache=True)
def wedges_ok(dx, dy, wedge, m):
    """Tell whether offset (dx, dy) = p - M [m] lies in every wedge of marker m.

    ``wedge`` (M, W, 4): rows ``(nx, ny, cos_inc, offset)`` for :func:`facing_ok`; a row with
    ``n = (0, 0)`` is unused.
    """
    for w in range(wedge.shape[1]):
        if not facing_ok(dx, dy, wedge[m, w, 0], wedge[m, w, 1], wedge[m, w, 2], wedge[m, w, 3]):
            return False
    return True


@compiled.njit(cache=True)
def _blocked(ax, ay, bx, by, planes, sight, count, sight_bbox, blocks):
    """Tell whether segment a-b enters the open line-of-sight piece of any blocking piece."""
    lox, hix = min(ax, bx), max(ax, bx)
    loy, hiy = min(ay, by), max(ay, by)
    for p in range(count.size):
        if (not blocks[p] or sight_bbox[p, 0] >= hix or sight_bbox[p, 2] <= lox or sight_bbox[p, 1] >= hiy
                or sight_bbox[p, 3] <= loy):
            continue
        if segment_enters(ax, ay, bx, by, planes, sight, count, p):
            return True
    return False


@compiled.njit(cache=True)
def in_shadow(px, py, hp, n):
    """Tell whether point (px, py) meets all ``n`` half-planes ``a x + b y + c < 0`` of ``hp`` (False if n <= 0)."""
    if n <= 0:
        return False
    for h in range(n):
        if not hp[h, 0] * px + hp[h, 1] * py + hp[h, 2] < 0.0:
            return False
    return True


@compiled.njit(cache=True)
def _on_mount(mx, my, planes, swallow, count, p):
    """Tell whether (mx, my) lies in piece ``p`` grown to the offsets ``swallow`` (its mount, :mod:`.sight`)."""
    for k in range(count[p]):
        c = planes[p, k, 2]
        if not planes[p, k, 0] * mx + planes[p, k, 1] * my - c <= swallow[p, k] - c:
            return False
    return True


@compiled.njit(cache=True)
def marker_pieces(m, mx, my, planes, count, sight, shrunk, sight_bbox, blocks, swallow, bodies, n_ob, margin,
                  max_range, split, hp, nhp, clip):
    """Marker m's blocking pieces within reach: their shadows and, with ``split``, the pieces to clip.

    The arrays are :class:`SightArrays`' (``sight`` (2, P, V) etc.: index 0 the pieces as a
    mount sees them, 1 grown by the physics ray's reach). A piece is marker m's mount when m
    lies in it grown to ``swallow``; its own body (a body piece ``p >= n_ob`` at m's position)
    does not block. A piece's shadow is widened by ``margin`` [m] except on the mount (every
    half-plane moved out by it, mitred: a superset of the points within ``margin`` of the
    shadow). A piece whose bounding box is farther than ``max_range`` plus its widening from m
    is left out: a point within ``max_range`` of m never looks at m through it.

    With ``split`` (the points path) the pieces not widened go to ``clip`` (rows ``(p, 0 or 1)``,
    tested by clipping the segment) instead of getting a shadow. Scratch: ``hp`` (>= P, V + 2,
    3), ``nhp`` (>= P,), ``clip`` (>= P, 2).

    Returns
    -------
    (int, int, bool)
        Shadows written (``hp[:n]``, ``nhp[:n]``), clip rows written, and whether m lies in one
        of its pieces (it is hidden everywhere).
    """
    x, y = mx[m], my[m]
    ns, nc = 0, 0
    hidden = False
    for p in range(count.size):
        mount = _on_mount(x, y, planes, swallow, count, p)
        g = 0 if mount else 1
        if not blocks[g, p]:
            continue
        if p >= n_ob and bodies[p - n_ob, 0] == x and bodies[p - n_ob, 1] == y:
            continue  # its own body: what the ray must meet
        w = 0.0 if mount else margin
        dx = max(sight_bbox[g, p, 0] - x, x - sight_bbox[g, p, 2], 0.0)
        dy = max(sight_bbox[g, p, 1] - y, y - sight_bbox[g, p, 3], 0.0)
        reach = max_range + w
        if not dx * dx + dy * dy <= reach * reach * 1.0000001:
            continue  # its shadow, beyond it, is out of range (and m is not inside it)
        if split and not w > 0.0:
            clip[nc, 0], clip[nc, 1] = p, g
            nc += 1
            continue
        n = shadow_halfplanes(x, y, planes, sight[g], shrunk[g], count, p, hp[ns])
        if n < 0:
            hidden = True
            continue
        if w > 0.0:
            for h in range(n):
                hp[ns, h, 2] -= w * math.sqrt(hp[ns, h, 0] ** 2 + hp[ns, h, 1] ** 2)
        nhp[ns] = n
        ns += 1
    return ns, nc, hidden


@compiled.njit(cache=True)
def shadow_table(mx, my, planes, count, sight, shrunk, sight_bbox, blocks, swallow, bodies, n_ob, margin, max_range):
    """Shadow half-planes of each marker's pieces within reach, their counts, and the markers hidden everywhere.

    The arguments are :class:`SightArrays`' and :func:`marker_pieces`'. Marker m's shadows are
    ``hp[m, :K_m]`` with ``nhp[m, :K_m]`` half-planes each (``nhp`` 0 past ``K_m``): shapes
    (M, K, V + 2, 3) and (M, K) with K the largest ``K_m``, the pieces in reach of some marker
    rather than all of them. ``hidden[m]``: the marker lies in one of its pieces.
    """
    nm, npc = mx.size, count.size
    hp1 = np.zeros((max(npc, 1), planes.shape[1] + 2, 3))
    nhp1 = np.zeros(max(npc, 1), dtype=np.int64)
    clip = np.zeros((1, 2), dtype=np.int64)
    kept = np.zeros(nm, dtype=np.int64)
    hidden = np.zeros(nm, dtype=np.bool_)
    for m in range(nm):
        kept[m], _, hidden[m] = marker_pieces(m, mx, my, planes, count, sight, shrunk, sight_bbox, blocks, swallow,
                                              bodies, n_ob, margin, max_range, np.bool_(False), hp1, nhp1, clip)
    k = max(1, kept.max()) if nm else 1
    hp = np.zeros((nm, k, planes.shape[1] + 2, 3))
    nhp = np.zeros((nm, k), dtype=np.int64)
    for m in range(nm):  # again, into the table sized by the first pass (cheap next to its use)
        n, _, _ = marker_pieces(m, mx, my, planes, count, sight, shrunk, sight_bbox, blocks, swallow, bodies, n_ob,
                                margin, max_range, np.bool_(False), hp1, nhp1, clip)
        hp[m, :n] = hp1[:n]
        nhp[m, :n] = nhp1[:n]
    return hp, nhp, hidden


@compiled.njit(cache=True, nogil=True)
def _free_points_range(lo, hi, px, py, x0, y0, x1, y1, planes, count, bbox, free):
    for n in range(lo, hi):
        free[n] = _is_free(px[n], py[n], x0, y0, x1, y1, planes, count, bbox)


@compiled.njit(cache=True, nogil=True)
def _visible_points_markers(m0, m1, px, py, free, mx, my, wedge, max_range, planes, count, sight, shrunk,
                            sight_bbox, blocks, swallow, bodies, n_ob, margin, vis):
    """Markers ``m0 <= m < m1``: each one's pieces once (:func:`marker_pieces`), then every point."""
    npc = max(count.size, 1)
    hp = np.zeros((npc, planes.shape[1] + 2, 3))
    nhp = np.zeros(npc, dtype=np.int64)
    clip = np.zeros((npc, 2), dtype=np.int64)
    r2max = max_range * max_range
    for m in range(m0, m1):
        ns, nc, _ = marker_pieces(m, mx, my, planes, count, sight, shrunk, sight_bbox, blocks, swallow, bodies,
                                  n_ob, margin, max_range, np.bool_(True), hp, nhp, clip)
        bx, by = mx[m], my[m]
        for n in range(px.size):
            ok = free[n]
            ax, ay = px[n], py[n]
            if ok:
                dx, dy = ax - bx, ay - by
                ok = dx * dx + dy * dy <= r2max and wedges_ok(dx, dy, wedge, m)
            if ok:
                lox, hix = min(ax, bx), max(ax, bx)
                loy, hiy = min(ay, by), max(ay, by)
                for i in range(nc):
                    p, g = clip[i, 0], clip[i, 1]
                    if (sight_bbox[g, p, 0] >= hix or sight_bbox[g, p, 2] <= lox or sight_bbox[g, p, 1] >= hiy
                            or sight_bbox[g, p, 3] <= loy):
                        continue
                    if segment_enters(ax, ay, bx, by, planes, sight[g], count, p):
                        ok = False
                        break
            if ok:
                for s in range(ns):
                    if in_shadow(ax, ay, hp[s], nhp[s]):
                        ok = False
                        break
            vis[m, n] = ok


@compiled.njit(cache=True, nogil=True)
def _visible_pairs_markers(u0, u1, used, starts, order, px, py, free, mx, my, wedge, max_range, planes, count,
                           sight, shrunk, sight_bbox, blocks, swallow, bodies, n_ob, margin, out):
    """Markers ``used[u]``, ``u0 <= u < u1``: their pieces once each, then their points (``order``, ``starts``)."""
    npc = max(count.size, 1)
    hp = np.zeros((npc, planes.shape[1] + 2, 3))
    nhp = np.zeros(npc, dtype=np.int64)
    clip = np.zeros((npc, 2), dtype=np.int64)
    r2max = max_range * max_range
    for u in range(u0, u1):
        m = used[u]
        ns, nc, _ = marker_pieces(m, mx, my, planes, count, sight, shrunk, sight_bbox, blocks, swallow, bodies,
                                  n_ob, margin, max_range, np.bool_(True), hp, nhp, clip)
        bx, by = mx[m], my[m]
        # the test of _visible_points_markers, written out again (a call per point costs more)
        for i in range(starts[u], starts[u + 1]):
            n = order[i]
            ok = free[n]
            ax, ay = px[n], py[n]
            if ok:
                dx, dy = ax - bx, ay - by
                ok = dx * dx + dy * dy <= r2max and wedges_ok(dx, dy, wedge, m)
            if ok:
                lox, hix = min(ax, bx), max(ax, bx)
                loy, hiy = min(ay, by), max(ay, by)
                for j in range(nc):
                    p, g = clip[j, 0], clip[j, 1]
                    if (sight_bbox[g, p, 0] >= hix or sight_bbox[g, p, 2] <= lox or sight_bbox[g, p, 1] >= hiy
                            or sight_bbox[g, p, 3] <= loy):
                        continue
                    if segment_enters(ax, ay, bx, by, planes, sight[g], count, p):
                        ok = False
                        break
            if ok:
                for s in range(ns):
                    if in_shadow(ax, ay, hp[s], nhp[s]):
                        ok = False
                        break
            out[n] = ok


@dataclass(frozen=True)
class SightArrays:
    """The pieces every marker's line of sight is tested on, and each marker's wedges (:func:`prepare_sight`).

    The pieces are shared: the obstacles' and, with a rule, every reflector's body (an octagon
    around it). What differs from marker to marker (which pieces are its mount, which body is
    its own, which are in reach) :func:`marker_pieces` decides for one marker at a time, so
    nothing of size (markers x pieces) is kept: placement asks this of thousands of candidate
    sites, each a body too.

    Attributes
    ----------
    planes : ndarray, shape (P, V, 3)
        The pieces' edges (``PieceArrays.planes``): the obstacles', then each body's.
    count : ndarray of int64, shape (P,)
        Their edge counts.
    sight : ndarray, shape (2, P, V)
        Edge offsets for line of sight [m]: ``[0]`` as a marker on the piece (its mount) sees
        it, shrunk (``PieceArrays.sight``); ``[1]`` as the others do, grown by
        ``SightRule.reach`` (the same as ``[0]`` without a rule).
    shrunk : ndarray, shape (2, P, V, 2)
        The corners of those pieces [m].
    sight_bbox : ndarray, shape (2, P, 4)
        Their bounding boxes [m].
    blocks : ndarray of bool, shape (2, P)
        Whether they block (``PieceArrays.blocks``).
    swallow : ndarray, shape (P, V)
        Edge offsets of the pieces grown by ``SightRule.grow`` [m]: a marker inside one is on
        its mount (-inf without a rule: no mounts).
    bodies : ndarray, shape (B, 2)
        Where the bodies stand [m] (pieces ``n_ob ..``); a body at a marker's position is its own.
    n_ob : int
        Number of obstacle pieces.
    margin : float
        How far the shadow of a piece that is not the marker's mount is widened [m] (0 without a rule).
    wedge : ndarray, shape (M, W, 4)
        Each marker's wedges ``(nx, ny, cos_inc, offset)`` (:func:`wedges_ok`): a flat marker's
        incidence wedge, and one per mount face (a face whose line passes within the
        reflector's radius of the marker: two in a corner), ``n = (0, 0)`` where unused.
    """

    planes: np.ndarray
    count: np.ndarray
    sight: np.ndarray
    shrunk: np.ndarray
    sight_bbox: np.ndarray
    blocks: np.ndarray
    swallow: np.ndarray
    bodies: np.ndarray
    n_ob: int
    margin: float
    wedge: np.ndarray

    def kernel_args(self) -> tuple:
        """Return the fields the kernels take, in their order (``wedge`` aside)."""
        return (self.planes, self.count, self.sight, self.shrunk, self.sight_bbox, self.blocks, self.swallow,
                self.bodies, self.n_ob, self.margin)


def prepare_sight(obstacles, markers: np.ndarray, bounds: tuple[float, float, float, float],
                  normals: np.ndarray | None = None, max_incidence: float = math.pi / 2,
                  rule: SightRule | None = None, bodies: np.ndarray | None = None) -> tuple[PieceArrays, SightArrays]:
    """Prepare the obstacles, the pieces of the markers' lines of sight and each marker's wedges.

    Parameters
    ----------
    obstacles : scenarios.ConvexPieces or ndarray of shape (B, 4, 2)
        As in :func:`prepare` (already prepared ``PieceArrays`` only when ``rule`` is None).
    markers : ndarray, shape (M, 2)
        Marker positions [m].
    bounds : (float, float, float, float)
        Workspace ``(x0, y0, x1, y1)`` [m]: its sides are mount faces too (the border walls).
    normals, max_incidence
        Flat markers' normals and incidence limit, as in :func:`visible_points`.
    rule : SightRule, optional
        The margins of a usable line of sight (:mod:`planner.pef.sight`); None: the margin-free
        test (segment against the shrunk pieces, the flat wedge only).
    bodies : ndarray, shape (B, 2), optional
        Where the reflectors' bodies stand [m] (every marker of the world, when ``markers`` are
        some of them); default ``markers``. A body at a marker's own position is its own.

    Returns
    -------
    (PieceArrays, SightArrays)
        The obstacles (free space), and the line of sight's pieces.
    """
    mk = np.asarray(markers, float).reshape(-1, 2)
    fn = _normals(normals, mk.shape[0])
    if rule is None or not isinstance(obstacles, ConvexPieces):
        return _prepare_sight(obstacles, mk, bounds, fn, max_incidence, rule, bodies)
    # a planner asks this of the same scenario's markers many times (map, segments, plan, schedule)
    at = None if bodies is None else np.asarray(bodies, float).reshape(-1, 2)
    key = (mk.tobytes(), fn.tobytes(), tuple(float(b) for b in bounds), float(max_incidence), rule,
           None if at is None else at.tobytes())
    memo = _SIGHT.setdefault(obstacles, {})
    got = memo.get(key)
    if got is None:
        got = memo[key] = _prepare_sight(obstacles, mk, bounds, fn, max_incidence, rule, at)
        while len(memo) > _SIGHT_KEPT:
            memo.pop(next(iter(memo)))
    return got


#: Sight arrays kept per set of obstacles (:func:`prepare_sight`), by markers and rule.
_SIGHT: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
#: The PEF's rule and the schedule's sight check, one rule per 5 mm of pose bound
#: (:mod:`planner.schedule.sightcheck`: some twenty in a plan); an entry is tens to hundreds of kB.
_SIGHT_KEPT = 32


def _prepare_sight(obstacles, mk: np.ndarray, bounds, fn: np.ndarray, max_incidence: float, rule: SightRule | None,
                   bodies: np.ndarray | None) -> tuple[PieceArrays, SightArrays]:
    """:func:`prepare_sight` computed (``fn`` the markers' normals, (M, 2))."""
    m_n = mk.shape[0]
    wedge = np.zeros((m_n, 1 if rule is None else _MAX_WEDGES, 4))
    wedge[:, 0, :2] = fn
    wedge[:, 0, 2] = math.cos(max_incidence)
    if rule is None:
        pa = prepare(obstacles)
        twice = lambda a: np.ascontiguousarray(np.stack([a, a]))  # noqa: E731
        return pa, SightArrays(pa.planes, pa.count, twice(pa.sight), twice(pa.shrunk), twice(pa.sight_bbox),
                               twice(pa.blocks), np.full(pa.sight.shape, -np.inf), np.zeros((0, 2)),
                               int(pa.count.size), 0.0, wedge)
    flat = np.any(fn != 0.0, axis=1)
    wedge[flat, 0, 3] = rule.wedge_offset(math.cos(max_incidence))   # the incidence limit within the margin too
    at = mk if bodies is None else np.asarray(bodies, float).reshape(-1, 2)
    geo = _sight_geometry(obstacles, mk, bounds, rule.radius, rule.reach, rule.grow, at)
    for m, faces in enumerate(geo.faces):
        for w, face in enumerate(faces, start=1):
            wedge[m, w] = (face[0], face[1], rule.slope, rule.offset)
    return geo.pa, SightArrays(geo.planes, geo.count, geo.sight, geo.shrunk, geo.sight_bbox, geo.blocks, geo.swallow,
                               geo.bodies, geo.n_ob, float(rule.margin), wedge)


@dataclass(frozen=True, eq=False)
class _SightGeometry:
    """The part of :class:`SightArrays` that does not depend on the rule's margin, and each marker's mount faces."""

    pa: PieceArrays
    planes: np.ndarray
    count: np.ndarray
    sight: np.ndarray
    shrunk: np.ndarray
    sight_bbox: np.ndarray
    blocks: np.ndarray
    swallow: np.ndarray
    bodies: np.ndarray
    n_ob: int
    faces: list


#: Margin-free sight geometry per set of obstacles (:func:`_sight_geometry`): the schedule's sight
#: check asks for a rule per 5 mm of margin, and only the wedges' offsets and the margin differ.
_GEOMETRY: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_GEOMETRY_KEPT = 4


def _sight_geometry(obstacles, mk: np.ndarray, bounds, radius: float, reach: float, grow: float,
                    at: np.ndarray) -> _SightGeometry:
    """Return the pieces (obstacles, then bodies ``at`` (B, 2)), grown and swallowing, and ``mk``'s (M, 2) mount faces.

    ``radius``, ``reach`` and ``grow`` are the rule's (:class:`~planner.pef.sight.SightRule`).
    Kept per obstacles (when :class:`~scenarios.ConvexPieces`), markers, bounds, those three
    and bodies: the arrays are shared by every rule that differs only in its margin (none of
    the callers writes into them).
    """
    key = (mk.tobytes(), at.tobytes(), tuple(float(b) for b in bounds), float(radius), float(reach), float(grow))
    memo = _GEOMETRY.setdefault(obstacles, {}) if isinstance(obstacles, ConvexPieces) else {}
    got = memo.get(key)
    if got is not None:
        return got
    pa = prepare(obstacles)
    pieces = _pieces(obstacles)
    n_ob = len(pieces.count)
    # the obstacles' pieces, then every marker's body (it blocks the others' lines of sight)
    both = _with_bodies(pieces, at, radius)
    base = piece_arrays(both, BOX_SHRINK)
    grown = piece_arrays(both, BOX_SHRINK, reach)
    swallow = piece_arrays(both, BOX_SHRINK, grow).sight
    mount = _mount_table(np.ascontiguousarray(mk[:, 0]), np.ascontiguousarray(mk[:, 1]), base.planes, swallow,
                         base.count, n_ob)
    faces = [_mount_faces(pa, pieces, mk[m], mount[m], radius, bounds) for m in range(mk.shape[0])]
    pair = lambda a, b: np.ascontiguousarray(np.stack([a, b]))  # noqa: E731
    got = _SightGeometry(pa, base.planes, base.count, pair(base.sight, grown.sight), pair(base.shrunk, grown.shrunk),
                         pair(base.sight_bbox, grown.sight_bbox), pair(base.blocks, grown.blocks), swallow,
                         np.ascontiguousarray(at), n_ob, faces)
    memo[key] = got
    while len(memo) > _GEOMETRY_KEPT:
        memo.pop(next(iter(memo)))
    return got


@compiled.njit(cache=True)
def _mount_table(mx, my, planes, swallow, count, n):
    """``mount[m, p]``: piece ``p < n`` is marker m's mount (:func:`_on_mount`); shape (M, n)."""
    out = np.zeros((mx.size, n), dtype=np.bool_)
    for m in range(mx.size):
        for p in range(n):
            out[m, p] = _on_mount(mx[m], my[m], planes, swallow, count, p)
    return out


def _with_bodies(pieces: ConvexPieces, mk: np.ndarray, radius: float) -> ConvexPieces:
    """``pieces`` followed by one octagon per body ``mk`` (B, 2), circumscribing it (radius ``radius``) [m]."""
    ang = np.pi / 8.0 + np.arange(8) * np.pi / 4.0
    octagon = (radius / math.cos(np.pi / 8.0)) * np.column_stack([np.cos(ang), np.sin(ang)])
    nv = max(pieces.vertices.shape[1], 8)
    n_ob, m_n = len(pieces.count), mk.shape[0]
    verts = np.zeros((n_ob + m_n, nv, 2))
    verts[:n_ob, :pieces.vertices.shape[1]] = pieces.vertices
    verts[:n_ob, pieces.vertices.shape[1]:] = pieces.vertices[:, -1:]
    verts[n_ob:, :8] = mk[:, None, :] + octagon[None]
    verts[n_ob:, 8:] = verts[n_ob:, 7:8]
    inner = np.zeros((n_ob + m_n, nv), dtype=np.bool_)
    inner[:n_ob, :pieces.inner.shape[1]] = pieces.inner
    inset = np.zeros((n_ob + m_n, nv))
    inset[:n_ob, :pieces.inset.shape[1]] = pieces.inset
    return ConvexPieces(verts, np.concatenate([pieces.count, np.full(m_n, 8, dtype=np.int64)]),
                        np.concatenate([pieces.owner, -1 - np.arange(m_n, dtype=np.int64)]), inner, inset)


#: Wedges per marker: a flat marker's incidence wedge and up to two mount faces (a corner).
_MAX_WEDGES = 3


def _range(max_range: float, rule: SightRule | None) -> float:
    """Return the range limit the kernels apply [m]: the sensor's, or the rule's usable range."""
    return float(max_range) if rule is None else rule.usable_range(max_range)


def _pieces(obstacles) -> ConvexPieces:
    """Return the obstacles as :class:`~scenarios.ConvexPieces` (box corners packed)."""
    if isinstance(obstacles, ConvexPieces):
        return obstacles
    if isinstance(obstacles, PieceArrays):
        raise ValueError("obstacles: a line-of-sight rule needs the convex pieces, not prepared PieceArrays")
    corners = np.asarray(obstacles, float).reshape(-1, 4, 2)
    return pack_pieces([_Corners(c) for c in corners])


def _mount_faces(pa: PieceArrays, pieces: ConvexPieces, mk: np.ndarray, mount: np.ndarray, radius: float,
                 bounds) -> list[tuple[float, float]]:
    """Return a marker's mount faces: outward unit normals, the nearest first, at most two.

    A face is an obstacle edge of a mount piece (not a cut between pieces), or a side of the
    workspace (the border walls), whose line passes within ``radius`` (the reflector's body) of
    the marker ``mk`` (2,) and whose extent, lengthened by ``radius`` at both ends, the marker
    faces. Faces of one direction count once.
    """
    found = []
    v = pa.vertices
    for p in np.flatnonzero(mount):
        n = int(pa.count[p])
        for k in range(n):
            if pieces.inner[p, k]:
                continue
            a, b = v[p, k], v[p, (k + 1) % n]
            e = b - a
            length = math.hypot(float(e[0]), float(e[1]))
            if length == 0.0:
                continue
            t = float(np.dot(mk - a, e)) / length
            d = abs(float(np.dot(pa.planes[p, k, :2], mk) - pa.planes[p, k, 2]))
            if -radius <= t <= length + radius and d <= radius:
                found.append((d, float(pa.planes[p, k, 0]), float(pa.planes[p, k, 1])))
    x0, y0, x1, y1 = (float(b) for b in bounds)
    for d, nx, ny in ((mk[0] - x0, 1.0, 0.0), (x1 - mk[0], -1.0, 0.0), (mk[1] - y0, 0.0, 1.0), (y1 - mk[1], 0.0, -1.0)):
        if abs(d) <= radius:
            found.append((abs(float(d)), nx, ny))
    faces: list[tuple[float, float]] = []
    for _, nx, ny in sorted(found):
        if all(nx * fx + ny * fy < 1.0 - 1e-9 for fx, fy in faces):
            faces.append((nx, ny))
    return faces[:_MAX_WEDGES - 1]


def visible_points(points: np.ndarray, markers: np.ndarray, obstacles, max_range: float,
                   bounds: tuple[float, float, float, float], normals: np.ndarray | None = None,
                   max_incidence: float = math.pi / 2, rule: SightRule | None = None,
                   bodies: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Visibility of markers from arbitrary points.

    Parameters
    ----------
    points : ndarray, shape (N, 2)
        Query points [m].
    markers : ndarray, shape (M, 2)
        Marker positions [m].
    obstacles : scenarios.ConvexPieces, PieceArrays or ndarray of shape (B, 4, 2)
        Obstacles as convex pieces, or box corners [m] (see :func:`prepare`).
    max_range : float
        Sensor range limit [m] (inclusive).
    bounds : (float, float, float, float)
        Workspace ``(x0, y0, x1, y1)`` [m] (``Workspace.bounds``); points outside are not free.
    normals : ndarray, shape (M, 2), optional
        Unit normals of flat markers, (0, 0) for posts (``Scenario.marker_normals``); default
        all posts.
    max_incidence : float
        Largest angle between ``p - M`` and a flat marker's normal [rad], in (0, pi/2].
    rule : SightRule, optional
        The margins of a usable line of sight (:mod:`planner.pef.sight`: obstacles grown, mount
        and incidence wedges, the range shortened by the margin); None: the margin-free test.
    bodies : ndarray, shape (B, 2), optional
        Every reflector body in the world [m], when ``markers`` are some of them (the rule only;
        :func:`prepare_sight`).

    Returns
    -------
    vis : ndarray of bool, shape (M, N)
        ``vis[m, n]``: marker m visible from point n (marker-major, the layout the PEF kernels
        read; transpose for (N, M)). False wherever the point is not free.
    free : ndarray of bool, shape (N,)
        Point in free space.
    """
    p = np.ascontiguousarray(np.asarray(points, float).reshape(-1, 2))
    mk = np.asarray(markers, float).reshape(-1, 2)
    pa, sa = prepare_sight(obstacles, mk, bounds, normals, max_incidence, rule, bodies)
    x0, y0, x1, y1 = (float(v) for v in bounds)
    vis = np.empty((mk.shape[0], p.shape[0]), dtype=np.bool_)
    free = np.empty(p.shape[0], dtype=np.bool_)
    px, py = np.ascontiguousarray(p[:, 0]), np.ascontiguousarray(p[:, 1])
    run_ranges(_free_points_range, p.shape[0], (px, py, x0, y0, x1, y1, pa.planes, pa.count, pa.bbox, free),
               min_chunk=2048)
    # marker by marker: each one's pieces in reach once, then every point (widened pieces by
    # their shadows, the grid path's half-planes; the others by clipping the segment)
    run_ranges(_visible_points_markers, mk.shape[0],
               (px, py, free, np.ascontiguousarray(mk[:, 0]), np.ascontiguousarray(mk[:, 1]), sa.wedge,
                _range(max_range, rule), *sa.kernel_args(), vis), min_chunk=8)
    return vis, free


def visible_pairs(points: np.ndarray, which: np.ndarray, markers: np.ndarray, obstacles, max_range: float,
                  bounds: tuple[float, float, float, float], normals: np.ndarray | None = None,
                  max_incidence: float = math.pi / 2, rule: SightRule | None = None,
                  bodies: np.ndarray | None = None) -> np.ndarray:
    """Whether each point sees one marker: ``visible_points(points, ...)[which[n], n]`` for each n.

    The same test, made only for the pairs asked (each marker's pieces prepared once, for the
    markers named in ``which``): a fix's lines of sight, not every marker from every pose.

    Parameters
    ----------
    points : ndarray, shape (N, 2)
        Query points [m].
    which : ndarray of int, shape (N,)
        The marker each point looks at (an index into ``markers``).
    markers, obstacles, max_range, bounds, normals, max_incidence, rule, bodies
        As in :func:`visible_points` (all the markers: the arrays are those it prepares).

    Returns
    -------
    numpy.ndarray of bool, shape (N,)
    """
    p = np.ascontiguousarray(np.asarray(points, float).reshape(-1, 2))
    which = np.asarray(which, dtype=np.int64).reshape(-1)
    mk = np.asarray(markers, float).reshape(-1, 2)
    pa, sa = prepare_sight(obstacles, mk, bounds, normals, max_incidence, rule, bodies)
    x0, y0, x1, y1 = (float(v) for v in bounds)
    out = np.zeros(p.shape[0], dtype=np.bool_)
    if p.shape[0] == 0:
        return out
    free = np.empty(p.shape[0], dtype=np.bool_)
    px, py = np.ascontiguousarray(p[:, 0]), np.ascontiguousarray(p[:, 1])
    run_ranges(_free_points_range, p.shape[0], (px, py, x0, y0, x1, y1, pa.planes, pa.count, pa.bbox, free),
               min_chunk=2048)
    order = np.argsort(which, kind="stable")
    used, first = np.unique(which[order], return_index=True)
    starts = np.append(first, order.size).astype(np.int64)
    run_ranges(_visible_pairs_markers, used.size,
               (used.astype(np.int64), starts, order.astype(np.int64), px, py, free, np.ascontiguousarray(mk[:, 0]),
                np.ascontiguousarray(mk[:, 1]), sa.wedge, _range(max_range, rule), *sa.kernel_args(), out),
               min_chunk=8)
    return out


def _normals(normals: np.ndarray | None, m: int) -> np.ndarray:
    """Markers' normals as a (M, 2) float array; all posts (zeros) when None."""
    if normals is None:
        return np.zeros((m, 2))
    fn = np.asarray(normals, float).reshape(-1, 2)
    if fn.shape[0] != m:
        raise ValueError(f"normals: expected {m} rows (one per marker), got {fn.shape[0]}")
    return fn


def segment_blocked(a, b, obstacles) -> bool:
    """Tell whether segment a-b (each (x, y) [m]) crosses an obstacle's interior (line of sight)."""
    pa = prepare(obstacles)
    return bool(_blocked(float(a[0]), float(a[1]), float(b[0]), float(b[1]), pa.planes, pa.sight, pa.count,
                         pa.sight_bbox, pa.blocks))


# --- grid path ------------------------------------------------------------------------------

@compiled.njit(cache=True)
def _first_above(x, v):
    """Smallest index i with x[i] > v (x ascending, uniform); x.size if none."""
    n = x.size
    # outside the grid (and infinite v, whose int() is undefined) without walking the row
    if not x[0] <= v:  # NaN too, as before
        return 0
    if x[n - 1] <= v:
        return n
    i = int(math.floor((v - x[0]) / (x[1] - x[0]))) + 1
    if i < 0:
        i = 0
    if i > n:
        i = n
    while i < n and x[i] <= v:
        i += 1
    while i > 0 and x[i - 1] > v:
        i -= 1
    return i


@compiled.njit(cache=True)
def _first_at_or_above(x, v):
    """Smallest index i with x[i] >= v (x ascending, uniform); x.size if none."""
    n = x.size
    if not x[0] < v:  # NaN too, as before
        return 0
    if x[n - 1] < v:
        return n
    i = int(math.ceil((v - x[0]) / (x[1] - x[0])))
    if i < 0:
        i = 0
    if i > n:
        i = n
    while i < n and x[i] < v:
        i += 1
    while i > 0 and x[i - 1] >= v:
        i -= 1
    return i


@compiled.njit(cache=True)
def _free_grid_kernel(x, y, x0, y0, x1, y1, planes, count, bbox, free):
    for iy in range(y.size):
        for ix in range(x.size):
            free[iy, ix] = x0 <= x[ix] <= x1 and y0 <= y[iy] <= y1
    for p in range(count.size):
        # Cells of the piece's bounding box, then the exact test used by the points path.
        i0 = max(_first_at_or_above(x, bbox[p, 0]) - 1, 0)
        i1 = min(_first_above(x, bbox[p, 2]) + 1, x.size)
        j0 = max(_first_at_or_above(y, bbox[p, 1]) - 1, 0)
        j1 = min(_first_above(y, bbox[p, 3]) + 1, y.size)
        for iy in range(j0, j1):
            for ix in range(i0, i1):
                if free[iy, ix] and inside_closed(x[ix], y[iy], planes, count, p):
                    free[iy, ix] = False


@compiled.njit(cache=True)
def shadow_row(hp, n, yy, x):
    """Columns ``i0 <= ix < i1`` of grid row ``yy`` inside a shadow (``n`` half-planes ``hp``).

    ``hp`` (>= n, 3) as written by :func:`~planner.pef.convex.shadow_halfplanes`; ``x`` the
    cell-centre columns (ascending, uniform). An empty range (i0 >= i1) when the row misses it
    or ``n <= 0``.
    """
    if n <= 0:
        return 0, 0
    lo, hi = -np.inf, np.inf
    for h in range(n):
        a, bb, c = hp[h, 0], hp[h, 1], hp[h, 2]
        rhs = -(bb * yy + c)  # a x < rhs
        if a > 0.0:
            v = rhs / a
            if v < hi:
                hi = v
        elif a < 0.0:
            v = rhs / a
            if v > lo:
                lo = v
        elif rhs <= 0.0:
            return 0, 0
        if not lo < hi:
            return 0, 0
    return _first_above(x, lo), _first_at_or_above(x, hi)


@compiled.njit(cache=True)
def _visible_grid_marker(m, x, y, mx, my, wedge, max_range, hp, nhp, hidden_all, free, vis):
    """Fill ``vis[m]``: free, in range and in the wedges, then clear each piece's shadow row by row."""
    r2max = max_range * max_range
    npc = nhp.shape[1]
    hidden = hidden_all[m]
    for iy in range(y.size):
        yy = y[iy]
        dy = yy - my[m]
        for ix in range(x.size):
            dx = x[ix] - mx[m]
            vis[m, iy, ix] = (free[iy, ix] and (dx * dx + dy * dy <= r2max) and not hidden
                              and wedges_ok(dx, dy, wedge, m))
        if hidden:
            continue
        for p in range(npc):
            i0, i1 = shadow_row(hp[m, p], nhp[m, p], yy, x)
            for ix in range(i0, i1):
                vis[m, iy, ix] = False


@compiled.njit(cache=True, nogil=True)
def _visible_grid_markers(m0, m1, x, y, mx, my, wedge, max_range, hp, nhp, hidden, free, vis):
    for m in range(m0, m1):
        _visible_grid_marker(m, x, y, mx, my, wedge, max_range, hp, nhp, hidden, free, vis)


def visible_grid(x: np.ndarray, y: np.ndarray, markers: np.ndarray, obstacles,
                 max_range: float, bounds: tuple[float, float, float, float], normals: np.ndarray | None = None,
                 max_incidence: float = math.pi / 2, rule: SightRule | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Visibility of markers from the cell centres of a regular grid.

    Parameters
    ----------
    x : ndarray, shape (nx,)
        Cell-centre x coordinates, ascending and uniformly spaced [m].
    y : ndarray, shape (ny,)
        Cell-centre y coordinates, ascending and uniformly spaced [m].
    markers, obstacles, max_range, bounds, normals, max_incidence, rule
        As in :func:`visible_points`.

    Returns
    -------
    vis : ndarray of bool, shape (M, ny, nx)
        ``vis[m, iy, ix]``: marker m visible from cell (iy, ix); False where not free.
    free : ndarray of bool, shape (ny, nx)
        Cell centre in free space.
    """
    x = np.ascontiguousarray(x, dtype=float)
    y = np.ascontiguousarray(y, dtype=float)
    mk = np.asarray(markers, float).reshape(-1, 2)
    pa, sa = prepare_sight(obstacles, mk, bounds, normals, max_incidence, rule)
    x0, y0, x1, y1 = (float(v) for v in bounds)
    free = np.empty((y.size, x.size), dtype=np.bool_)
    _free_grid_kernel(x, y, x0, y0, x1, y1, pa.planes, pa.count, pa.bbox, free)
    vis = np.empty((mk.shape[0], y.size, x.size), dtype=np.bool_)
    mx, my = np.ascontiguousarray(mk[:, 0]), np.ascontiguousarray(mk[:, 1])
    hp, nhp, hidden = shadow_table(mx, my, *sa.kernel_args(), _range(max_range, rule))
    run_ranges(_visible_grid_markers, mk.shape[0],
               (x, y, mx, my, sa.wedge, _range(max_range, rule), hp, nhp, hidden, free, vis))
    return vis, free


def scenario_visible_points(scenario: Scenario, points: np.ndarray,
                            sight: bool = True, widen: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """:func:`visible_points` for a scenario's markers (their kinds too), obstacles and declared sensor.

    With ``sight`` False the margin-free geometry (no :func:`scenario_sight_rule`): what the
    drawing alone says. ``widen`` [m] is added to the rule's margin: a marker is then seen from
    every position within ``widen`` of a point, as from the point (the samples of a path that
    are ``2 widen`` apart, :mod:`planner.routes.admissible`). Returns ``vis`` (M, N) and ``free`` (N,).
    """
    return visible_points(points, scenario.marker_positions(), scenario.obstacle_pieces(),
                          scenario.sensor.max_range, scenario.workspace.bounds, scenario.marker_normals(),
                          scenario.sensor.max_incidence, scenario_sight_rule(scenario, widen) if sight else None)


def scenario_visible_grid(scenario: Scenario, x: np.ndarray, y: np.ndarray,
                          sight: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """:func:`visible_grid` for a scenario's markers (their kinds too), obstacles and declared sensor.

    ``sight`` as in :func:`scenario_visible_points`.

    Returns ``vis`` (M, ny, nx) and ``free`` (ny, nx).
    """
    return visible_grid(x, y, scenario.marker_positions(), scenario.obstacle_pieces(),
                        scenario.sensor.max_range, scenario.workspace.bounds, scenario.marker_normals(),
                        scenario.sensor.max_incidence, scenario_sight_rule(scenario) if sight else None)


def scenario_sight_rule(scenario: Scenario, widen: float = 0.0) -> SightRule:
    """Return the line-of-sight rule of a scenario's maps (:func:`planner.pef.sight.sight_rule` of its sensor).

    ``widen`` [m] is added to its margin (:func:`scenario_visible_points`).
    """
    rule = sight_rule(scenario.sensor)
    return rule if widen <= 0.0 else SightRule(margin=rule.margin + float(widen), radius=rule.radius, reach=rule.reach)


compiled.keep_fresh(__name__)
