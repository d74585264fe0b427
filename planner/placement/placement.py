"""Marker placement: the fewest markers, among candidate sites, that keep every point under eps_max.

A point is covered when some visible subset of k chosen markers has ``tau < eps_max`` under the
scenario's PEF model. For k = 2 the coverage of a point is by *pairs* of sites: a set cover
over pairs, the MILP (site variables z_j, pair variables y_jl)::

    min sum_j z_j  s.t.  sum_{pairs good at i} y_jl >= 1 for every point i,
                         y_jl <= z_j,  y_jl <= z_l,  z binary,  0 <= y <= 1

:mod:`planner.placement.cover` solves the same problem without the pair variables (equivalent
independent-set cuts generated as needed: far fewer rows, a tighter LP; see there). For k > 2
a good *pair* is used as a sufficient condition (adding markers to a subset only shrinks the
strip intersection and adds GDOP information) together with ``sum_{j visible from i} z_j >= k``;
a point that only k mediocre markers together could cover, without a good pair among them, is
reported uncovered (conservative).

Size limit: with at most :data:`MILP_MAX_SITES` useful sites (in some good pair), ``auto``
runs the exact solver (LP cutting planes, local search, then HiGHS MILP rounds via
:func:`scipy.optimize.milp` with a node limit); it reports ``optimal`` when the bound meets the
best cover. Above it, the LP relaxation's rounding improved by local search
(:mod:`planner.placement.search`) is reported with the LP relaxation's lower bound. Per-pair
tau comes from the PEF's own kernel (:func:`planner.pef.kernels.subset_tau`) on the points'
visible sites, visibility the PEF's (:func:`planner.pef.visibility.scenario_visible_points`) over
a scenario copy whose markers are the sites; the ``exact`` model is optimised with its
linearisation (``strips``): clipping polygons for every pair and point would be far too slow.

Refinement: sampled sites (``placement.spacing`` apart) can miss the few places on a face from
which a point is seen at all (a flat reflector is seen only within ``max_incidence`` of its
normal: from 1 m off a rack face, a 2 m stretch of it). Where points are left uncovered, the
faces are sampled again at half the spacing, and the new sites that form a good pair for an
uncovered point (with any site) join the candidates; this repeats down to
``spacing / 2**REFINE_LEVELS``. With ``planning.redundancy`` = r a point counts as uncovered
until all sites together keep it covered with any r of them blocked (a point a face sees from
only one good pair needs a finer sampling as much as one it does not see at all). Points still
uncovered then are reported (uncoverable at that sampling). Only the sites that help those
points are added, so the problem stays small.

Keeping what is installed (``placement.existing = "keep"``): the scenario's markers are sites
that are always chosen (held at 1 in the LP and MILP, never dropped by the greedy or the local
search) and not counted; count and lower bound are those of the markers added.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import tomllib
import warnings
import weakref
from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np
import tomli_w

from jit import compiled
from planner.pef import kernels as pef_kernels
from planner.pef import stretch as pef_stretch
from planner.placement.cover import MILP_TIME_LIMIT, solve_exact
from planner.placement.facing import site_facings, site_marker
from planner.placement.pair_cover import PairCover, subset_rows
from planner.placement.redundant import robust_rows
from planner.placement.sites import candidate_sites, cover_points
from scenarios.errors import PlanningError, ScenarioWarning, output_errors
from scenarios.load import MIN_SPACING
from scenarios.schema import Marker, MarkerKind, PefModel, Scenario

MILP_MAX_SITES = 150
"""Largest number of useful sites (in some good pair) for which ``auto`` runs integer rounds."""
DENSE_KEYS = 20_000_000
"""Largest sites**2 for which the pairs are numbered through a dense table (5 bytes a key)."""
SEARCH_STREAM = 15
"""Spawn key of the local search's random stream under the scenario seed."""
REFINE_LEVELS = 4
"""Halvings of ``placement.spacing`` tried where points are left uncovered (2 m -> 0.125 m)."""
TAU_MARGIN = 1e-5
"""Pairs count as good when ``tau < eps_max (1 - TAU_MARGIN)``: the PEF selects its best
subset in float32, so its tau may exceed the float64 minimum by ~1e-6 relative."""


