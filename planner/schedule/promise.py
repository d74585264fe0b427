"""The promise of a moving fix, for the measurement schedule.

A fix started at arc length ``s_j`` measures its k markers one after another, the m-th
``(m + 1) * measurement_time`` after the start, while the robot drives on; the earlier ranges
are carried to the last one by odometry (:mod:`estimators.fault.carried`). The fix's promise,
``predicted_tau``, bounds the diameter of the fault area the simulation realises for that
construction (:func:`estimators.fault.carried.promised_fault_area`'s, from measured ranges at the
true positions), over every true pose the robot may take (below, "Derived promise").

The schedule searches over thousands of candidate starts with the same bound (k = 2, both
measurement orders; for other k the static PEF of the stretch), and :func:`predict` computes
it for the fixes it chose (for every k).

Not covered here: a fix that lost a marker mid-fix is promised by ``sim.episode.fixes`` the
construction of the markers it did measure at the planned poses, without this bound (only with
``sensor.block_probability``).

Slowing down for a fix
    The shift of an earlier range grows with speed, so a fix that breaks its promise at
    cruising speed may keep it slower. :data:`SPEED_LEVELS` are the speeds tried (fractions of
    the planned speed, then ``planning.min_fix_speed``); :func:`slowed_speeds` caps the path's
    vertex speeds over the fix's stretch and lets the robot brake and speed up again at the
    planner's acceleration limit. Slower, the follower's lookahead (its corner cut), the start
    lag and the carried travel shrink too, so a corner that makes the promise too large at
    cruising speed is taken slower. A fix that breaks its promise even at the minimum speed is
    not usable.

Derived promise
    The robot does not measure at the planned poses: it drives on its *estimate* with a
    pure-pursuit follower and starts a fix when the estimate passes the planned start. The
    promise is therefore a bound on the realised fault area over every fix whose true
    measurement positions lie within ``Δ_i`` of the planned ones
    (:func:`estimators.fault.perturbed.perturbed_diameters`: the marker directions turn by at
    most ``asin((Δ_i + shift bound) / r_i)``, the bands widen by ``Re Δ_i``, the annuli's curvature
    over the area is bounded by its sagitta, and the parallelogram, or for k > 2 the strip
    polygon, is taken at its worst). :func:`pose_bound` states ``Δ_i`` as the sum of

    - the follower's tracking error on the path, :func:`tracking_bound` (below, "Tracking");
    - the estimate's error the follower steers by, and that decides when a fix starts: the
      error the plan itself certifies while the fix is taken, i.e. the previous fix's promise
      (the largest of its fallbacks' where it has any; with redundancy also the fix before it,
      when the previous one may be lost) plus the drift bound from its start until this fix
      completes (:func:`planner.schedule.schedule.certified_estimate`). The schedule's search
      scores candidates with ``eps_max`` (every certified error is under it), then recomputes
      the chosen fixes' promises with the certified errors until each is at least what the
      promises before it certify (a post-fixed point: the promises only shrink);
    - the start lag: a fix starts at the first control tick past its planned start, and each
      range at the physics step it falls due, up to :data:`START_LAG` late, at the planned speed
      near the robot (:func:`speed_reach`: the follower commands the planned speed of the vertex
      nearest its estimate, and keeps to the acceleration-limited profile);
    - the speed: within a fix (``k measurement_time``, tens of ms) the follower changes its
      speed at most at :data:`FOLLOWER_MAX_ACCEL`: ``FOLLOWER_MAX_ACCEL t^2 / 2`` along the path.

    The dead-reckoned travel over which an earlier range is carried is bounded by that speed
    times the time. Assumptions: the estimate's error while a fix is taken is within what the
    plan certifies there, which holds by induction along the schedule when the fixes before
    kept their promises, the filter's estimate lay in the realised area (as the plan's
    predicted error ``promise + drift`` assumes) and the drift bound held (the calibrated dock
    starts the induction); the filter's heading std at a fix is no larger than
    ``planning.heading_std_deg`` (a larger one is a broken promise the check reports), noise
    within its declared bound, the follower :mod:`sim.episode.follower` with this module's
    lookahead and acceleration (it reads them from here).

Tracking
    Pure pursuit steers towards the path point one lookahead ``L = max(LOOKAHEAD_MIN,
    LOOKAHEAD_GAIN v)`` (plus one vertex spacing) ahead. :func:`tracking_bound` sums two parts.

    - *The turn it cuts.* It drives on the chords of the path of arc length ``L``: its distance
      from the path is taken as the largest distance of ``path(s)`` from a chord of arc length
      ``L`` over it (0 on a straight; in a corner it grows with the heading change within ``L``,
      so the heading change of a fix taken in a corner enters here). Leaving a corner it swings
      wide and settles back, by no more than it cut the turn: the bound at ``s`` is the largest
      chord bound over the :data:`SETTLE_LOOKAHEADS` ``L`` before ``s``. That window is
      measured on the follower (corridor world: 9.5 cm wide at a 90 deg corner, back within
      1.5 cm 2.5 m later), not derived: the swing goes on decaying past it (random world 38 at
      1.4 m/s: out 6.5-10 cm at the corner's end, back across 3.4 m later, out by 1-2 cm again
      3.5 m after that, slower than the linear model below says), within the second part's
      headroom in every episode checked.
    - *The wheels' systematic error.* The declared wheel radius error ``e`` turns a robot
      commanded straight at ``kappa = 2 |e| / b`` (:func:`turn_bias`), which its odometry does
      not see; the fixes move the estimate back to the truth, so the follower steers by an
      estimate that drifts the same way. Linearised about a straight (lateral offset ``y``,
      arc length ``sigma``), pure pursuit commands the curvature ``-2 (y + L y') / L^2``, so
      ``y'' + 2 y' / L + 2 y / L^2 = kappa``, which settles at ``y = kappa L_d^2 / 2``, ``L_d``
      the distance to its target (at most one lookahead and one and a half vertex spacings:
      the target is the first vertex one lookahead past the vertex nearest the robot). The
      follower does not answer the turn directly: it answers the estimate, whose heading the
      filter corrects only as the fixes show the drift, so the offset is reached as the
      response to a step through a lightly damped loop (corner world at 1.4 m/s, ``e = 0.004``,
      ``b = 0.33 m``: 19.5 mm final, 33.6 mm at its first peak after the dock, swinging about
      the final value with half the amplitude 6-7 m later). No second-order response to a step
      exceeds twice its final value, whatever its damping: the part is :data:`STEP_PEAK`
      ``= 2`` times ``kappa L_d^2 / 2``. From the dock, where the robot starts at rest on the
      path with its estimate calibrated, it is at most ``kappa s^2 / 2`` at arc length ``s``
      (the turn alone, which the follower's answer only takes back while the offset first
      grows; past that rise the peak bounds it). On random world 38 (``e = 0.0034``, ``b = 0.33 m``,
      1.4 m/s) the robot runs 1.4-2.2 cm to its left on the straights, both ways (bound
      3.3 cm); on ``warehouse`` (0.002, 0.5 m, 1 m/s) 2.6-3.4 mm (bound 7.2 mm).

    Argued from the follower and checked on it at every control step, not proved
    (``tests/sim/episode/test_offset_bound.py``: the corner world's corners at 1 m/s, and the
    same world at 1.4 m/s with the largest wheel radius error random worlds draw).

Polygon tolerance
    The simulation's fault area is a polygon reaching up to ``tol = DEFAULT_TOLERANCE_FRACTION
    min(rho)`` beyond the exact arcs (:mod:`estimators.fault.exact`), so its diameter up to
    ``2 tol`` beyond the exact one. Every strip of the bound's polygon holds the disc of radius
    ``min(h) >= min(rho)``, so the promise ``d >= 2 min(rho)`` and ``2 tol <= f d``:
    :data:`POLYGON_TOLERANCE` ``= f = DEFAULT_TOLERANCE_FRACTION``. A fix is usable when its
    promise times ``1 + POLYGON_TOLERANCE`` is under ``eps_max``; nothing else is tolerated.

Start lag
    The robot starts a fix at its first control tick past the planned start, and takes each
    range at the first physics step it falls due: up to :data:`START_LAG` later than planned
    (``sim.episode.drive`` checks its own control and physics periods against it).

Lines of sight
    A fix is promised only where each of its markers stays in the laser's sight from every
    position within its pose bound (:mod:`planner.schedule.sightcheck`); elsewhere
    :func:`predict` returns inf and the schedule searches again without that subset there.

Bearings
    The promise counts ranges only. A fix that also measures bearings realises the same
    annuli intersected with the heading-free regions of its bearings' pairwise differences
    (:mod:`estimators.fault.exact`, "Robot-frame bearings"): a subset, so its diameter is at most
    the ranges-only realised one's (up to the polygonisation: it lies in the ranges-only exact
    set of ``rho + tolerance``; tested in ``tests/estimators/fault/test_heading_free.py``).
    Bearings therefore never make a fix break a promise its ranges keep. What does *not* hold:
    the heading-free set is the union over all headings of the heading-given wedges'
    intersections, so it is larger than the intersection at a known heading (the planner's
    ``exact``/``strips`` PEF with bearings, which assume the heading known); with two or more
    ranges the annuli bound the fix, so the range-only promise stays the right one to keep.
"""

