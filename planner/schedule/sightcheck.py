"""Whether a fix's lines of sight hold at every pose its promise covers.

The PEF judges visibility with the margin of :func:`planner.pef.sight.sight_rule`, the smallest
pose bound the plan can certify; the schedule's search (:func:`seen_within`) counts a subset at a
sample only where it stays in sight within the pose bound the search assumes there. A fix's
promise, however, covers every true measurement position within its own pose bound ``Δ_i``
(:func:`planner.schedule.promise.pose_bound`: tracking error, the estimate's certified error, the
start lag, the speed), and in a corner or after a weak fix ``Δ_i`` can exceed that margin. Where
the laser may lose a marker somewhere within ``Δ_i``, the robot measures another subset (or
dead-reckons on) and the promise is not one the plan can keep. So a scheduled measurement counts
on its marker only when :func:`planner.pef.visibility.visible_points` sees it under
``SightRule(margin=Δ_i)`` (every obstacle grown by the physics ray's reach, the marker's mount
and incidence wedges, the range shortened, all held at every point within ``Δ_i``; every other
reflector's body blocks, as in the simulation). A fix with a marker that fails this has no promise
(:func:`planner.schedule.promise.predict` returns inf), and the schedule searches again without
that subset there.

Margins are rounded up to :data:`MARGIN_STEP`, so that the sight arrays are prepared once per
step and scenario rather than once per fix (a plan asks for some twenty steps, hundreds of
times); rounding up only makes the check stricter.
"""

from __future__ import annotations

import weakref

import numpy as np

from planner.pef.sight import SightRule
from planner.pef.visibility import visible_pairs, visible_points
from scenarios.schema import Scenario

MARGIN_STEP = 0.005
"""Granularity of the margins checked [m]: each pose bound is rounded up to a multiple of it."""


def unseen(scenario: Scenario, subsets, poses: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """Tell which fixes have a marker that may be hidden from some pose within their bound.

    Parameters
    ----------
    scenario : Scenario
        Its markers (kinds too), obstacles and declared sensor.
    subsets : array_like of int, shape (F, k)
        Each fix's markers, in measurement order (indices into ``scenario.markers``).
    poses : ndarray, shape (F, k, 2)
        Planned position of each measurement [m].
    delta : ndarray, shape (F, k)
        Bound on ``|true - planned|`` of each measurement position [m].

    Returns
    -------
    numpy.ndarray of bool, shape (F,)
        True where some measurement's marker is not seen under ``SightRule(margin=delta)``
        (also where ``delta`` is not finite).
    """
    sub = np.asarray(subsets, dtype=np.int64)
    f_n = sub.shape[0]
    out = np.zeros(f_n, dtype=bool)
    if f_n == 0 or sub.ndim != 2 or sub.shape[1] == 0:
        return out
    p = np.asarray(poses, dtype=float).reshape(f_n, sub.shape[1], 2)
    d = np.asarray(delta, dtype=float).reshape(f_n, sub.shape[1])
    finite = np.isfinite(d)
    out |= ~finite.all(axis=1)
    steps = np.where(finite, np.ceil(np.where(finite, d, 0.0) / MARGIN_STEP - 1e-9), -1).astype(np.int64)
    markers = scenario.marker_positions()
    normals = scenario.marker_normals()
    pieces = scenario.obstacle_pieces()
    sensor = scenario.sensor
    for step in np.unique(steps[steps >= 0]).tolist():
        rows, cols = np.nonzero(steps == step)
        rule = SightRule(margin=max(step, 0) * MARGIN_STEP)
        # every marker's sight arrays (the same for every call at this margin, prepared once:
        # planner.pef.visibility.prepare_sight keeps them), each point tested on its own marker only
        seen = visible_pairs(p[rows, cols], sub[rows, cols], markers, pieces, sensor.max_range,
                             scenario.workspace.bounds, normals, sensor.max_incidence, rule)
        out[rows[~seen]] = True
    return out



def seen_within(scenario: Scenario, points: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """Which markers stay in the laser's sight from every position within ``delta`` of each point.

    Parameters
    ----------
    scenario : Scenario
        Its markers, obstacles and declared sensor.
    points : ndarray, shape (N, 2)
        Planned positions [m].
    delta : ndarray, shape (N,)
        Bound on ``|true - planned|`` at each point [m], rounded up to :data:`MARGIN_STEP`.

    Returns
    -------
    numpy.ndarray of bool, shape (N, M)
        True where marker ``m`` is seen under ``SightRule(margin=delta)`` (False where ``delta``
        is not finite).
    """
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    d = np.asarray(delta, dtype=float).reshape(-1)
    markers = scenario.marker_positions()
    out = np.zeros((len(p), len(markers)), dtype=bool)
    finite = np.isfinite(d)
    steps = np.where(finite, np.ceil(np.where(finite, d, 0.0) / MARGIN_STEP - 1e-9), -1).astype(np.int64)
    normals = scenario.marker_normals()
    pieces = scenario.obstacle_pieces()
    sensor = scenario.sensor
    # a point's row depends on the point, its margin and the scenario's sight alone: rows are
    # remembered, and only points not asked before at their margin are tested (a schedule's
    # slow-down attempts ask again for every sample before the stretch they slowed)
    layouts = _SEEN.setdefault(pieces, {})
    key = (markers.tobytes(), normals.tobytes(), tuple(float(b) for b in scenario.workspace.bounds),
           float(sensor.max_range), float(sensor.max_incidence))
    memo = layouts.pop(key, None)
    if memo is None or len(memo) > _SEEN_KEPT:
        memo = {}
    layouts[key] = memo  # the most recent last; placement's earlier layouts go first
    while len(layouts) > _SEEN_LAYOUTS:
        layouts.pop(next(iter(layouts)))
    p = np.ascontiguousarray(p)
    names = p.view(np.dtype((np.void, p.itemsize * 2))).ravel().tolist()
    for step in np.unique(steps[steps >= 0]).tolist():
        rows = np.flatnonzero(steps == step)
        known = [memo.get((step, names[r])) for r in rows.tolist()]
        todo = np.array([i for i, row in enumerate(known) if row is None], dtype=np.int64)
        if todo.size:
            rule = SightRule(margin=max(step, 0) * MARGIN_STEP)
            vis, _ = visible_points(p[rows[todo]], markers, pieces, sensor.max_range, scenario.workspace.bounds,
                                    normals, sensor.max_incidence, rule)
            for i, col in zip(todo.tolist(), np.ascontiguousarray(vis.T), strict=True):
                known[i] = memo[(step, names[rows[i]])] = col
        out[rows] = np.stack(known) if known else out[rows]
    return out


#: Rows of :func:`seen_within` kept per set of obstacles and sight inputs, by point and margin step.
_SEEN: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
#: Rows kept for one layout's sight before they are forgotten at once (a row is M bytes).
_SEEN_KEPT = 200_000
#: Layouts (markers, sensor) kept per set of obstacles: placement plans one layout after another.
_SEEN_LAYOUTS = 2