@dataclass(frozen=True, eq=False)
class PlacementResult:
    """Chosen markers and how good the choice is.

    Attributes
    ----------
    markers : list of (str, (float, float))
        Marker ids and positions [m].
    count : int
    lower_bound : int
        No placement among the sites covers the coverable points with fewer markers (added
        markers, when some are kept).
    optimal : bool
        ``count`` is proven minimal (MILP solved to optimality).
    uncovered : ndarray, shape (U, 2)
        Points no subset of sites can cover [m].
    method : str
        ``milp`` (integer rounds ran), ``search`` (LP rounding and local search only; with
        redundancy 1 LP rounding completed greedily), or ``greedy`` (nothing to cover).
    sites : ndarray, shape (S, 2)
        The candidate sites [m].
    points : ndarray, shape (N, 2)
        The points to cover [m].
    chosen : ndarray of int, shape (count,)
        Indices of the chosen sites.
    facings : tuple of (float or None)
        Facing of each chosen marker [rad]: flat, out of its face; None for a post.
    redundancy : int
        r: every covered point keeps a good subset with any r chosen markers blocked.
    kept : tuple of Marker
        Markers kept as installed (``placement.existing = "keep"``); ``markers``, ``count``
        and ``lower_bound`` are then the ones added.
    target : float
        The cover's target [m]: every covered point has a subset with tau below it.
    unplanned : tuple of str
        ``"A->B: reason"`` for each task without an admissible route on the layout (filled by
        :func:`planner.placement.plannable.place_plannable`; empty when not checked).
    finest_spacing : float or None
        Finest spacing the candidate sites were refined to where points were uncovered [m]
        (None: not refined).
    """

    markers: list[tuple[str, tuple[float, float]]]
    count: int
    lower_bound: int
    optimal: bool
    uncovered: np.ndarray
    method: str
    sites: np.ndarray
    points: np.ndarray
    chosen: np.ndarray
    facings: tuple = ()
    redundancy: int = 0
    kept: tuple = ()
    target: float = float("nan")
    unplanned: tuple = ()
    finest_spacing: float | None = None
    written: Path | None = None
    """The scenario TOML with these markers :func:`pefsim.place` wrote (None: not asked, or no fix possible)."""

    @property
    def new_ids(self) -> tuple[str, ...]:
        """Ids of the markers this placement added (all of them unless markers were kept)."""
        return tuple(i for i, _ in self.markers)

    def layout(self) -> tuple[Marker, ...]:
        """Every marker of the placed layout: the kept ones unchanged, then the added ones."""
        return self.kept + tuple(site_marker(i, p, f) for (i, p), f in _facing_pairs(self))

    def shortfall(self, scenario: Scenario, *, unwritten: bool = False) -> str | None:
        """Say in one line what the placement left undone (uncovered points, unplanned tasks), else None.

        ``unwritten``: a scenario TOML was asked for (``out``) but not written (fewer than k markers).
        """
        n_bad, n_pts = len(self.uncovered), len(self.points)
        if n_bad:
            first = ", ".join(f"({x:.2f}, {y:.2f})" for x, y in self.uncovered[:3])
            note = "; out not written: no markers" if unwritten else ""
            if scenario.placement.candidates:
                hint = ""
            else:
                finest = scenario.placement.spacing if self.finest_spacing is None else self.finest_spacing
                hint = (f"; candidate sites were sampled down to {finest:g} m apart"
                        + (": posts (placement.marker_kind) may cover them"
                           if scenario.placement.marker_kind.value == "flat" else ""))
            return (f"{n_bad} of {n_pts} points cannot be covered by any candidate sites "
                    f"(first: {first}){hint}{note}")
        if self.unplanned:
            return (f"{len(self.unplanned)} of {len(scenario.tasks)} tasks have no admissible route on the "
                    f"placed markers, even with the cover target at {self.target:g} m: {self.unplanned[0]}")
        return None

    def fixable(self, markers_per_fix: int) -> bool:
        """Whether the layout has the ``markers_per_fix`` markers a fix needs (else there is nothing to write)."""
        return len(self.layout()) >= markers_per_fix

    def to_dict(self) -> dict:
        """Return the placement as a JSON-ready dict (what ``pefsim place --json`` prints; metres, degrees).

        ``markers`` is the whole layout, each marker with ``new`` (added by this placement);
        ``count`` and ``lower_bound`` are of the added ones.
        """
        new = set(self.new_ids)
        return {
            "target": _finite_or_none(self.target),
            "unplanned": list(self.unplanned),
            "count": int(self.count),
            "lower_bound": int(self.lower_bound),
            "optimal": bool(self.optimal),
            "method": self.method,
            "kept": [m.id for m in self.kept],
            "new": sorted(new, key=self.new_ids.index),
            "markers": [{**_marker_dict(m), "kind": m.kind.value, "new": m.id in new} for m in self.layout()],
            "points": int(len(self.points)),
            "sites": int(len(self.sites)),
            "finest_spacing": self.finest_spacing,
            "uncovered": [[float(x), float(y)] for x, y in self.uncovered],
        }