from __future__ import annotations

import hashlib
import itertools
import math
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from estimators.fault.exact import DEFAULT_TOLERANCE_FRACTION
from estimators.fault.perturbed import perturbed_diameters
from jit import compiled
from planner.pef.threads import run_ranges
from planner.routes.smoothing import MAX_ACCEL, acceleration_limited
from planner.schedule.pathtime import Kinematics, Track, mean_speed
from planner.schedule.sightcheck import unseen
from scenarios.schema import Scenario

SPEED_LEVELS = (1.0, 0.5, 0.25)
"""Fractions of the planned speed tried for a fix, before ``planning.min_fix_speed``."""
MAX_SUBSETS = 400
"""Above this many k-subsets of path-visible markers, only the PEF's pointwise-best subsets
along the path are considered (cost: one ``tau_subset`` call per subset)."""
POLYGON_TOLERANCE = DEFAULT_TOLERANCE_FRACTION
"""Relative excess of a realised (polygonised) fault-area diameter over its promise: the
polygon's reach beyond the exact arcs (module docstring, "Polygon tolerance")."""
LOOKAHEAD_MIN = 0.3
"""The path follower's shortest lookahead [m] (``sim.episode.follower.PurePursuit`` reads it)."""
LOOKAHEAD_GAIN = 0.8
"""The path follower's lookahead per speed [s]."""
SETTLE_LOOKAHEADS = 3.0
"""Length, in lookaheads, over which the follower settles back onto the path after a turn: it
leaves a 90 deg corner of the corridor world (lookahead 0.8 m + 0.1 m vertex spacing) 9.5 cm
wide and is back within 1.5 cm 2.5 m later. Measured on the follower, not derived (below)."""
STEP_PEAK = 2.0
"""Peak of the steady offset's step response over its final value: no second-order response to
a step overshoots by more than its final value, whatever its damping (module docstring,
"Tracking")."""
ROTATE_ABOVE = math.radians(60.0)
"""The path follower turns on the spot while its target lies more than this off its heading [rad]
(``sim.episode.follower.PurePursuit`` reads it); below it, it drives an arc towards the target."""
FOLLOWER_MAX_ACCEL = MAX_ACCEL
"""The path follower's limit on the change of its speed [m/s^2] (the planner's own)."""
START_LAG = 1.0 / 48.0
"""Latest a fix may start after its planned time [s]: one control period and one physics step
(the simulation's 60 Hz control at 240 Hz physics; ``sim.episode.drive`` checks its own)."""


@dataclass(frozen=True, eq=False)
class Level:
    """Promises of every candidate fix at one speed level (C subsets, n samples).

    Attributes
    ----------
    tau : ndarray, shape (C, n)
        Promise of a fix of subset c started at sample j [m] (inf where not visible).
    flipped : ndarray, shape (C, n), bool
        The subset is best measured in reverse order.
    speed : ndarray, shape (n,)
        Speed during the fix [m/s]; nan where it is the planned (cruising) one.
    """

    tau: np.ndarray
    flipped: np.ndarray
    speed: np.ndarray


def local_speed(s_v: np.ndarray, speed: np.ndarray, s: np.ndarray, reach) -> np.ndarray:
    """Largest planned vertex speed within ``reach`` (float or array like ``s``) of each arc length ``s`` [m/s].

    Between vertices the speed changes monotonically (constant acceleration), so the largest
    over a stretch is that of the vertices bracketing it.
    """
    s = np.asarray(s, dtype=float)
    v = np.asarray(speed, dtype=float)
    lo = np.clip(np.searchsorted(s_v, s - reach, side="right") - 1, 0, len(v) - 1)
    hi = np.clip(np.searchsorted(s_v, s + reach, side="left"), 0, len(v) - 1)
    # sparse table of running maxima: O(N log N) once, O(1) per query
    table = [v]
    while 2 ** len(table) <= len(v):
        w = 2 ** (len(table) - 1)
        table.append(np.maximum(table[-1][:-w], table[-1][w:]))
    n = hi - lo + 1
    lvl = np.floor(np.log2(np.maximum(n, 1))).astype(np.int64)
    out = np.empty(s.shape)
    for q in np.unique(lvl).tolist():
        m = lvl == q
        out[m] = np.maximum(table[q][lo[m]], table[q][hi[m] - 2 ** q + 1])
    return out


