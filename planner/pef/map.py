"""The Position Error Function: predicted position error tau at points and on grids.

``tau(p)`` is the error of the best visible subset of k markers at ``p`` under a model
(`docs/design.md` §1), computed from the *declared* sensor (``scenario.sensor``):

- ``parallelogram`` (k = 2, ranges only): long diagonal of the linearised parallelogram;
- ``strips``: diameter of the intersection of the linearised strips of the subset, with the
  tangential bearing strips when the sensor measures bearings;
- ``gdop``: major axis (diameter) of the ``planning.gdop_level`` confidence ellipse of the
  least-squares fix with ``sigma = rho / 3`` (:mod:`estimators.fault.linearized`), bearings included
  as tangential rows. Every model reports a diameter (the paper's d), so eps_max means the same
  under each; they agree where their assumptions overlap (``tests/planner/pef/test_models_agree.py``);
- ``exact``: diameter of the exact fault area of noise-free measurements
  (:func:`estimators.fault.exact.fault_area_of_point`, polygon clipping). It is slow (a
  polygon clipping per point and subset): use it on points and coarse grids. To keep it
  tractable only the subsets whose linearised (strips) diameter is within a factor
  ``exact_margin`` of the best linearised one are clipped; with the default 1.5 this finds the
  exact minimum whenever the linearisation is within 20 % of the exact diameter for every
  subset ((1 + 0.2) / (1 - 0.2) = 1.5), true far beyond the paper's Re < 1 % regime.
  ``exact_margin=inf`` clips every subset.

``tau`` is inf where fewer than k markers are visible, outside the workspace and inside
obstacles.

Redundancy (``planning.redundancy`` = r): ``tau_r(p)`` is the largest, over every set of r
visible markers removed, of the best-subset tau. Removing a marker outside the best subset
leaves tau unchanged and removing markers never lowers it, so only the best subset's members
matter: ``tau_r(vis) = max over members j of best(vis) of tau_{r-1}(vis without j)``, exact,
at k^r evaluations of the plain PEF (3 for k = 2, r = 1, on the same visibility) instead of
C(M, r). The best subset without member j is that member's *fallback* (:attr:`PefResult.fallback`).

Points and grids go through the same kernels (:mod:`planner.pef.kernels`); a grid is its
cell centres (the parallelogram kernel walks a grid in tiles, for its pair pruning,
with the same values as on the points). The kernels rank candidate subsets in float32 and
recompute the winner's tau in float64: tau is exact for the chosen subset and within ~1e-6
relative of the minimum. Speed and the one-off numba compilation (kernels are compiled per model on first use
in a fresh checkout, then loaded from the on-disk cache) are measured by
``benchmarks/pef_map.py``.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import numpy as np

from estimators.fault.linearized import chi2_2dof_ppf
from planner.pef import kernels as pef_kernels
from planner.pef import stretch as pef_stretch
from planner.pef.gridtiles import parallelogram_grid
from planner.pef.pointmemo import PointMemo, point_keys
from planner.pef.result import PefMap, PefResult, grid_centres
from planner.pef.subsetvalues import SubsetValues
from planner.pef.visibility import scenario_sight_rule, scenario_visible_grid, scenario_visible_points, visible_points
from scenarios.errors import PlanningError
from scenarios.schema import PefModel, Scenario

#: Default factor for the ``exact`` model's candidate subsets (see the module docstring).
EXACT_MARGIN = 1.5
#: Most marker subsets a PEF scores per point (C(M, k)); the list alone takes 8 k bytes each.
MAX_SUBSETS = 2_000_000

_KERNEL_MODEL = {PefModel.PARALLELOGRAM: pef_kernels.PARALLELOGRAM, PefModel.STRIPS: pef_kernels.STRIPS,
                 PefModel.GDOP: pef_kernels.GDOP}


class PEF:
    """The position error function of a scenario.

    Parameters
    ----------
    scenario : Scenario
        Workspace, obstacles, markers and the declared sensor.
    model : PefModel or str, optional
        Error model; default ``scenario.planning.pef_model``.
    k : int, optional
        Markers per fix; default ``scenario.sensor.markers_per_fix``.
    exact_margin : float
        Candidate factor of the ``exact`` model (see the module docstring).
    redundancy : int, optional
        r, markers that may be blocked (tau_r); default ``scenario.planning.redundancy``.
    sight : bool
        Count a marker only where the plan's line-of-sight rule does (:mod:`planner.pef.sight`,
        the default); False gives the margin-free geometry of the scenario's shapes alone.
    """

    def __init__(self, scenario: Scenario, model: PefModel | str | None = None, k: int | None = None,
                 exact_margin: float = EXACT_MARGIN, redundancy: int | None = None, sight: bool = True):
        self.scenario = scenario
        self.sight = bool(sight)
        self.rule = scenario_sight_rule(scenario) if self.sight else None
        self.sensor = scenario.sensor
        try:
            self.model = PefModel(model) if model is not None else scenario.planning.pef_model
        except ValueError:
            choices = ", ".join(m.value for m in PefModel)
            raise PlanningError(f"model: expected one of {choices}, got {model!r}") from None
        self.k = int(k) if k is not None else scenario.sensor.markers_per_fix
        if self.k < 1:
            raise PlanningError(f"k: expected at least 1 marker per fix, got {self.k}")
        if self.model is PefModel.PARALLELOGRAM and self.k != 2:
            raise PlanningError(f"k: the parallelogram model needs k = 2, got {self.k} (use strips or gdop)")
        if not exact_margin >= 1.0:
            raise PlanningError(f"exact_margin: expected >= 1, got {exact_margin}")
        self.exact_margin = float(exact_margin)
        self.redundancy = int(redundancy) if redundancy is not None else scenario.planning.redundancy
        if self.redundancy < 0:
            raise PlanningError(f"redundancy: expected a number of markers >= 0, got {self.redundancy}")
        self.markers = scenario.marker_positions()
        n = len(self.markers)
        if n >= self.k and math.comb(n, self.k) > MAX_SUBSETS:
            raise PlanningError(f"sensor.markers_per_fix: {self.k} of {n} markers gives {math.comb(n, self.k):.3g} "
                                f"subsets to score at every point (at most {MAX_SUBSETS:.0e}); use fewer per fix")
        if self.k == 2:  # the same lexicographic order as combinations, without 40k Python tuples
            self.subsets = np.column_stack(np.triu_indices(n, 1)).astype(np.int64).reshape(-1, 2)
        else:
            combos = list(itertools.combinations(range(n), self.k)) if n >= self.k else []
            self.subsets = np.array(combos, dtype=np.int64).reshape(len(combos), self.k)
        self.chi2_ppf = chi2_2dof_ppf(scenario.planning.gdop_level)

    # --- visibility ---------------------------------------------------------------------------

    def visible(self, points: np.ndarray, widen: float = 0.0) -> np.ndarray:
        """Markers visible from points (range and line of sight), shape (N, M) bool.

        Parameters
        ----------
        points : ndarray, shape (N, 2)
            Points [m]; rows all False where a point is not free.
        widen : float
            A marker counts only when it is seen from every position within this distance of
            the point too [m] (:func:`planner.pef.visibility.scenario_visible_points`).
        """
        return self._visibility(_points(points), widen).T

    def _visibility(self, pts: np.ndarray, widen: float) -> np.ndarray:
        """``scenario_visible_points(...)[0]`` (M, N), a copy; the last points asked are remembered.

        A schedule asks :meth:`visible` and then :meth:`at` of the same samples.
        """
        key = (pts.tobytes(), pts.shape, float(widen), self.sight, id(self.scenario))
        last = getattr(self, "_vis_last", None)
        if last is None or last[0] != key:
            vis, _ = scenario_visible_points(self.scenario, pts, self.sight, widen)
            last = self._vis_last = (key, vis)
        return last[1].copy()

    # --- evaluation ---------------------------------------------------------------------------

    def at(self, points: np.ndarray, widen: float = 0.0) -> PefResult:
        """Evaluate the PEF at arbitrary points.

        Parameters
        ----------
        points : ndarray, shape (N, 2)
            Points [m].
        widen : float
            Count a marker only when it is seen from every position within this distance of
            the point too [m] (:mod:`planner.routes.admissible`: a path's samples stand for
            the stretches between them).

        Returns
        -------
        PefResult
            ``tau`` (N,) [m] (tau_r), ``best`` (N, k) marker indices, and with r >= 1 the
            fallback subsets.
        """
        pts = _points(points)
        # each point's value is its own: a point asked again, in this call or an earlier one (the
        # schedule samples a path again for each rung and slow-down attempt), is not evaluated again
        memo = self._memo("at", widen)

        def compute(first: np.ndarray) -> list[np.ndarray]:
            r = self._at_points(pts[first], widen)
            return [r.tau, r.best, r.tau_plain, r.fallback]

        tau, best, tau_plain, fallback = memo.rows(memo.held(point_keys(pts), compute))
        return PefResult(tau=tau, best=best, tau_plain=tau_plain, fallback=fallback)

    def stretch_bound(self, points: np.ndarray, widen: float, target: float = math.inf) -> np.ndarray:
        """Bound tau over the stretch within ``widen`` of each point (:mod:`planner.pef.stretch`).

        Parameters
        ----------
        points : ndarray, shape (N, 2)
            Points [m].
        widen : float
            The stretch's half-length [m]: markers count only when seen from all of it.
        target : float
            Where the bound of the best subset (by tau) reaches ``target`` [m] but its tau does
            not, every visible subset is tried (the least ``g_S tau_S``): the bound is then under
            ``target`` exactly when some subset keeps the whole stretch under it. Elsewhere the
            best subset's bound.

        Returns
        -------
        ndarray, shape (N,)
            The bound [m] (tau_r with redundancy r: the worst of the bounds with any r markers
            blocked); inf where no subset is seen over the stretch.
        """
        pts = _points(points)
        memo = self._memo(f"stretch {float(target)!r}", widen)

        def compute(first: np.ndarray) -> list[np.ndarray]:
            return [self._stretch_points(pts[first], float(widen), float(target))]

        (bound,) = memo.rows(memo.held(point_keys(pts), compute))
        return bound

    def _stretch_points(self, pts: np.ndarray, h: float, target: float) -> np.ndarray:
        """:meth:`stretch_bound` of ``pts`` (N, 2), without the memo."""
        px, py = np.ascontiguousarray(pts[:, 0]), np.ascontiguousarray(pts[:, 1])
        if self.redundancy == 0:  # the plain values are held by at()
            r = self.at(pts, h)
            return self._stretched(px, py, PefResult(tau=r.tau, best=r.best), h, target,
                                   lambda: self._visibility(pts, h)).tau
        vis = self._visibility(pts, h)
        # the recursion over blocked markers takes the subset each bound comes from
        return self._redundant(lambda v: self._stretched(px, py, self._evaluate(px, py, v), h, target, lambda: v),
                               vis).tau

    def _stretched(self, px: np.ndarray, py: np.ndarray, plain: PefResult, h: float, target: float,
                   vis_of) -> PefResult:
        """Return the best subset's bound over the stretch, and the least of every subset's where it decides.

        ``plain``: tau (N,) and best (N, k) at (px, py); ``vis_of()``: the visibility (M, N).
        """
        sensor = self.sensor
        tan_xi = math.tan(sensor.bearing_error) if sensor.uses_bearing else 0.0
        exact = self.model is PefModel.EXACT
        code = pef_kernels.STRIPS if exact else _KERNEL_MODEL[self.model]
        mx, my = np.ascontiguousarray(self.markers[:, 0]), np.ascontiguousarray(self.markers[:, 1])
        g = np.empty(px.size)
        pef_stretch.best_stretch(code, px, py, mx, my, np.ascontiguousarray(plain.best), float(sensor.relative_error),
                                 float(sensor.absolute_error), tan_xi, self.chi2_ppf, h,
                                 np.ascontiguousarray(plain.tau, dtype=float), not exact, g)
        bound = plain.tau * g
        best = plain.best.copy()
        band = np.flatnonzero((plain.tau < target) & ~(bound < target))
        if band.size and len(self.subsets):
            vis = np.ascontiguousarray(vis_of()[:, band])
            bx, by = np.ascontiguousarray(px[band]), np.ascontiguousarray(py[band])
            if exact:
                least, sub = self._exact_stretched(bx, by, vis, h)
            else:
                least, sub = np.empty(band.size), np.empty((band.size, self.k), dtype=np.int64)
                pef_stretch.min_stretched(code, bx, by, mx, my, vis, self.subsets, float(sensor.relative_error),
                                          float(sensor.absolute_error), tan_xi, self.chi2_ppf, h, least, sub)
            better = least < bound[band]
            bound[band[better]] = least[better]
            best[band[better]] = sub[better]
        return PefResult(tau=bound, best=best)

    def _exact_stretched(self, px: np.ndarray, py: np.ndarray, vis: np.ndarray, h: float):
        """Return the least ``g_S tau_S`` (N,) of the exact model and its subsets (N, k), over its candidates."""
        n, nsub = px.size, len(self.subsets)
        cand = self._exact_candidates(px, py, vis)
        pts = np.column_stack([px, py])
        ids = self._exact_ids(pts)
        self._exact_values()
        sensor = self.sensor
        tan_xi = math.tan(sensor.bearing_error) if sensor.uses_bearing else 0.0
        mx, my = np.ascontiguousarray(self.markers[:, 0]), np.ascontiguousarray(self.markers[:, 1])
        least, best = np.full(n, np.inf), np.full((n, self.k), -1, dtype=np.int64)
        for s in range(nsub):
            rows = np.flatnonzero(cand[:, s] & vis[self.subsets[s]].all(axis=0))
            if not rows.size:
                continue
            tau = self._exact_held(pts, ids, rows, self.subsets[s])
            g = np.empty(rows.size)
            pef_stretch.best_stretch(pef_kernels.STRIPS, px[rows], py[rows], mx, my,
                                     np.repeat(self.subsets[s][None], rows.size, axis=0),
                                     float(sensor.relative_error), float(sensor.absolute_error), tan_xi,
                                     self.chi2_ppf, h, np.ascontiguousarray(tau, dtype=float), False, g)
            v = tau * g
            better = v < least[rows]
            least[rows[better]] = v[better]
            best[rows[better]] = self.subsets[s]
        return least, best

    def _memo(self, name: str, widen: float) -> PointMemo:
        """Return the memo of ``name``'s per-point results at ``widen`` (:mod:`planner.pef.pointmemo`).

        Held for this PEF's scenario and settings; a change of either starts afresh.
        """
        config = (self.sight, self.rule, self.model, self.k, self.redundancy, self.exact_margin,
                  self.markers.tobytes())
        memos = getattr(self, "_memos", None)
        if memos is None or memos[0] is not self.scenario or memos[1] != config:
            memos = self._memos = (self.scenario, config, {})
        return memos[2].setdefault((name, float(widen)), PointMemo())

    def _at_points(self, pts: np.ndarray, widen: float) -> PefResult:
        """:meth:`at` of ``pts`` (N, 2), without the memo of earlier calls."""
        # a point asked twice (candidate routes share their stretches: a third of the hall's
        # samples) is evaluated once
        _, first, again = np.unique(pts.view(np.dtype((np.void, pts.itemsize * 2))).ravel(),
                                    return_index=True, return_inverse=True)
        if first.size < len(pts):
            order = np.sort(first)
            rank = np.empty(len(pts), dtype=np.int64)
            rank[order] = np.arange(order.size)
            at = rank[first[again.ravel()]]
            r = self._at_points(pts[order], widen)
            return PefResult(tau=r.tau[at], best=r.best[at],
                             tau_plain=None if r.tau_plain is None else r.tau_plain[at],
                             fallback=None if r.fallback is None else r.fallback[at])
        vis = self._visibility(pts, widen)
        px, py = np.ascontiguousarray(pts[:, 0]), np.ascontiguousarray(pts[:, 1])
        return self._redundant(lambda v: self._evaluate(px, py, v), vis)

    def grid(self, resolution: float | None = None) -> PefMap:
        """Evaluate the PEF on the cell centres of a grid over the workspace.

        Parameters
        ----------
        resolution : float, optional
            Cell size [m]; default ``scenario.planning.resolution``. The workspace is divided
            evenly, so the cells are as close to this size as an integer count allows.

        Returns
        -------
        PefMap
        """
        res = float(resolution) if resolution is not None else self.scenario.planning.resolution
        x, y = grid_centres(self.scenario.workspace.size, res, self.scenario.workspace.origin)
        size = self.scenario.workspace.size
        return replace(self.cells(x, y, cell_size=(size[0] / x.size, size[1] / y.size)), resolution=res)

    def cells(self, x: np.ndarray, y: np.ndarray, cell_size: tuple[float, float] | None = None) -> PefMap:
        """Evaluate the PEF on the grid of cell centres ``x`` x ``y`` (a window of :meth:`grid`'s).

        Every cell's value depends on its centre alone, so a window of a grid's centres gives
        the grid's values there (``pefsim watch`` recomputes only where a moved marker is seen).

        Parameters
        ----------
        x : ndarray, shape (nx,)
            Cell-centre x coordinates [m], increasing.
        y : ndarray, shape (ny,)
            Cell-centre y coordinates [m], increasing.
        cell_size : (float, float), optional
            Recorded in the result [m]; default the spacing of ``x`` and ``y``.

        Returns
        -------
        PefMap
        """
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        if cell_size is None:
            dx = float(x[1] - x[0]) if x.size > 1 else 0.0
            cell_size = (dx, float(y[1] - y[0]) if y.size > 1 else dx)
        if self.model is PefModel.PARALLELOGRAM and self.redundancy <= 1:
            # streamed band by band: no (M, ny, nx) visibility array (planner.pef.gridtiles), with
            # tau_1 in the same pass; r >= 2 and the other models take the general path below
            sc = self.scenario
            tau, best, free, tau_plain = parallelogram_grid(
                x, y, self.markers, sc.obstacle_pieces(), self.sensor.max_range, sc.workspace.bounds,
                float(self.sensor.relative_error), float(self.sensor.absolute_error), self.redundancy,
                sc.marker_normals(), self.sensor.max_incidence, self.rule)
            return PefMap(x=x, y=y, tau=tau, best=best, free=free, model=self.model,
                          cell_size=cell_size, redundancy=self.redundancy, tau_plain=tau_plain,
                          eps_max=sc.planning.eps_max)
        vis, free = scenario_visible_grid(self.scenario, x, y, self.sight)
        if self.model is PefModel.EXACT:
            px, py = np.tile(x, y.size), np.repeat(y, x.size)
            evaluate = lambda v: self._evaluate(px, py, v)  # noqa: E731
        else:
            def evaluate(v: np.ndarray) -> PefResult:
                t, b = self._kernel_grid(x, y, v.reshape(v.shape[0], y.size, x.size))
                return PefResult(tau=t.ravel(), best=b.reshape(y.size * x.size, self.k))
        r = self._redundant(evaluate, vis.reshape(vis.shape[0], y.size * x.size))
        shape = (y.size, x.size)
        return PefMap(x=x, y=y, tau=r.tau.reshape(shape), best=r.best.reshape(*shape, self.k), free=free,
                      model=self.model, cell_size=cell_size,
                      redundancy=self.redundancy, tau_plain=r.tau_plain.reshape(shape),
                      eps_max=self.scenario.planning.eps_max)

    def tau_subset(self, points: np.ndarray, subset: np.ndarray) -> np.ndarray:
        """Evaluate the model's error of given marker subsets at points.

        Parameters
        ----------
        points : ndarray, shape (N, 2)
            Points [m].
        subset : ndarray of int, shape (k,) or (C, k)
            Marker indices: one subset, or C of them (their markers' visibility is computed once).

        Returns
        -------
        ndarray, shape (N,) or (C, N)
            tau [m]; inf where a marker of the subset is not visible (out of range, hidden, beyond
            a flat marker's incidence limit) or the point not free.
        """
        pts = _points(points)
        many = np.ndim(subset) == 2
        sub = np.asarray(subset, dtype=np.int64).reshape(-1, np.shape(subset)[-1] if np.ndim(subset) else 1)
        if sub.shape[1] != self.k:
            raise PlanningError(f"subset: expected {self.k} marker indices, got {sub.shape[1]}")
        for row in sub.tolist():
            if min(row) < 0 or max(row) >= len(self.markers) or len(set(row)) != self.k:
                raise PlanningError(f"subset: expected {self.k} distinct marker indices "
                                    f"in [0, {len(self.markers)}), got {row}")
        # only the subsets' markers matter: their visibility alone, and the kernel on each
        # subset's k markers (the winner's tau is recomputed from them alone)
        # a schedule's rungs at the same speeds ask for the same samples and subsets again
        key = (pts.tobytes(), pts.shape, sub.tobytes(), sub.shape, self.rule, self.model, id(self.scenario))
        last = getattr(self, "_subset_last", None)
        if last is not None and last[0] == key:
            out = last[1].copy()
            return out if many else out[0]
        if self.model is PefModel.EXACT:
            out = self._exact_subsets(pts, sub)
            self._subset_last = (key, out.copy())
            return out if many else out[0]
        sc = self.scenario
        used = np.unique(sub)
        vis_used, _ = visible_points(pts, self.markers[used], sc.obstacle_pieces(), self.sensor.max_range,
                                     sc.workspace.bounds, sc.marker_normals()[used], self.sensor.max_incidence,
                                     self.rule, bodies=self.markers)
        local = np.arange(self.k, dtype=np.int64)
        out = np.empty((sub.shape[0], pts.shape[0]))
        px, py = pts[:, 0].copy(), pts[:, 1].copy()
        for i, row in enumerate(sub):
            vis = np.ascontiguousarray(vis_used[np.searchsorted(used, row)])  # rows in subset order
            out[i] = self._kernel(px, py, vis, local.reshape(1, -1), _KERNEL_MODEL[self.model],
                                  self.markers[row])[0]
        self._subset_last = (key, out.copy())
        return out if many else out[0]

    def _exact_subsets(self, pts: np.ndarray, sub: np.ndarray) -> np.ndarray:
        """:meth:`tau_subset` of the ``exact`` model, (C, N) for subsets ``sub`` (C, k) at ``pts`` (N, 2).

        A clipping (milliseconds each) is done once per point and subset: the values computed
        in earlier calls are held (:mod:`planner.pef.pointmemo`; only those, where the subset is
        visible: elsewhere the value is inf without a clipping).
        """
        sc = self.scenario
        used = np.unique(sub)
        vis_used, _ = visible_points(pts, self.markers[used], sc.obstacle_pieces(), self.sensor.max_range,
                                     sc.workspace.bounds, sc.marker_normals()[used], self.sensor.max_incidence,
                                     self.rule, bodies=self.markers)
        ids = self._exact_ids(pts)
        self._exact_values()  # a call begins: only now may the store drop values (planner.pef.subsetvalues)
        out = np.full((sub.shape[0], pts.shape[0]), np.inf)
        for i, row in enumerate(sub):
            seen = np.flatnonzero(vis_used[np.searchsorted(used, row)].all(axis=0))
            out[i, seen] = self._exact_held(pts, ids, seen, row)
        return out

    def _exact_ids(self, pts: np.ndarray) -> np.ndarray:
        """Return each point's number in the memo of exact values (:meth:`_exact_held`), (N,)."""
        return self._memo("exact", 0.0).held(point_keys(pts))

    def _exact_held(self, pts: np.ndarray, ids: np.ndarray, rows: np.ndarray, subset: np.ndarray) -> np.ndarray:
        """:meth:`_exact_subset` of ``subset`` (k,) at ``pts[rows]``, each (point, subset) clipped once.

        ``ids`` (N,): the points' numbers from :meth:`_exact_ids`. The value of a subset at a point
        is the clipping of its markers' fault area there, whoever asks (:meth:`at` for the best
        subset, :meth:`tau_subset` for given ones): the values computed before are held
        (:mod:`planner.pef.subsetvalues`; a call starts with :meth:`_exact_values`).
        """
        local = np.arange(self.k, dtype=np.int64)

        def clip(first: np.ndarray) -> np.ndarray:
            at = rows[first]
            return self._exact_subset(pts[at], np.ones((self.k, len(at)), dtype=bool), local, self.markers[subset])

        return self._exact_values(begin=False).values(tuple(subset.tolist()), ids[rows], clip)

    def _exact_values(self, begin: bool = True) -> SubsetValues:
        """Return the store of exact values (numbered by :meth:`_exact_ids`'s memo); ``begin``: a call starts."""
        memo = self._memo("exact", 0.0)
        held = getattr(self, "_exact_store", None)
        if held is None or held[0] is not memo or held[1] != memo.epoch:  # the points renumbered
            held = self._exact_store = (memo, memo.epoch, SubsetValues())
        if begin:
            held[2].begin()
        return held[2]

    # --- internals ----------------------------------------------------------------------------

    def _redundant(self, evaluate, vis: np.ndarray) -> PefResult:
        """tau_r by the recursion over the best subset's members (module docstring).

        ``evaluate(vis)`` returns the plain :class:`PefResult` for a visibility ``vis`` (M, N)
        (its own points); the recursion hands it copies with one marker per point cleared.
        """
        plain = evaluate(vis)
        n = plain.tau.size
        fallback = np.full((n, self.k, self.k), -1, dtype=np.int64)
        if self.redundancy == 0:
            return PefResult(tau=plain.tau, best=plain.best, tau_plain=plain.tau, fallback=fallback)
        worst = plain.tau.copy()
        for j in range(self.k):
            tau_j, best_j = self._without(evaluate, vis, plain.best[:, j], self.redundancy - 1)
            np.maximum(worst, tau_j, out=worst)
            fallback[:, j] = best_j
        return PefResult(tau=worst, best=plain.best, tau_plain=plain.tau, fallback=fallback)

    def _without(self, evaluate, vis: np.ndarray, drop: np.ndarray, depth: int) -> tuple[np.ndarray, np.ndarray]:
        """tau_depth and the best subset with marker ``drop[n]`` (N,) hidden at point n (-1: none)."""
        rows = np.flatnonzero(drop >= 0)
        v = vis.copy()
        v[drop[rows], rows] = False
        r = evaluate(v)
        tau = r.tau.copy()
        tau[drop < 0] = np.inf  # no best subset: already no fix, and none without a marker either
        if depth > 0:
            for j in range(self.k):
                tau_j, _ = self._without(evaluate, v, r.best[:, j], depth - 1)
                np.maximum(tau, tau_j, out=tau)
        best = np.where((drop >= 0)[:, None], r.best, -1)
        return tau, best

    def _kernel(self, px: np.ndarray, py: np.ndarray, vis: np.ndarray, subsets: np.ndarray,
                model: int, markers: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Return tau (N,) and the chosen subset's markers (N, k) for points (px, py), vis (M, N).

        ``markers`` (M, 2): the markers ``vis`` and ``subsets`` refer to; default all of them.
        """
        mk = self.markers if markers is None else markers
        n = px.size
        tau = np.empty(n)
        best = np.empty((n, subsets.shape[1]), dtype=np.int64)
        if n == 0:
            return tau, best
        if subsets.shape[0] == 0:
            tau.fill(np.inf)
            best.fill(-1)
            return tau, best
        tan_xi = math.tan(self.sensor.bearing_error) if self.sensor.uses_bearing else 0.0
        pef_kernels.best_subset(
            px, py, np.ascontiguousarray(mk[:, 0]), np.ascontiguousarray(mk[:, 1]),
            np.ascontiguousarray(vis), float(self.sensor.relative_error),
            float(self.sensor.absolute_error), tan_xi, model, subsets, self.chi2_ppf, tau, best)
        return tau, best

    def _kernel_grid(self, x: np.ndarray, y: np.ndarray, vis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return tau (ny, nx) and the best subsets (ny, nx, k) on cell centres x, y; vis (M, ny, nx)."""
        tau = np.empty((y.size, x.size))
        best = np.empty((y.size, x.size, self.k), dtype=np.int64)
        if self.subsets.shape[0] == 0:
            tau.fill(np.inf)
            best.fill(-1)
            return tau, best
        tan_xi = math.tan(self.sensor.bearing_error) if self.sensor.uses_bearing else 0.0
        pef_kernels.best_subset_grid(
            x, y, np.ascontiguousarray(self.markers[:, 0]), np.ascontiguousarray(self.markers[:, 1]),
            np.ascontiguousarray(vis), float(self.sensor.relative_error), float(self.sensor.absolute_error),
            tan_xi, _KERNEL_MODEL[self.model], self.subsets, self.chi2_ppf, tau, best)
        return tau, best

    def _evaluate(self, px: np.ndarray, py: np.ndarray, vis: np.ndarray) -> PefResult:
        """Evaluate the plain best-subset PEF at points (px, py) (N,) [m] with visibility ``vis`` (M, N)."""
        if self.model is PefModel.EXACT:
            tau, best = self._exact(px, py, vis)
        else:
            tau, best = self._kernel(px, py, vis, self.subsets, _KERNEL_MODEL[self.model])
        return PefResult(tau=tau, best=best)

    def _exact(self, px: np.ndarray, py: np.ndarray, vis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Exact model: clip the candidate subsets chosen by their linearised diameters."""
        n, nsub = px.size, len(self.subsets)
        if n == 0 or nsub == 0:
            return np.full(n, np.inf), np.full((n, self.k), -1, dtype=np.int64)
        cand = self._exact_candidates(px, py, vis)
        pts = np.column_stack([px, py])
        ids = self._exact_ids(pts)
        self._exact_values()  # a call begins: only now may the store drop values (planner.pef.subsetvalues)
        exact = np.full((n, nsub), np.inf)
        for s in range(nsub):
            # the candidates the subset is visible from (elsewhere inf without a clipping)
            rows = np.flatnonzero(cand[:, s] & vis[self.subsets[s]].all(axis=0))
            if rows.size:
                exact[rows, s] = self._exact_held(pts, ids, rows, self.subsets[s])
        idx = np.where(np.isfinite(exact).any(axis=1), exact.argmin(axis=1), -1)
        best = np.where(idx[:, None] >= 0, self.subsets[np.maximum(idx, 0)], -1)
        return exact.min(axis=1), best

    def _exact_candidates(self, px: np.ndarray, py: np.ndarray, vis: np.ndarray) -> np.ndarray:
        """Return (N, C) bool: the subsets worth clipping at each point, by their linearised diameters."""
        lin = np.empty((px.size, len(self.subsets)))
        for s in range(len(self.subsets)):
            lin[:, s] = self._kernel(px, py, vis, self.subsets[s:s + 1], pef_kernels.STRIPS)[0]
        return np.isfinite(lin) & (lin <= self.exact_margin * lin.min(axis=1, keepdims=True))

    def _exact_subset(self, pts: np.ndarray, vis: np.ndarray, subset: np.ndarray,
                      markers: np.ndarray | None = None) -> np.ndarray:
        """Exact fault-area diameters of one ``subset`` (k,) at ``pts`` (N, 2); inf where hidden.

        ``subset`` indexes ``markers`` (default all markers) and the rows of ``vis``.
        """
        from estimators.fault.exact import fault_area_of_point

        out = np.full(len(pts), np.inf)
        mk = (self.markers if markers is None else markers)[subset]
        for i in np.flatnonzero(vis[subset].all(axis=0)):
            rho = self.sensor.range_bound(np.hypot(*(pts[i] - mk).T))
            out[i] = fault_area_of_point(mk, pts[i], rho, bearing_error=self.sensor.bearing_error).diameter
        return out


def _points(points: np.ndarray) -> np.ndarray:
    p = np.asarray(points, dtype=float)
    if p.ndim == 1 and p.shape[0] == 2:
        p = p[None, :]
    if p.ndim != 2 or p.shape[1] != 2:
        raise PlanningError(f"points: expected shape (N, 2), got {np.shape(points)}")
    return np.ascontiguousarray(p)