def _finite_or_none(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


@compiled.njit(parallel=True, cache=True)
def _good_pairs_kernel(px, py, sx, sy, vis, model, rel, ab, tan_xi, chi2, h, limit, offsets, out_j, out_l):
    """Count (``offsets`` None-like: size 0) or list the good pairs of every point.

    ``vis`` (N, S); pairs ``(j, l)``, j < l, both visible and tau under ``limit`` over the whole
    stretch within ``h`` [m] of the point (:func:`planner.pef.stretch.subset_stretch`). Returns
    the counts.
    """
    n, s = vis.shape
    counts = np.zeros(n, dtype=np.int64)
    for i in numba.prange(n):
        seen = np.empty(s, dtype=np.int64)
        m = 0
        for j in range(s):
            if vis[i, j]:
                seen[m] = j
                m += 1
        sub = np.empty(2, dtype=np.int64)
        nx, ny, b = np.empty(4), np.empty(4), np.empty(4)
        c = 0
        for a in range(m):
            for z in range(a + 1, m):
                sub[0], sub[1] = seen[a], seen[z]
                t = pef_kernels.subset_tau(model, px[i], py[i], sx, sy, sub, rel, ab, tan_xi, chi2, nx, ny, b)
                t = t * pef_stretch.subset_stretch(model, px[i], py[i], sx, sy, sub, rel, ab, tan_xi, chi2, h, t, True)
                if t < limit:
                    if offsets.size:
                        out_j[offsets[i] + c] = seen[a]
                        out_l[offsets[i] + c] = seen[z]
                    c += 1
        counts[i] = c
    return counts


def _site_scenario(scenario: Scenario, sites: np.ndarray, kept: tuple[Marker, ...] = ()) -> Scenario:
    """Return a copy of ``scenario`` whose markers are the sites (flat on faces, see :mod:`.facing`).

    ``kept``: markers already installed, as they are; they stand for the first ``len(kept)``
    rows of ``sites``, the others become markers of the placement's kind.
    """
    free = sites[len(kept):]
    markers = kept + tuple(site_marker(f"S{j}", p, f)
                           for j, (p, f) in enumerate(zip(free, site_facings(scenario, free), strict=True)))
    return dataclasses.replace(scenario, markers=markers)


def _model(scenario: Scenario) -> PefModel:
    m = scenario.planning.pef_model
    return PefModel.STRIPS if m is PefModel.EXACT else m


def build_cover(scenario: Scenario, points: np.ndarray, sites: np.ndarray, eps_max: float,
                kept: tuple[Marker, ...] = (), widen: float = 0.0):
    """Good pairs of sites at every point.

    ``kept``: markers already installed, standing for the first ``len(kept)`` sites (their
    own kinds and facings; see :func:`_site_scenario`). ``widen`` [m]: a site counts at a point
    only when it is seen from every position within it too (the route points stand for the
    stretches between them, :mod:`planner.routes.admissible`).

    Returns
    -------
    cover : PairCover
        The cover problem over the coverable points (rows deduplicated).
    coverable : ndarray of bool, shape (N,)
        Points some subset of sites can cover.
    """
    from estimators.fault.linearized import chi2_2dof_ppf
    from planner.pef.visibility import scenario_visible_points

    k = scenario.sensor.markers_per_fix
    # the sites' visibility only: a PEF over them would list every pair of sites (4e6 for 3000
    # sites, past its limit), where a point's good pairs are among the few sites it sees
    points = np.ascontiguousarray(np.asarray(points, dtype=float).reshape(-1, 2))
    # the same sites and points whatever the target: place_plannable's tighter covers reuse it
    key = (points.tobytes(), np.ascontiguousarray(sites, dtype=float).tobytes(), kept, float(widen))
    got = [e for e in _COVER_VIS if e[0]() is scenario and e[1] == key]
    if got:
        vis = got[0][2]
    else:
        vis = np.ascontiguousarray(scenario_visible_points(_site_scenario(scenario, sites, kept), points,
                                                           widen=widen)[0].T)
        _COVER_VIS[:] = [*_COVER_VIS[-(_COVER_VIS_KEPT - 1):], (weakref.ref(scenario), key, vis)]
    model = _model(scenario)
    kernel_model = {PefModel.PARALLELOGRAM: pef_kernels.PARALLELOGRAM, PefModel.STRIPS: pef_kernels.STRIPS,
                    PefModel.GDOP: pef_kernels.GDOP}[model]
    sensor = scenario.sensor
    tan_xi = math.tan(sensor.bearing_error) if sensor.uses_bearing else 0.0
    chi2 = float(chi2_2dof_ppf(scenario.planning.gdop_level))
    args = (np.ascontiguousarray(points[:, 0]), np.ascontiguousarray(points[:, 1]),
            np.ascontiguousarray(sites[:, 0]), np.ascontiguousarray(sites[:, 1]), vis, kernel_model,
            float(sensor.relative_error), float(sensor.absolute_error), tan_xi, chi2, float(widen),
            float(eps_max) * (1.0 - TAU_MARGIN))
    empty = np.zeros(0, dtype=np.int64)
    counts = _good_pairs_kernel(*args, empty, empty, empty)
    offsets = np.concatenate([[0], np.cumsum(counts)])
    out_j, out_l = np.empty(offsets[-1], dtype=np.int64), np.empty(offsets[-1], dtype=np.int64)
    _good_pairs_kernel(*args, offsets, out_j, out_l)
    coverable = (counts > 0) & (vis.sum(axis=1) >= k)

    n_sites = len(sites)
    key = out_j * n_sites + out_l
    if n_sites * n_sites <= DENSE_KEYS:  # unique keys by a table: the sort of ~1e7 keys took seconds
        present = np.zeros(n_sites * n_sites, dtype=bool)
        present[key] = True
        pair_keys = np.flatnonzero(present)
        pair_of_entry = (np.cumsum(present, dtype=np.int32) - 1)[key].astype(np.int64)
    else:
        pair_keys, pair_of_entry = np.unique(key, return_inverse=True)
    point_of_entry = np.repeat(np.arange(len(points)), counts)
    keep = coverable[point_of_entry]
    # rows: identical (good-pair set, visible set) points merge into one weighted row
    rows: dict[bytes, int] = {}
    row_of = np.empty(int(coverable.sum()), dtype=np.int64)
    first_point = []
    for n_i, i in enumerate(np.flatnonzero(coverable)):
        sig = pair_of_entry[offsets[i]:offsets[i + 1]].tobytes() + np.packbits(vis[i]).tobytes()
        row_of[n_i] = rows.setdefault(sig, len(rows))
        if row_of[n_i] == len(first_point):
            first_point.append(i)
    first_point = np.asarray(first_point, dtype=np.int64)
    is_first = np.zeros(len(points), dtype=bool)
    is_first[first_point] = True
    row_index = np.full(len(points), -1)
    row_index[first_point] = np.arange(len(first_point))
    sel = keep & is_first[point_of_entry]
    er, ep = row_index[point_of_entry[sel]], pair_of_entry[sel]
    pj, pl = pair_keys // n_sites, pair_keys % n_sites
    cover = PairCover(weight=np.bincount(row_of, minlength=len(first_point)).astype(float), row_of=row_of,
                   row_ptr=np.searchsorted(er, np.arange(len(first_point) + 1)), ep=ep, ea=pj[ep], eb=pl[ep],
                   pj=pj, pl=pl, vis=np.ascontiguousarray(vis[first_point]), n_sites=n_sites)
    return cover, coverable


#: The last visibility tables of :func:`build_cover`: (its scenario, weakly; its sites, points,
#: kept markers and widening; the table, which is only read). A cover and its refinement's.
_COVER_VIS: list = []
_COVER_VIS_KEPT = 3


def _search_seed(seed: int) -> int:
    """Seed of the placement's local search, from its own stream of the scenario seed."""
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(SEARCH_STREAM,)))
    return int(rng.integers(2**63))