def speed_reach(s_v: np.ndarray, off: np.ndarray) -> np.ndarray:
    """Arc length around a planned point whose planned speeds bound the robot's there [m].

    The follower commands the planned speed of the path vertex nearest its estimate
    (:mod:`sim.episode.follower`), which is within ``off`` (estimate error plus tracking bound)
    of the true position, so within ``off`` plus one vertex spacing along the path; it changes
    its speed at most at :data:`FOLLOWER_MAX_ACCEL`, the rate the planned profile is limited to
    (:func:`planner.routes.smoothing.acceleration_limited`), so it keeps to the profile up to
    one control period (``FOLLOWER_MAX_ACCEL START_LAG``, added by the caller).
    """
    return np.asarray(off, dtype=float) + float(np.max(np.diff(s_v), initial=0.0))


def turn_bias(robot) -> float:
    """Curvature a robot commanded straight drives from its declared wheel radius error [1/m].

    The right wheel is ``r (1 + e)`` and the left ``r (1 - e)``
    (:mod:`sim.physics.robot`): at equal wheel speeds the robot turns at ``2 |e| / b``.

    Parameters
    ----------
    robot : scenarios.schema.RobotSpec
        The declared robot (``wheel_radius_error`` e, ``wheel_base`` b [m]).
    """
    return 2.0 * abs(float(robot.wheel_radius_error)) / float(robot.wheel_base)


def tracking_bound(path: np.ndarray, s_v: np.ndarray, speed: np.ndarray, s: np.ndarray,
                   bias: float) -> np.ndarray:
    """Bound on the follower's distance from the path at arc length ``s`` (module docstring) [m].

    Parameters
    ----------
    path : ndarray, shape (N, 2)
        Path vertices [m].
    s_v : ndarray, shape (N,)
        Their arc length [m].
    speed : ndarray, shape (N,)
        Planned vertex speeds [m/s].
    s : ndarray, any shape
        Arc lengths [m].
    bias : float
        The robot's :func:`turn_bias` [1/m].

    Returns
    -------
    numpy.ndarray, same shape as ``s``
        The sum of two parts (module docstring, "Tracking"), ``L`` the lookahead at the local
        speed plus one vertex spacing [m]: the largest distance of ``path(a)`` from a chord
        ``path(b) path(b + L)`` with ``b <= a <= b + L`` over ``a`` in the
        :data:`SETTLE_LOOKAHEADS` ``L`` before ``s``; and the offset the wheel radius error
        holds, :data:`STEP_PEAK` ``bias (L + spacing / 2)^2 / 2``, and at most ``bias s^2 / 2``
        (the path starts at rest on a dock).
    """
    s = np.asarray(s, dtype=float)
    spacing = float(np.max(np.diff(s_v), initial=0.0))
    reach = LOOKAHEAD_MIN + LOOKAHEAD_GAIN * float(np.max(speed, initial=0.0)) + spacing
    look = np.maximum(LOOKAHEAD_MIN, LOOKAHEAD_GAIN * local_speed(s_v, speed, s, reach)) + spacing
    out = settle_bound(path, s_v, s, look)
    if bias > 0.0:
        # from the dock, where it starts on the path: the turn alone, kappa s^2 / 2, until the
        # step's peak (the follower's answer only takes it back towards the path)
        steady = STEP_PEAK * 0.5 * float(bias) * (look + 0.5 * spacing) ** 2
        out = out + np.minimum(steady, 0.5 * float(bias) * np.maximum(s, 0.0) ** 2)
    return out


def departure_bound(path: np.ndarray, s_v: np.ndarray, speed: np.ndarray, s: np.ndarray,
                    heading: float) -> np.ndarray:
    """Bound on the follower's extra distance from the path as it leaves its dock [m].

    The robot stands at the path's start with the dock's ``heading``; its first target, one
    lookahead ahead, lies ``alpha`` off that heading. Above :data:`ROTATE_ABOVE` it turns on the
    spot until the target is :data:`ROTATE_ABOVE` off, then, like below it, drives the arc
    tangent to its heading through the target: an arc of chord ``L`` and tangent angle
    ``alpha`` strays ``L / 2 tan(alpha / 2)`` from its chord. The lookahead grows as the robot
    speeds up, so ``L`` is the longest over the departure (plus one vertex spacing), and the
    robot is back on the path, like leaving a corner, within :data:`SETTLE_LOOKAHEADS` more
    lookaheads: the bound holds over ``[0, (SETTLE_LOOKAHEADS + 1) L]``, 0 after it. It adds to
    :func:`tracking_bound` (which bounds the chord's distance from the path). Argued from the
    follower's geometry like the settle factor; checked on episodes
    (``tests/sim/test_realmap_tb3.py``).

    Parameters
    ----------
    path, s_v, speed : ndarray, shape (N, 2), (N,), (N,)
        Path vertices [m], their arc length [m] and planned speeds [m/s].
    s : ndarray, any shape
        Arc lengths [m].
    heading : float
        The robot's heading at the start [rad].

    Returns
    -------
    numpy.ndarray, same shape as ``s``
    """
    s = np.asarray(s, dtype=float)
    spacing = float(np.max(np.diff(s_v), initial=0.0))
    reach = (SETTLE_LOOKAHEADS + 1.0) * (LOOKAHEAD_MIN + LOOKAHEAD_GAIN * float(np.max(speed, initial=0.0)) + spacing)
    v_max = float(local_speed(s_v, speed, np.array([0.0]), reach)[0])
    look = max(LOOKAHEAD_MIN, LOOKAHEAD_GAIN * v_max) + spacing
    # the first target: one shortest lookahead ahead (the robot stands still)
    target = np.array([np.interp(LOOKAHEAD_MIN, s_v, path[:, 0]), np.interp(LOOKAHEAD_MIN, s_v, path[:, 1])])
    d = target - path[0]
    if not np.hypot(*d) > 0.0:
        return np.zeros(s.shape)
    off = math.atan2(d[1], d[0]) - heading
    alpha = min(abs(math.atan2(math.sin(off), math.cos(off))), ROTATE_ABOVE)
    dep = 0.5 * look * math.tan(0.5 * alpha)
    return np.where(s <= (SETTLE_LOOKAHEADS + 1.0) * look, dep, 0.0)


def settle_bound(path: np.ndarray, s_v: np.ndarray, s: np.ndarray, look: np.ndarray) -> np.ndarray:
    """Return the geometric part of the tracking bound: the chord bound, or the largest one it settles from [m].

    The largest :func:`chord_bound` over ``[s - SETTLE_LOOKAHEADS look, s]`` (25 points): leaving a
    turn the follower swings out by no more than it cut the turn, and is back within a few
    lookaheads. :func:`tracking_bound` adds the wheels' part to it.

    Parameters
    ----------
    path, s_v : ndarray, shape (N, 2), (N,)
        Path vertices and their arc length [m].
    s, look : ndarray, same shape
        Arc lengths and lookaheads (chord lengths along the path) [m].

    Returns
    -------
    numpy.ndarray, same shape as ``s``
    """
    return _chords(path, s_v, s, look, SETTLE_LOOKAHEADS, np.linspace(0.0, 1.0, 25))


