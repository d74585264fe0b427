"""The promise of a moving fix, for the measurement schedule.

A fix started at arc length ``s_j`` measures its k markers one after another, the m-th
``(m + 1) * measurement_time`` after the start, while the robot drives on; the earlier ranges
are carried to the last one by odometry (:mod:`estimators.fault.carried`). The fix's promise,
``predicted_tau``, is the diameter of the fault area of that construction on noise-free
ranges at the planned positions: :func:`estimators.fault.carried.promised_fault_area`, the code the
simulation uses for the realised fault area.

The schedule searches over thousands of candidate starts, so it scores them with the
construction's parallelogram (:func:`estimators.fault.carried.promised_parallelogram_best`, k = 2;
for other k the static PEF of the stretch), and :func:`predict` then computes the exact
promise of the fixes it chose.

Slowing down for a fix
    The shift of an earlier range grows with speed, so a fix that breaks its promise at
    cruising speed may keep it slower. :data:`SPEED_LEVELS` are the speeds tried (fractions of
    the planned speed, then ``planning.min_fix_speed``); :func:`slowed_speeds` caps the path's
    vertex speeds over the fix's stretch and lets the robot brake and speed up again at the
    planner's acceleration limit. A fix that breaks its promise even at the minimum speed is
    not usable.

Promise tolerance
    The realised area differs from the promise through noise (the annuli move by the range
    errors, the arcs' curvature changes the corners) and the robot being a little off its
    planned pose and speed: :data:`PROMISE_TOLERANCE` (2 %). A fix is usable when its promise,
    times ``1 + PROMISE_TOLERANCE``, is under ``eps_max``, so that the realised area is too.

Start lag
    The robot starts a fix at its first control tick past the planned start, and takes each
    range at the first physics step it falls due: up to :data:`START_LAG` later than planned.
    Where the promise changes fast along the path (two markers a metre away on either side:
    the angle between them changes by degrees per centimetre), those 2 cm of travel move the
    realised area by more than the tolerance (a fallback fix of ``warehouse-reflectors``
    realised 1.037x its promise at the planned poses). :func:`predict` therefore promises the
    largest fault area over starts :data:`START_LAGS` after the planned one.

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

from dataclasses import dataclass

import numpy as np

from estimators.fault.carried import promised_diameters, promised_parallelogram_best
from planner.routes.smoothing import acceleration_limited
from planner.schedule.pathtime import Kinematics, Track, positions_at
from scenarios.schema import Scenario

SPEED_LEVELS = (1.0, 0.5, 0.25)
"""Fractions of the planned speed tried for a fix, before ``planning.min_fix_speed``."""
MAX_SUBSETS = 400
"""Above this many k-subsets of path-visible markers, only the PEF's pointwise-best subsets
along the path are considered (cost: one ``tau_subset`` call per subset)."""
PROMISE_TOLERANCE = 0.02
"""Relative excess of a realised fault-area diameter over its promise the validation allows."""
START_LAG = 1.0 / 48.0
"""Latest a fix may start after its planned time [s]: one control period and one physics step
(the simulation's 60 Hz control at 240 Hz physics; ``sim.episode.drive`` checks its own)."""
START_LAGS = (0.0, 0.5 * START_LAG, START_LAG)
"""Start delays [s] over which :func:`predict` takes the largest promise."""


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


def _parallelogram(scenario: Scenario, markers: np.ndarray, subsets, poses: list[np.ndarray],
                   where: np.ndarray) -> tuple:
    """Best-order k = 2 promise (C, n) and whether the reversed order won.

    ``poses`` lists the measurement positions (n, 2, 2) of each start lag scored; each order's
    promise is its largest over them. Only the entries of ``where`` (C, n) are scored (a subset
    not visible over a stretch never takes a fix there); elsewhere the promise is inf and
    ``flipped`` False.
    """
    c, j = np.nonzero(where)
    sens, rob, hs = scenario.sensor, scenario.robot, scenario.planning.heading_std
    pairs = np.asarray(subsets, dtype=np.int64)
    best, flipped = promised_parallelogram_best(sens, rob, markers, pairs, np.stack(poses), c, j, hs)
    tau = np.full(where.shape, np.inf)
    flip = np.zeros(where.shape, dtype=bool)
    tau[c, j] = best
    flip[c, j] = flipped
    return tau, flip


def levels(scenario: Scenario, subsets, tr: Track, path: np.ndarray, static_tau: np.ndarray, k: int) -> list[Level]:
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

    Returns
    -------
    list of Level
        Cruising speed first; for k != 2 only that level, scored by ``static_tau``.
    """
    n = len(tr.s)
    visible = np.isfinite(static_tau)
    if k != 2:
        return [Level(static_tau, np.zeros(static_tau.shape, bool), np.full(n, np.nan))]
    markers = scenario.marker_positions()
    out = []
    mt = scenario.sensor.measurement_time
    # scored at the planned start and START_LAG later (predict's extremes)
    late = positions_at(tr.kin, tr.kin.s_v, path, tr.t_start[:, None] + START_LAG + mt * np.arange(1, k + 1))
    late[0] = path[0]  # the standstill fix before departure does not lag
    tau, flip = _parallelogram(scenario, markers, subsets, [tr.xy_m, late], visible)
    out.append(Level(tau, flip, np.full(n, np.nan)))
    v_plan = np.diff(tr.kin.s_at(tr.t_start[:, None] + np.array([0.0, k * mt])), axis=1)[:, 0] / (k * mt)
    v_plan[0] = 0.0
    s_path = tr.kin.s_v
    for f in (*SPEED_LEVELS[1:], None):
        v = np.full(n, scenario.planning.min_fix_speed) if f is None else f * v_plan
        v = np.maximum(v, scenario.planning.min_fix_speed)
        slower = v < v_plan * (1.0 - 1e-9)
        if not slower.any():
            continue
        at = []
        for lag in (0.0, START_LAG):
            s_m = tr.s[:, None] + v[:, None] * (lag + mt * np.arange(1, k + 1)[None, :])
            at.append(np.stack([np.interp(s_m, s_path, path[:, 0]), np.interp(s_m, s_path, path[:, 1])], axis=-1))
        tau, flip = _parallelogram(scenario, markers, subsets, at, visible & slower[None, :])
        out.append(Level(tau, flip, np.where(slower, v, np.nan)))
    return out


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
            subsets: list[tuple[int, ...]]) -> tuple[np.ndarray, np.ndarray, Kinematics]:
    """Exact promise of each chosen fix at the final speed profile.

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

    Returns
    -------
    predicted_tau : numpy.ndarray, shape (F,)
        Largest fault-area diameter of each fix's construction over starts :data:`START_LAGS`
        late [m] (inf when empty or not defined).
    poses : numpy.ndarray, shape (F, k, 2)
        Planned position at each measurement (no lag) [m].
    kin : Kinematics
        Arc length against time of ``speed``.
    """
    seg = np.hypot(*np.diff(path, axis=0).T)
    s_v = np.concatenate([[0.0], np.cumsum(seg)])
    kin = Kinematics(s_v, np.asarray(speed, dtype=float))
    k = len(subsets[0]) if subsets else 0
    mt = scenario.sensor.measurement_time
    starts = np.asarray(starts, dtype=float)
    t0 = kin.t_at(starts)
    # the fix at s = 0 is taken at standstill before departure (whichever row it is: the
    # fallbacks pass only the fixes that have one)
    still = starts <= 0.0
    markers = scenario.marker_positions()
    out = np.full(len(starts), -np.inf)
    for n, lag in enumerate(START_LAGS):
        s_m = kin.s_at(t0[:, None] + lag + mt * np.arange(1, k + 1)[None, :])
        s_m[still] = 0.0
        at = np.stack([np.interp(s_m, s_v, path[:, 0]), np.interp(s_m, s_v, path[:, 1])], axis=-1)
        if n == 0:
            poses = at
        # a standstill fix does not lag; an empty area stays none
        rows = np.arange(len(subsets)) if n == 0 else np.flatnonzero(~still & np.isfinite(out))
        if rows.size == 0:
            continue
        diameter, empty = promised_diameters(scenario.sensor, scenario.robot, markers[np.asarray(subsets)[rows]],
                                             at[rows], scenario.planning.heading_std)
        for i, d, e in zip(rows.tolist(), diameter.tolist(), empty.tolist(), strict=True):
            out[i] = max(out[i], d) if not e else np.inf
    return np.where(out == -np.inf, np.inf, out), poses, kin


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
        raise PlanningError(f"--speed: the motion-aware map needs markers_per_fix = 2, got "
                            f"{scenario.sensor.markers_per_fix}")
    if not (speed >= 0.0 and math.isfinite(speed)):
        raise PlanningError(f"--speed: expected a speed >= 0 m/s, got {speed}")
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
    return replace(static, tau=tau, best=best.reshape(*shape, 2))