def place(scenario: Scenario, points: np.ndarray | None = None, sites: np.ndarray | None = None,
          eps_max: float | None = None, method: str = "auto",
          time_limit: float = MILP_TIME_LIMIT) -> PlacementResult:
    """Find the fewest markers among candidate sites that cover every coverable point.

    Parameters
    ----------
    scenario : Scenario
        Sensor, obstacles, PEF model, k, and the defaults below. With
        ``placement.existing = "keep"`` its markers stay as they are and only the added ones
        are chosen and counted (see module doc); with ``"replace"`` they are ignored.
    points : ndarray, shape (N, 2), optional
        Points to cover [m]; default :func:`planner.placement.sites.cover_points`.
    sites : ndarray, shape (S, 2), optional
        Candidate sites [m]; default :func:`planner.placement.sites.candidate_sites`, refined
        where points are left uncovered (see module doc). Given sites are not refined.
    eps_max : float, optional
        Allowed error [m]; default ``scenario.planning.eps_max``. With
        ``planning.redundancy`` = 1 every covered point keeps a pair under it with any one
        chosen marker blocked (the redundancy-1 cutting planes of :mod:`planner.placement.cover`,
        with their own LP bound; points no choice keeps robust are reported uncovered).
    method : {"auto", "milp", "greedy"}
        ``auto``: the exact solver with at most :data:`MILP_MAX_SITES` useful sites, else
        ``greedy``: LP rounding and local search (with the LP bound), no integer rounds.
    time_limit : float
        Time limit of the solver's LP and MILP rounds [s].

    Returns
    -------
    PlacementResult
    """
    if method not in ("auto", "milp", "greedy"):
        raise PlanningError(f"placement method: expected auto, milp or greedy, got {method!r}")
    pts = cover_points(scenario) if points is None else np.asarray(points, dtype=float).reshape(-1, 2)
    cand = candidate_sites(scenario) if sites is None else np.asarray(sites, dtype=float).reshape(-1, 2)
    eps = scenario.planning.eps_max if eps_max is None else float(eps_max)
    k = scenario.sensor.markers_per_fix
    redundancy = scenario.planning.redundancy
    kept = scenario.markers if scenario.placement.existing == "keep" else ()
    if kept:  # a candidate where a marker already is would only duplicate it
        have = scenario.marker_positions()
        cand = cand[np.hypot(*(cand[:, None, :] - have[None, :, :]).transpose(2, 0, 1)).min(axis=1) > 1e-6]
    n_kept = len(kept)
    allx = lambda c: np.vstack([np.asarray(scenario.marker_positions(), dtype=float).reshape(-1, 2)[:n_kept], c])
    # the route points (planning.resolution apart, planner.placement.sites.route_points) stand for
    # the stretches between them: a site counts only where it stays in sight over the stretch, as
    # plan and export judge a path (planner.routes.admissible); given points stand for themselves
    from planner.routes.admissible import stretch_widen

    routes = points is None and scenario.placement.cover != "free"
    widen = stretch_widen(scenario.planning.resolution) if routes else 0.0
    cov, coverable = build_cover(scenario, pts, allx(cand), eps, kept, widen)
    finest = None
    if sites is None and not scenario.placement.candidates \
            and not _servable(cov, coverable, k, redundancy).all():
        cand, finest = _refine(scenario, pts, cand, _servable(cov, coverable, k, redundancy), eps, kept, widen)
        if finest is not None:
            cov, coverable = build_cover(scenario, pts, allx(cand), eps, kept, widen)
    fixed = np.zeros(n_kept + len(cand), dtype=bool)
    fixed[:n_kept] = True
    chosen, bound, optimal, used = fixed.copy(), 0.0, True, "greedy"
    if coverable.any():
        used_sites = int(np.setdiff1d(np.concatenate([cov.pj, cov.pl]), np.arange(n_kept)).size)
        integral = method == "milp" or (method == "auto" and used_sites <= MILP_MAX_SITES)
        problem = cov
        if redundancy > 0:  # only rows that all sites together keep robust can be asked to be
            target = robust_rows(cov, np.ones(cov.n_sites, dtype=bool), k, redundancy)
            coverable = coverable.copy()
            coverable[np.flatnonzero(coverable)] = target[cov.row_of]
            problem = subset_rows(cov, target)
        if coverable.any():
            chosen, bound, optimal = solve_exact(problem, k, time_limit, integral=integral, xy=allx(cand),
                                                 seed=_search_seed(scenario.seed), fixed=fixed,
                                                 redundancy=redundancy)
        used = "milp" if integral else "search"
        if not n_kept:  # a fix needs k markers (k + r with r blocked); kept ones may already be them
            bound = max(bound, float(k + redundancy))
    idx = np.flatnonzero(chosen[n_kept:])
    lower = min(math.ceil(bound - 1e-6), len(idx))
    taken = {m.id for m in kept}
    names = (f"P{n}" for n in range(1, len(taken) + len(idx) + 2) if f"P{n}" not in taken)
    markers = [(next(names), (float(cand[j, 0]), float(cand[j, 1]))) for j in idx]
    facing = site_facings(scenario, cand[idx]) if len(idx) else []
    return PlacementResult(markers=markers, count=len(idx), lower_bound=lower,
                           optimal=bool(optimal and lower == len(idx)), uncovered=pts[~coverable],
                           method=used, sites=cand, points=pts, chosen=idx, facings=tuple(facing),
                           redundancy=redundancy, kept=tuple(kept), target=eps, finest_spacing=finest)