def chord_bound(path: np.ndarray, s_v: np.ndarray, s: np.ndarray, look: np.ndarray) -> np.ndarray:
    """Largest distance of ``path(s)`` from a chord ``path(a) path(a + look)``, ``a <= s <= a + look`` [m].

    Parameters
    ----------
    path, s_v : ndarray, shape (N, 2), (N,)
        Path vertices and their arc length [m].
    s, look : ndarray, same shape
        Arc lengths and chord lengths (along the path) [m].
    """
    return _chords(path, s_v, s, look, 0.0, np.zeros(1))


_CHORDS_MEMO: OrderedDict[bytes, dict[bytes, float]] = OrderedDict()
#: Paths whose chord bounds :func:`_chords` keeps (least recently used first out): a schedule's
#: search asks for the bound at the same arc lengths and lookaheads again for each rung of its
#: ladder, slow-down level and clearance pass.
CHORDS_MEMO_PATHS = 32


def _chords(path, s_v, s, look, reach: float, back: np.ndarray) -> np.ndarray:
    """Return the largest :func:`chord_bound` at ``s - reach look back_j`` over ``j``, shape of ``s`` [m].

    Each point's bound depends only on its own ``(s, look)`` and on the path, so the bounds are
    remembered per path (keyed by the bytes of the path, ``reach`` and ``back``) and per point
    (keyed by the bytes of ``s`` and ``look``): a remembered value is the number computed, and
    only the points not seen before on that path are computed. A point whose chords all lie on
    one axis-aligned straight of the path has the bound 0 without the kernel
    (:func:`_on_axis_aligned_straight`: exact there, where the kernel gives 0 or rounding).
    """
    s = np.asarray(s, dtype=float)
    look = np.broadcast_to(np.asarray(look, dtype=float), s.shape)
    path = np.ascontiguousarray(path, dtype=float)
    s_v = np.ascontiguousarray(s_v, dtype=float)
    back = np.ascontiguousarray(back, dtype=float)
    h = hashlib.blake2b(digest_size=20)
    for arr in (path, s_v, back):
        h.update(np.int64(arr.size).tobytes())
        h.update(arr.tobytes())
    h.update(np.float64(reach).tobytes())
    key = h.digest()
    known = _CHORDS_MEMO.get(key)
    if known is None:
        known = _CHORDS_MEMO[key] = {}
        if len(_CHORDS_MEMO) > CHORDS_MEMO_PATHS:
            _CHORDS_MEMO.popitem(last=False)
    else:
        _CHORDS_MEMO.move_to_end(key)
    pairs = np.ascontiguousarray(np.stack([s.ravel(), np.ascontiguousarray(look).ravel()], axis=1))
    # each row's 16 bytes, as row.tobytes() gives them, in one call (a call per row cost more than the lookups)
    names = pairs.view(np.dtype((np.void, pairs.itemsize * 2))).ravel().tolist()
    out = np.fromiter(map(known.get, names, itertools.repeat(math.nan)), dtype=float, count=len(names))
    todo = np.flatnonzero(np.isnan(out))
    if todo.size:
        straight = _on_axis_aligned_straight(path, s_v, pairs[todo, 0], pairs[todo, 1], float(reach))
        out[todo[straight]] = 0.0
        known.update(zip(map(names.__getitem__, todo[straight].tolist()), itertools.repeat(0.0)))
        todo = todo[~straight]
    if todo.size:
        new = np.empty(todo.size)
        px, py = np.ascontiguousarray(path[:, 0]), np.ascontiguousarray(path[:, 1])
        qs, ql = np.ascontiguousarray(pairs[todo, 0]), np.ascontiguousarray(pairs[todo, 1])
        args = (px, py, s_v, qs, ql, float(reach), back, np.linspace(0.0, 1.0, 33), new)
        with np.errstate(divide="ignore", invalid="ignore"):
            # np.interp's slopes, as it computes them (a zero-length segment's is never read)
            slope_x, slope_y = np.diff(px) / np.diff(s_v), np.diff(py) / np.diff(s_v)
        seg = np.diff(s_v) > 0
        plain = (np.isfinite(px).all() and np.isfinite(py).all() and np.isfinite(s_v).all()
                 and bool((np.diff(s_v) >= 0).all()) and np.isfinite(qs).all() and np.isfinite(ql).all()
                 and not np.isnan(slope_x[seg]).any() and not np.isnan(slope_y[seg]).any())
        # chunks of points on the kernel threads; each point's bound is its own
        if plain:
            run_ranges(_chords_kernel, -(-todo.size // _CHORDS_CHUNK), (*args, slope_x, slope_y), min_chunk=8)
        else:  # a NaN on the way: np.interp's own handling of it
            run_ranges(_chords_kernel_interp, -(-todo.size // _CHORDS_CHUNK), args, min_chunk=8)
        out[todo] = new
        known.update(zip(map(names.__getitem__, todo.tolist()), new.tolist(), strict=True))
    return out.reshape(s.shape)


def _on_axis_aligned_straight(path, s_v, s, look, reach: float) -> np.ndarray:
    """Tell which points' chords all lie on one axis-aligned straight of the path, shape of ``s``.

    Every chord of :func:`_chords` at ``(s, look)`` reads the path over ``[s - reach look - look,
    s + look]``. Where every vertex there (those bracketing it too) has the same x, bit for bit,
    and a monotone y, or the same y and a monotone x, that stretch of the polyline is one
    segment of a line parallel to an axis (ends beyond the path clamp to its end vertices, on the
    same line): ``path(q)`` lies between ``path(a)`` and ``path(b)`` for ``a <= q <= b``, so every
    chord's distance, and the bound, is exactly 0. The kernel's arithmetic gives 0 or rounding
    there (up to ~1e-15 m, np.interp's, not the path's): 0 is the bound proven, and no looser.
    """
    s = np.asarray(s, dtype=float)
    look = np.asarray(look, dtype=float)
    ok = np.isfinite(s) & np.isfinite(look)
    # a margin for the rounding of the chords' arc lengths (each within a few ulp of its value)
    pad = 1e-9 * (1.0 + np.abs(s) + np.abs(reach * look) + np.abs(look))
    lo = np.searchsorted(s_v, np.where(ok, s - reach * look - look - pad, 0.0), side="right") - 1
    hi = np.searchsorted(s_v, np.where(ok, s + look + pad, 0.0), side="left")
    lo, hi = np.clip(lo, 0, len(s_v) - 1), np.clip(hi, 0, len(s_v) - 1)
    d = np.diff(path, axis=0)

    def count(flag):  # segments lo <= j < hi with the flag
        c = np.concatenate([[0], np.cumsum(flag)])
        return c[hi] - c[lo]

    along_x = (count(d[:, 1] != 0) == 0) & ((count(d[:, 0] < 0) == 0) | (count(d[:, 0] > 0) == 0))
    along_y = (count(d[:, 0] != 0) == 0) & ((count(d[:, 1] < 0) == 0) | (count(d[:, 1] > 0) == 0))
    return ok & (along_x | along_y) & bool(np.isfinite(path).all())


_CHORDS_CHUNK = 64
"""Points a thread takes at a time (and :func:`_chords_kernel_interp` interpolates the path for)."""


@compiled.njit(inline="always")
def _locate(x, s_v, j):
    # np.interp's segment of x: -1 below the path, len(s_v) beyond it, else the last j with
    # s_v[j] <= x (whatever the search, there is one such j); walked from the guess j, which is
    # near (the chords of one point lie within a few lookaheads), else bisected
    n = s_v.size
    if x > s_v[n - 1]:
        return n
    if x < s_v[0]:
        return -1
    j = min(max(j, 0), n - 1)
    # (a bounded walk written as one loop with a counter compiled 2.5 times slower)
    if s_v[j] > x:
        if j >= 8 and s_v[j - 8] > x:
            return np.searchsorted(s_v, x, side="right") - 1
        while s_v[j] > x:
            j -= 1
        return j
    if j + 9 < n and s_v[j + 9] <= x:
        return np.searchsorted(s_v, x, side="right") - 1
    while j + 1 < n and s_v[j + 1] <= x:
        j += 1
    return j


@compiled.njit(inline="always")
def _value(x, s_v, p, slope, j):
    # np.interp's value at a finite x in segment j (_locate), its cases and arithmetic: with
    # finite vertices and slopes it never takes its NaN fallbacks
    n = s_v.size
    if j == -1:
        return p[0]
    if j >= n - 1:
        return p[n - 1]
    if s_v[j] == x:
        return p[j]
    return slope[j] * (x - s_v[j]) + p[j]


@compiled.njit(cache=True, nogil=True)
def _chords_kernel(c0, c1, px, py, s_v, s, look, reach, back, frac, out, slope_x, slope_y):
    # Thousands of fixes x 25 settle points x 33 chords. The bits of _chords_kernel_interp (the
    # form the identity tables were made with): the same interpolation (np.interp's segment,
    # slope and formula, the slopes passed in as np.interp computes them) and the same chord
    # arithmetic in the same order, without its temporaries and searches. Only the largest
    # distance is kept, so math.hypot is called only for a chord whose squared distance is
    # within 1e-9 (relative) of the largest seen: the others are shorter by more than hypot's
    # error (< 1 ulp) and the squares' rounding (a few ulp) together, so they cannot be the
    # maximum; squares under 1e-280 (underflow) are always taken.
    # Chunks c0 <= c < c1 of _CHORDS_CHUNK points (a thread's share).
    nb, nf = back.size, frac.size
    jq = 0
    for i in range(c0 * _CHORDS_CHUNK, min(c1 * _CHORDS_CHUNK, s.size)):
        si, li = s[i], look[i]
        best = -np.inf
        top = 0.0  # the largest squared distance whose hypot was taken
        for j in range(nb):
            qj = si - reach * li * back[j]
            jq = _locate(qj, s_v, jq)
            xx = _value(qj, s_v, px, slope_x, jq)
            xy = _value(qj, s_v, py, slope_y, jq)
            ja = jq
            jb = jq
            for f in range(nf):
                a = qj - li * frac[f]
                b = a + li
                ja = _locate(a, s_v, ja)
                pax = _value(a, s_v, px, slope_x, ja)
                pay = _value(a, s_v, py, slope_y, ja)
                jb = _locate(b, s_v, jb)
                abx = _value(b, s_v, px, slope_x, jb) - pax
                aby = _value(b, s_v, py, slope_y, jb) - pay
                ab2 = abx * abx + aby * aby
                w = ((xx - pax) * abx + (xy - pay) * aby) / (ab2 if ab2 > 0 else 1.0)
                w = min(max(w, 0.0), 1.0)
                dx = xx - (pax + w * abx)
                dy = xy - (pay + w * aby)
                d2 = dx * dx + dy * dy
                if top > 1e-280 and d2 < top * (1.0 - 1e-9):
                    continue
                best = max(best, math.hypot(dx, dy))
                top = max(top, d2)
        out[i] = best


@compiled.njit(cache=True, nogil=True)
def _chords_kernel_interp(c0, c1, px, py, s_v, s, look, reach, back, frac, out):
    # The reference form of _chords_kernel, with np.interp (and its NaN handling) over a chunk
    # of points at a time; called only where a NaN is about (never on a plan's path).
    nb, nf = back.size, frac.size
    chunk = _CHORDS_CHUNK
    q = np.empty(chunk * nb)
    a = np.empty(chunk * nb * nf)
    b = np.empty(chunk * nb * nf)
    for i0 in range(c0 * chunk, min(c1 * chunk, s.size), chunk):
        n = min(chunk, s.size - i0)
        for i in range(n):
            for j in range(nb):
                qj = s[i0 + i] - reach * look[i0 + i] * back[j]
                q[i * nb + j] = qj
                for f in range(nf):
                    m = (i * nb + j) * nf + f
                    a[m] = qj - look[i0 + i] * frac[f]
                    b[m] = a[m] + look[i0 + i]
        xx, xy = np.interp(q[:n * nb], s_v, px), np.interp(q[:n * nb], s_v, py)
        pax, pay = np.interp(a[:n * nb * nf], s_v, px), np.interp(a[:n * nb * nf], s_v, py)
        abx = np.interp(b[:n * nb * nf], s_v, px) - pax
        aby = np.interp(b[:n * nb * nf], s_v, py) - pay
        for i in range(n):
            best = -np.inf
            for j in range(nb):
                r = i * nb + j
                for f in range(nf):
                    m = r * nf + f
                    ab2 = abx[m] * abx[m] + aby[m] * aby[m]
                    w = ((xx[r] - pax[m]) * abx[m] + (xy[r] - pay[m]) * aby[m]) / (ab2 if ab2 > 0 else 1.0)
                    w = min(max(w, 0.0), 1.0)
                    best = max(best, math.hypot(xx[r] - (pax[m] + w * abx[m]), xy[r] - (pay[m] + w * aby[m])))
            out[i0 + i] = best


def pose_bound(scenario: Scenario, path: np.ndarray, s_v: np.ndarray, speed: np.ndarray,
               s_m: np.ndarray, estimate, still: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Bounds on a fix's true measurement positions and carried travel (module docstring).

    Parameters
    ----------
    scenario : Scenario
    path, s_v, speed : ndarray, shape (N, 2), (N,), (N,)
        Path vertices [m], their arc length [m] and planned speeds [m/s].
    s_m : ndarray, shape (F, k)
        Planned arc length of each measurement [m].
    estimate : float or ndarray, shape (F,)
        Bound on the estimate's error while each fix is taken [m] (module docstring, "Derived
        promise": what the plan certifies there).
    still : ndarray of bool, shape (F,), optional
        Fixes taken at standstill (on the dock before departure): no tracking, lag or travel.

    Returns
    -------
    delta : numpy.ndarray, shape (F, k)
        Bound on ``|true - planned|`` of each measurement position [m].
    travel : numpy.ndarray, shape (F, k)
        Bound on the travel from each measurement to the fix's last [m].
    """
    s_m = np.asarray(s_m, dtype=float)
    k = s_m.shape[-1]
    mt = scenario.sensor.measurement_time
    est = np.broadcast_to(np.asarray(estimate, dtype=float), s_m.shape[:-1])[..., None]
    track = tracking_bound(path, s_v, speed, s_m, turn_bias(scenario.robot))
    v = local_speed(s_v, speed, s_m, speed_reach(s_v, est + track)) + FOLLOWER_MAX_ACCEL * START_LAG
    t_rel = mt * np.arange(1, k + 1)
    delta = track + est + v * START_LAG + 0.5 * FOLLOWER_MAX_ACCEL * t_rel**2
    travel = np.max(v, axis=-1, keepdims=True) * mt * (k - 1 - np.arange(k))
    if still is not None:
        delta[still] = scenario.planning.eps_max
        travel[still] = 0.0
    return delta, travel


def _bounded(scenario: Scenario, markers: np.ndarray, poses: np.ndarray, delta: np.ndarray,
             travel: np.ndarray) -> np.ndarray:
    """:func:`perturbed_diameters` with the scenario's sensor, robot and heading std."""
    return perturbed_diameters(scenario.sensor, scenario.robot, markers, poses, delta, travel,
                               scenario.planning.heading_std)


def _parallelogram(scenario: Scenario, markers: np.ndarray, subsets, poses: np.ndarray, delta: np.ndarray,
                   travel: np.ndarray, where: np.ndarray) -> tuple:
    """Best-order k = 2 promise (C, n) and whether the reversed order won.

    ``poses`` (n, 2, 2), ``delta`` and ``travel`` (n, 2) are the measurement positions and their
    bounds of a fix started at each sample. Only the entries of ``where`` (C, n) are scored (a
    subset not visible over a stretch never takes a fix there); elsewhere the promise is inf
    and ``flipped`` False.
    """
    c, j = np.nonzero(where)
    pairs = np.asarray(subsets, dtype=np.int64)[c]
    fwd = _bounded(scenario, markers[pairs], poses[j], delta[j], travel[j])
    rev = _bounded(scenario, markers[pairs[:, ::-1]], poses[j], delta[j], travel[j])
    tau = np.full(where.shape, np.inf)
    flip = np.zeros(where.shape, dtype=bool)
    tau[c, j] = np.minimum(fwd, rev)
    flip[c, j] = rev < fwd
    return tau, flip


class Levels(Sequence):
    """The speed levels of :func:`levels`: the cruising one at once, the slower ones when first read.

    A schedule's search tries the cruising level alone first and reads the slower ones only
    where it fails, or where a chosen fix's exact promise breaks (a level of thousands of
    candidate fixes costs as much as the cruising one); :meth:`map` edits the levels computed
    and those still to come alike.
    """

    def __init__(self, first: Level, rest: list[Callable[[], Level]] | None = None):
        self._made: list[Level | None] = [first, *([None] * len(rest or []))]
        self._make = [None, *(rest or [])]
        self._edits: list[list[Callable[[Level], Level]]] = [[] for _ in self._made]

    def __len__(self) -> int:
        return len(self._made)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        i = range(len(self))[i]
        got = self._made[i]
        if got is None:
            got = self._make[i]()
            for edit in self._edits[i]:
                got = edit(got)
            self._made[i] = got
        return got

    def map(self, edit: Callable[[Level], Level]) -> Levels:
        """Return the levels with ``edit`` applied to each (now to those computed, later to the others)."""
        out = Levels.__new__(Levels)
        out._made = [None if x is None else edit(x) for x in self._made]
        out._make = self._make
        out._edits = [e if x is not None else [*e, edit] for x, e in zip(self._made, self._edits, strict=True)]
        return out


def levels(scenario: Scenario, subsets, tr: Track, path: np.ndarray, static_tau: np.ndarray, k: int,
           estimate) -> Levels:
    """Promises of every candidate fix at each speed level (module docstring).

    Parameters
    ----------
    scenario : Scenario
    subsets : list of tuple of int
        Candidate marker subsets (C).
    tr : Track
        The path sampled at the planned speeds, with measurement positions (``xy_m``).
    path : ndarray, shape (N, 2)
        The path's vertices [m].
    static_tau : ndarray, shape (C, n)
        Static PEF of each subset over each fix's stretch [m]: inf where not visible.
    k : int
        Markers per fix.
    estimate : float or ndarray, shape (n,)
        Bound on the estimate's error while a fix started at each sample is taken [m].

    Returns
    -------
    Levels
        Cruising speed first (computed); the slower levels are computed when first read. For
        k != 2 only the cruising level, scored by ``static_tau``.
    """
    n = len(tr.s)
    visible = np.isfinite(static_tau)
    if k != 2:
        return Levels(Level(static_tau, np.zeros(static_tau.shape, bool), np.full(n, np.nan)))
    markers = scenario.marker_positions()
    mt = scenario.sensor.measurement_time
    s_path = tr.kin.s_v
    # each sample's bound is its own: only those of samples where some subset is visible are used
    need = visible.any(axis=0)
    still = np.zeros(n, dtype=bool)
    still[0] = True  # the standstill fix before departure
    s_m = tr.kin.s_at(tr.t_start[:, None] + mt * np.arange(1, k + 1))
    s_m[0] = 0.0
    est = np.broadcast_to(np.asarray(estimate, dtype=float), (n,))
    delta, travel = np.full((n, k), np.nan), np.full((n, k), np.nan)
    delta[need], travel[need] = pose_bound(scenario, path, s_path, tr.kin.v, s_m[need], est[need], still[need])
    tau, flip = _parallelogram(scenario, markers, subsets, tr.xy_m, delta, travel, visible)
    first = Level(tau, flip, np.full(n, np.nan))
    v_plan = mean_speed(tr.kin, tr.t_start, k * mt)
    v_plan[0] = 0.0

    def slowed(v, slower):
        def make() -> Level:
            s_m = tr.s[:, None] + v[:, None] * mt * np.arange(1, k + 1)[None, :]
            at = np.stack([np.interp(s_m, s_path, path[:, 0]), np.interp(s_m, s_path, path[:, 1])], axis=-1)
            # the speed profile a slowed fix will get: capped at v over its stretch (slowed_speeds)
            use = need & slower
            delta, travel = np.full((n, k), np.nan), np.full((n, k), np.nan)
            delta[use], travel[use] = _slowed_bound(scenario, path, s_path, s_m[use], v[use], est[use])
            tau, flip = _parallelogram(scenario, markers, subsets, at, delta, travel, visible & slower[None, :])
            return Level(tau, flip, np.where(slower, v, np.nan))
        return make

    rest = []
    for f in (*SPEED_LEVELS[1:], None):
        v = np.full(n, scenario.planning.min_fix_speed) if f is None else f * v_plan
        v = np.maximum(v, scenario.planning.min_fix_speed)
        slower = v < v_plan * (1.0 - 1e-9)
        if not slower.any():
            continue
        rest.append(slowed(v, slower))
    return Levels(first, rest)


def lower_levels(scenario: Scenario, subsets, tr: Track, path: np.ndarray, static_tau: np.ndarray) -> np.ndarray:
    """Return a lower bound on every candidate fix's promise at any of :func:`levels`' speeds (k = 2), (C, n) [m].

    For each measurement order, each speed level's fix of subset c started at sample j (the same
    poses and visibility as :func:`levels`), :func:`perturbed_diameters` gives a parallelogram
    diagonal ``2 / sin w sqrt(h1^2 + h2^2 + 2 h1 h2 |cos w|)`` whose half-widths ``h_i`` are at
    least ``rho(r_i)`` (the range bound at the planned range: every term it adds is >= 0) and
    whose angle ``w`` is at least as far from 90 deg as the planned one ``a`` (so ``sin w <= sin a
    = |u1 x u2|``): the promise is at least ``2 sqrt(rho(r1)^2 + rho(r2)^2) / |u1 x u2|``, here
    taken 1e-9 smaller against rounding, 0 where the markers' directions are parallel. The
    smallest over the levels and both orders is returned (inf where the subset is not visible).

    The pose bound, the odometry shift and the ball iteration are not computed: a tenth of the
    cost. :func:`planner.schedule.schedule.make_schedule` proves with it that a bound has no
    schedule at the planned speed without computing the promises.
    """
    n = len(tr.s)
    k = 2
    visible = np.isfinite(static_tau)
    markers = scenario.marker_positions()
    mt = scenario.sensor.measurement_time
    s_path = tr.kin.s_v
    pairs = np.asarray(subsets, dtype=np.int64)
    out = np.full(visible.shape, np.inf)
    v_plan = mean_speed(tr.kin, tr.t_start, k * mt)
    v_plan[0] = 0.0
    todo = [(tr.xy_m, visible)]
    for f in (*SPEED_LEVELS[1:], None):   # the slower levels of :func:`levels`, the same poses
        v = np.full(n, scenario.planning.min_fix_speed) if f is None else f * v_plan
        v = np.maximum(v, scenario.planning.min_fix_speed)
        slower = v < v_plan * (1.0 - 1e-9)
        if not slower.any():
            continue
        s_m = tr.s[:, None] + v[:, None] * mt * np.arange(1, k + 1)[None, :]
        at = np.stack([np.interp(s_m, s_path, path[:, 0]), np.interp(s_m, s_path, path[:, 1])], axis=-1)
        todo.append((at, visible & slower[None, :]))
    for poses, where in todo:
        c, j = np.nonzero(where)
        for order in (pairs[c], pairs[c, ::-1]):
            v = poses[j] - markers[order]                                     # (E, 2, 2)
            r = np.hypot(v[..., 0], v[..., 1])
            u = v / np.where(r > 0, r, 1.0)[..., None]
            cross = np.abs(u[:, 0, 0] * u[:, 1, 1] - u[:, 0, 1] * u[:, 1, 0])
            rho = scenario.sensor.range_bound(r)
            with np.errstate(divide="ignore"):
                lb = np.where(cross > 0.0, 2.0 * np.sqrt(rho[:, 0] ** 2 + rho[:, 1] ** 2) / cross, 0.0) * (1.0 - 1e-9)
            out[c, j] = np.minimum(out[c, j], lb)
    return out


def _slowed_bound(scenario, path, s_path, s_m, v, estimate):
    """:func:`pose_bound` of fixes driven at no more than ``v`` (n,) over their stretch (``slowed_speeds``)."""
    k = s_m.shape[1]
    mt = scenario.sensor.measurement_time
    t_rel = mt * np.arange(1, k + 1)
    spacing = float(np.max(np.diff(s_path), initial=0.0))
    look = np.maximum(LOOKAHEAD_MIN, LOOKAHEAD_GAIN * v) + spacing
    delta = (settle_bound(path, s_path, s_m, look[:, None] * np.ones((1, k))) + estimate[:, None]
             + (v[:, None] + FOLLOWER_MAX_ACCEL * START_LAG) * START_LAG + 0.5 * FOLLOWER_MAX_ACCEL * t_rel**2)
    travel = (v[:, None] + FOLLOWER_MAX_ACCEL * START_LAG) * mt * (k - 1 - np.arange(k))[None, :]
    return delta, travel


def slowed_speeds(s_v: np.ndarray, speed: np.ndarray, slow: list[tuple[float, float, float]]) -> np.ndarray:
    """Vertex speeds with a cap over each slowed fix's stretch, braking and speeding up at the limit.

    Parameters
    ----------
    s_v : ndarray, shape (N,)
        Arc length of the path vertices [m].
    speed : ndarray, shape (N,)
        Planned vertex speeds [m/s].
    slow : list of (s_start [m], s_end [m], v [m/s])
        Stretches to drive at no more than v. The vertices bracketing a stretch are capped, so
        the constant-acceleration speed between them stays under the cap.

    Returns
    -------
    numpy.ndarray, shape (N,)
        New vertex speeds [m/s].
    """
    if not slow:
        return np.asarray(speed, dtype=float)
    cap = np.array(speed, dtype=float)
    for a, b, v in slow:
        lo = max(int(np.searchsorted(s_v, a, side="right")) - 1, 0)
        hi = min(int(np.searchsorted(s_v, b, side="left")), len(s_v) - 1)
        cap[lo:hi + 1] = np.minimum(cap[lo:hi + 1], v)
    return acceleration_limited(s_v, cap)


def predict(scenario: Scenario, path: np.ndarray, speed: np.ndarray, starts: np.ndarray,
            subsets: list[tuple[int, ...]], estimate) -> tuple[np.ndarray, np.ndarray, Kinematics]:
    """Promise of each chosen fix at the final speed profile (module docstring, "Derived promise").

    Parameters
    ----------
    scenario : Scenario
    path : ndarray, shape (N, 2)
        Path vertices [m].
    speed : ndarray, shape (N,)
        Vertex speeds, slow-downs included [m/s].
    starts : ndarray, shape (F,)
        Arc length where each fix starts [m]; a fix at 0 is taken at standstill.
    subsets : list of tuple of int
        Each fix's markers in measurement order.
    estimate : float or ndarray, shape (F,)
        Bound on the estimate's error while each fix is taken [m]: what the plan certifies there
        (:func:`planner.schedule.schedule.make_schedule` computes it along the schedule).

    Returns
    -------
    predicted_tau : numpy.ndarray, shape (F,)
        Bound on the realised fault-area diameter of each fix over the poses within
        :func:`pose_bound` of the planned ones [m] (inf when none is defined, or when one of its
        markers may be hidden from some of those poses: :mod:`planner.schedule.sightcheck`).
    poses : numpy.ndarray, shape (F, k, 2)
        Planned position at each measurement [m].
    kin : Kinematics
        Arc length against time of ``speed``.
    """
    seg = np.hypot(*np.diff(path, axis=0).T)
    s_v = np.concatenate([[0.0], np.cumsum(seg)])
    speed = np.asarray(speed, dtype=float)
    kin = Kinematics(s_v, speed)
    k = len(subsets[0]) if subsets else 0
    mt = scenario.sensor.measurement_time
    starts = np.asarray(starts, dtype=float)
    t0 = kin.t_at(starts)
    # the fix at s = 0 is taken at standstill before departure (whichever row it is: the
    # fallbacks pass only the fixes that have one)
    still = starts <= 0.0
    markers = scenario.marker_positions()
    s_m = kin.s_at(t0[:, None] + mt * np.arange(1, k + 1)[None, :])
    s_m[still] = 0.0
    poses = np.stack([np.interp(s_m, s_v, path[:, 0]), np.interp(s_m, s_v, path[:, 1])], axis=-1)
    if len(starts) == 0 or k == 0:
        return np.full(len(starts), np.inf), poses, kin
    est = np.broadcast_to(np.asarray(estimate, dtype=float), starts.shape)
    delta, travel = pose_bound(scenario, path, s_v, speed, s_m, est, still)
    pred = _bounded(scenario, markers[np.asarray(subsets)], poses, delta, travel)
    # a marker the laser may lose within the pose bound: the promise is not one the plan keeps
    pred[unseen(scenario, subsets, poses, delta)] = np.inf
    return pred, poses, kin


def moving_map(scenario: Scenario, pef, speed: float, resolution: float | None = None):
    """Compute the motion-aware PEF on a grid: the promise of a fix ending at each cell at ``speed``.

    Each cell is the end of a two-marker fix driven at constant ``speed`` [m/s]: the first
    range is taken ``measurement_time`` earlier, ``speed * measurement_time`` back, and carried
    to the cell with the odometry bound (:func:`estimators.fault.carried.shift_bound`, heading std
    ``planning.heading_std_deg``). The map takes the marker directions at the cell for both
    ranges (the robot moves a few centimetres during a fix, metres from the markers: the
    direction changes by less than that ratio, whatever way it drives), the better of the two
    measurement orders, and the best visible pair, the static map's candidate pairs when there
    are more than :data:`MAX_SUBSETS`.

    Parameters
    ----------
    scenario : Scenario
        Needs ``markers_per_fix = 2``.
    pef : planner.pef.map.PEF
        The static PEF (visibility, free cells, candidate pairs).
    speed : float
        Driving speed during the fix [m/s], >= 0 (0: a fix at standstill, whose first range
        still carries the encoders' sub-tick uncertainty).
    resolution : float, optional
        Cell size [m]; default ``planning.resolution``.

    Returns
    -------
    planner.pef.result.PefMap
        ``tau`` the motion-aware promise [m] (inf where fewer than 2 markers are visible),
        ``best`` the pair in measurement order.
    """
    import math
    from dataclasses import replace

    from estimators.fault.carried import shift_bound
    from scenarios.errors import PlanningError

    if scenario.sensor.markers_per_fix != 2:
        raise PlanningError(f"speed: the motion-aware map needs markers_per_fix = 2, got "
                            f"{scenario.sensor.markers_per_fix}")
    if not (speed >= 0.0 and math.isfinite(speed)):
        raise PlanningError(f"speed: expected a speed >= 0 m/s, got {speed}")
    static = pef.grid(resolution)
    xx, yy = np.meshgrid(static.x, static.y)
    xy = np.column_stack([xx.ravel(), yy.ravel()])
    vis = pef.visible(xy)
    markers = scenario.marker_positions()
    if len(markers) * (len(markers) - 1) // 2 <= MAX_SUBSETS:
        pairs = [(i, j) for i in range(len(markers)) for j in range(i + 1, len(markers))]
    else:
        b = static.best.reshape(-1, 2)
        pairs = [tuple(map(int, p)) for p in np.unique(np.sort(b[(b >= 0).all(axis=1)], axis=1), axis=0)]
    d = xy[:, None, :] - markers[None, :, :]
    r = np.hypot(d[..., 0], d[..., 1])
    u = d / np.where(r > 0, r, 1.0)[..., None]
    rho = scenario.sensor.range_bound(r)
    margin = float(shift_bound(scenario.robot, np.array([speed * scenario.sensor.measurement_time]),
                               scenario.planning.heading_std)[0])
    tau = np.full(len(xy), np.inf)
    best = np.full((len(xy), 2), -1, dtype=np.int64)
    for i, j in pairs:
        ok = vis[:, i] & vis[:, j]
        if not ok.any():
            continue
        sin_a = np.abs(u[:, i, 0] * u[:, j, 1] - u[:, i, 1] * u[:, j, 0])
        cos_a = np.abs(u[:, i, 0] * u[:, j, 0] + u[:, i, 1] * u[:, j, 1])
        for first, second in ((i, j), (j, i)):
            a, b2 = rho[:, first] + margin, rho[:, second]
            with np.errstate(divide="ignore", invalid="ignore"):
                t = 2.0 / sin_a * np.sqrt(a * a + b2 * b2 + 2.0 * a * b2 * cos_a)
            t = np.where(ok & (sin_a > 1e-12), t, np.inf)
            win = t < tau
            tau[win] = t[win]
            best[win] = (first, second)
    shape = static.tau.shape
    tau = np.where(static.free.ravel(), tau, np.inf).reshape(shape)
    return replace(static, tau=tau, best=best.reshape(*shape, 2), speed=float(speed))