def _servable(cov: PairCover, coverable: np.ndarray, k: int, redundancy: int) -> np.ndarray:
    """Points, shape (N,) bool, that every site together covers with any ``redundancy`` of them blocked.

    ``coverable`` (N,) bool is :func:`build_cover`'s; with ``redundancy`` = 0 it is the answer.
    """
    if redundancy == 0 or not coverable.any():
        return coverable
    out = coverable.copy()
    out[np.flatnonzero(coverable)] = robust_rows(cov, np.ones(cov.n_sites, dtype=bool), k, redundancy)[cov.row_of]
    return out


def _refine(scenario: Scenario, pts: np.ndarray, cand: np.ndarray, coverable: np.ndarray, eps: float,
            kept: tuple[Marker, ...], widen: float = 0.0) -> tuple[np.ndarray, float | None]:
    """Add finer candidate sites where points are uncovered (see module doc).

    Returns the candidate sites (the given ones first, then those added) and the finest spacing
    sampled [m] (None when nothing was sampled).
    """
    bad = pts[~coverable]
    finest = None
    for level in range(1, REFINE_LEVELS + 1):
        spacing = scenario.placement.spacing / 2**level
        if spacing < MIN_SPACING:
            break
        finest = spacing
        finer = candidate_sites(scenario, spacing=spacing)
        have = np.vstack([scenario.marker_positions()[:len(kept)].reshape(-1, 2), cand])
        far = np.ones(len(finer), dtype=bool)
        for lo in range(0, len(finer), 512):  # chunks: (512, S) distances
            d = np.hypot(*(finer[lo:lo + 512, None, :] - have[None, :, :]).transpose(2, 0, 1))
            far[lo:lo + 512] = d.min(axis=1) > 1e-6
        finer = finer[far]
        if not len(finer):
            continue
        base = len(kept) + len(cand)
        sub, ok = build_cover(scenario, bad, np.vstack([have, finer]), eps, kept, widen)
        ok = _servable(sub, ok, scenario.sensor.markers_per_fix, scenario.planning.redundancy)
        helpful = np.unique(np.concatenate([sub.pj, sub.pl]))
        helpful = helpful[helpful >= base] - base
        cand = np.vstack([cand, finer[helpful]])
        bad = bad[~ok]
        if not len(bad):
            break
    return cand, finest


def scenario_with_markers(scenario: Scenario, result: PlacementResult) -> Scenario:
    """Return a copy of ``scenario`` whose markers are the placement's (flat ones facing out of their faces).

    Kept markers (``result.kept``) come first, unchanged.
    """
    return dataclasses.replace(scenario, markers=result.layout())


def _facing_pairs(result: PlacementResult):
    facings = result.facings if len(result.facings) == result.count else (None,) * result.count
    return zip(result.markers, facings, strict=True)


def _marker_dict(m: Marker) -> dict:
    d = {"id": m.id, "position": [float(m.position[0]), float(m.position[1])]}
    if m.kind is MarkerKind.FLAT:
        d["kind"] = "flat"
    if m.facing is not None:
        d["facing_deg"] = round(math.degrees(m.facing), 9)
    return d


# --------------------------------------------------------------------------- writing TOML


def _scenario_dict(sc: Scenario) -> dict:
    """Turn a scenario into a TOML-shaped dict (angles back in degrees, defaults written out)."""
    def spec(obj, base=None):
        out = {}
        for f in dataclasses.fields(obj):
            v = getattr(obj, f.name)
            if base is not None and v == getattr(base, f.name):
                continue
            key, v = ((f.name + "_deg", math.degrees(v)) if f.name in ("bearing_error", "max_incidence")
                      else (f.name, v.value if hasattr(v, "value") else v))
            out[key] = v
        return out

    d: dict = {"name": sc.name, "seed": sc.seed, "description": sc.description,
               "workspace": {"size": list(sc.workspace.size), "origin": list(sc.workspace.origin)},
               "obstacles": [o.to_dict() for o in sc.obstacles],
               **({"unknown": [o.to_dict() for o in sc.unknown]} if sc.unknown else {}),
               "markers": [_marker_dict(m) for m in sc.markers],
               "sensor": spec(sc.sensor), "robot": spec(sc.robot)}
    if not sc.workspace.walls:
        d["workspace"]["walls"] = False
    if sc.sensor_actual != sc.sensor:
        d["sensor"]["actual"] = spec(sc.sensor_actual, sc.sensor)
    if sc.robot_actual != sc.robot:
        d["robot"]["actual"] = spec(sc.robot_actual, sc.robot)
    pl = sc.planning
    d["planning"] = {"eps_max": pl.eps_max, "pef_model": pl.pef_model.value, "gdop_level": pl.gdop_level,
                     "resolution": pl.resolution, "weights": spec(pl.weights),
                     "heading_std_deg": pl.heading_std_deg, "min_fix_speed": pl.min_fix_speed,
                     "redundancy": pl.redundancy}
    if pl.order:
        d["planning"]["order"] = list(pl.order)
    d["docks"] = [{"name": k.name, "node": k.node, "yaw_deg": math.degrees(k.pose[2])} if k.node is not None
                  else {"name": k.name, "pose": [k.pose[0], k.pose[1], math.degrees(k.pose[2])]} for k in sc.docks]
    if sc.routes is not None and sc.routes.source:
        # the graph stays in its file, named absolutely since the new scenario may live elsewhere
        d["routes"] = {"file": str(Path(sc.routes.source).resolve()), "traffic": dict(sc.routes.traffic)}
        if sc.routes.layout:
            d["routes"]["layout"] = sc.routes.layout
    elif sc.routes is not None:
        d["routes"] = {"nodes": {k: list(v) for k, v in sc.routes.nodes.items()},
                       "segments": [list(s) for s in sc.routes.segments], "traffic": dict(sc.routes.traffic)}
    d["tasks"] = [{"from": t.start, "to": t.goal} for t in sc.tasks]
    d["montecarlo"] = {"runs": sc.montecarlo.runs, "success_target": sc.montecarlo.success_target}
    d["placement"] = {"candidates": [list(c) for c in sc.placement.candidates],
                      "spacing": sc.placement.spacing, "cover": sc.placement.cover,
                      "marker_kind": sc.placement.marker_kind.value, "existing": sc.placement.existing}
    return d


@contextlib.contextmanager
def _said_already():
    """Silence pefsim's own warnings while the scenario is read again to check it.

    They were said when the scenario was loaded (a route graph's repeated edge ids: Nav2's depot
    graph gave the same line three times in one ``pefsim place -o``).
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ScenarioWarning)
        yield


def write_scenario_with_markers(scenario: Scenario, result: PlacementResult, path: str | Path) -> Path:
    """Write ``scenario`` with the placement's markers as a new scenario TOML file.

    The scenario's source TOML (``scenario.text``) is re-serialised with its other keys kept
    (comments are lost) when it still describes ``scenario``; otherwise (a modified copy) the
    scenario object itself is written out, defaults included.
    The text is validated with :func:`scenarios.loads` before writing.

    Raises
    ------
    PlanningError
        The placement has fewer than k markers (nothing coverable).
    OutputError
        The file cannot be written.
    """
    import scenarios as scn

    if not result.fixable(scenario.sensor.markers_per_fix):
        raise PlanningError(f"placement chose {len(result.layout())} markers, fewer than markers_per_fix = "
                            f"{scenario.sensor.markers_per_fix}: nothing to write")
    data = None
    if scenario.text:
        try:
            with _said_already():
                if scn.loads(scenario.text, source=scenario.source) == scenario:
                    data = tomllib.loads(scenario.text)
        except (scn.PefsimError, tomllib.TOMLDecodeError):
            data = None
    if data is None:
        data = _scenario_dict(scenario)
    added = [_marker_dict(site_marker(i, p, f)) for (i, p), f in _facing_pairs(result)]
    if result.kept:
        # the installed markers stay as written: the file's own tables, the drawing's layer
        in_file = data.get("markers", []) if isinstance(data.get("markers"), list) else []
        written = {str(m.get("id")) for m in in_file if isinstance(m, dict)}
        from_drawing = [m for m in result.kept if m.id not in written]
        if from_drawing and not (isinstance(data.get("floorplan"), dict) and "marker_layer" in data["floorplan"]):
            in_file = in_file + [_marker_dict(m) for m in from_drawing]  # a copy written out: all of them
        data["markers"] = in_file + added
    else:
        data["markers"] = added
        if isinstance(data.get("floorplan"), dict):
            data["floorplan"].pop("marker_layer", None)  # the placed markers replace the drawing's too
    out = Path(path)
    if scenario.routes is not None and scenario.routes.source:
        data["routes"]["file"] = str(Path(scenario.routes.source).resolve())
    for table in ("floorplan", "routes"):  # files the scenario reads, named from where it is written
        if isinstance(data.get(table), dict) and isinstance(data[table].get("file"), str):
            data[table]["file"] = _relative(data[table]["file"], out.parent)
    data["description"] = _placed_description(scenario, result)
    text = tomli_w.dumps(data)
    with _said_already():
        scn.loads(text, source=str(out), base=out.parent)  # a bug here must not leave a broken file behind
    with output_errors(out, "write the placed scenario"):
        out.write_text(text, encoding="utf-8")
    return out


def _relative(file: str, folder: Path) -> str:
    """``file`` (absolute, as a loaded scenario's text has it) relative to ``folder`` where it can be."""
    import os

    try:
        return Path(os.path.relpath(Path(file).resolve(), folder.resolve())).as_posix()
    except ValueError:  # another drive: only the absolute name reaches it
        return file


def _placed_description(scenario: Scenario, result: PlacementResult) -> str:
    """Describe the placed scenario (the source's description counted its own markers)."""
    what = (f"{len(result.kept)} markers kept and {result.count} added" if result.kept
            else f"{result.count} markers")
    target = f" (cover target {result.target:g} m)" if math.isfinite(result.target) else ""
    return f"{scenario.name} with {what} placed by pefsim place{target}"


# numba keys a cache on its own file only: flush the kernels above when a file they inline changed
compiled.keep_fresh(__name__)
