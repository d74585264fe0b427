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
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np
import tomli_w

from jit import compiled
from planner.pef import kernels as pef_kernels
from planner.placement.cover import MILP_TIME_LIMIT, PairCover, solve_exact
from planner.placement.facing import site_facings, site_marker
from planner.placement.redundant import greedy_robust
from planner.placement.sites import candidate_sites, cover_points
from scenarios.errors import PlanningError, output_errors
from scenarios.schema import Marker, MarkerKind, PefModel, Scenario

MILP_MAX_SITES = 150
"""Largest number of useful sites (in some good pair) for which ``auto`` runs integer rounds."""
DENSE_KEYS = 20_000_000
"""Largest sites**2 for which the pairs are numbered through a dense table (5 bytes a key)."""
SEARCH_STREAM = 15
"""Spawn key of the local search's random stream under the scenario seed."""
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
        No placement among the sites covers the coverable points with fewer markers.
    optimal : bool
        ``count`` is proven minimal (MILP solved to optimality).
    uncovered : ndarray, shape (U, 2)
        Points no subset of sites can cover [m].
    method : str
        ``milp`` (integer rounds ran), ``search`` (LP rounding and local search only), or
        ``greedy`` (nothing to cover); ``+greedy`` when redundancy completed it greedily.
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


@compiled.njit(parallel=True, cache=True)
def _good_pairs_kernel(px, py, sx, sy, vis, model, rel, ab, tan_xi, chi2, limit, offsets, out_j, out_l):
    """Count (``offsets`` None-like: size 0) or list the good pairs of every point.

    ``vis`` (N, S); pairs ``(j, l)``, j < l, both visible and tau < limit. Returns the counts.
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
                if t < limit:
                    if offsets.size:
                        out_j[offsets[i] + c] = seen[a]
                        out_l[offsets[i] + c] = seen[z]
                    c += 1
        counts[i] = c
    return counts


def _site_scenario(scenario: Scenario, sites: np.ndarray) -> Scenario:
    """Return a copy of ``scenario`` whose markers are the sites (flat on faces, see :mod:`.facing`)."""
    markers = tuple(site_marker(f"S{j}", p, f) for j, (p, f) in enumerate(zip(sites, site_facings(scenario, sites),
                                                                            strict=True)))
    return dataclasses.replace(scenario, markers=markers)


def _model(scenario: Scenario) -> PefModel:
    m = scenario.planning.pef_model
    return PefModel.STRIPS if m is PefModel.EXACT else m


def build_cover(scenario: Scenario, points: np.ndarray, sites: np.ndarray, eps_max: float):
    """Good pairs of sites at every point.

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
    vis = np.ascontiguousarray(scenario_visible_points(_site_scenario(scenario, sites), points)[0].T)
    model = _model(scenario)
    kernel_model = {PefModel.PARALLELOGRAM: pef_kernels.PARALLELOGRAM, PefModel.STRIPS: pef_kernels.STRIPS,
                    PefModel.GDOP: pef_kernels.GDOP}[model]
    sensor = scenario.sensor
    tan_xi = math.tan(sensor.bearing_error) if sensor.uses_bearing else 0.0
    chi2 = float(chi2_2dof_ppf(scenario.planning.gdop_level))
    args = (np.ascontiguousarray(points[:, 0]), np.ascontiguousarray(points[:, 1]),
            np.ascontiguousarray(sites[:, 0]), np.ascontiguousarray(sites[:, 1]), vis, kernel_model,
            float(sensor.relative_error), float(sensor.absolute_error), tan_xi, chi2,
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
        Sensor, obstacles, PEF model, k, and the defaults below.
    points : ndarray, shape (N, 2), optional
        Points to cover [m]; default :func:`planner.placement.sites.cover_points`.
    sites : ndarray, shape (S, 2), optional
        Candidate sites [m]; default :func:`planner.placement.sites.candidate_sites`.
    eps_max : float, optional
        Allowed error [m]; default ``scenario.planning.eps_max``. With
        ``planning.redundancy`` = 1 every covered point keeps a pair under it with any one
        chosen marker blocked (:mod:`planner.placement.redundant`: the exact redundancy-0
        cover completed greedily; its count is the lower bound).
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
    cov, coverable = build_cover(scenario, pts, cand, eps)
    chosen, bound, optimal, used = np.zeros(len(cand), dtype=bool), 0.0, True, "greedy"
    if coverable.any():
        used_sites = int(np.unique(np.concatenate([cov.pj, cov.pl])).size)
        integral = method == "milp" or (method == "auto" and used_sites <= MILP_MAX_SITES)
        chosen, bound, optimal = solve_exact(cov, k, time_limit, integral=integral, xy=cand,
                                             seed=_search_seed(scenario.seed))
        used = "milp" if integral else "search"
        bound = max(bound, float(k))
        if redundancy > 0:
            start = chosen
            chosen, target = greedy_robust(cov, k, redundancy, start)
            coverable = coverable.copy()
            coverable[np.flatnonzero(coverable)] = target[cov.row_of]
            bound = max(float(start.sum()) if optimal else bound, float(k + redundancy))
            optimal, used = False, used + "+greedy"
    idx = np.flatnonzero(chosen)
    lower = min(math.ceil(bound - 1e-6), len(idx))
    markers = [(f"P{n + 1}", (float(cand[j, 0]), float(cand[j, 1]))) for n, j in enumerate(idx)]
    facing = site_facings(scenario, cand[idx]) if len(idx) else []
    return PlacementResult(markers=markers, count=len(idx), lower_bound=lower,
                           optimal=bool(optimal and lower == len(idx)), uncovered=pts[~coverable],
                           method=used, sites=cand, points=pts, chosen=idx, facings=tuple(facing),
                           redundancy=redundancy)


def scenario_with_markers(scenario: Scenario, result: PlacementResult) -> Scenario:
    """Return a copy of ``scenario`` whose markers are the placement's (flat ones facing out of their faces)."""
    return dataclasses.replace(scenario, markers=tuple(site_marker(i, p, f) for (i, p), f in _facing_pairs(result)))


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
               "markers": [_marker_dict(m) for m in sc.markers],
               "sensor": spec(sc.sensor), "robot": spec(sc.robot)}
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
                      "marker_kind": sc.placement.marker_kind.value}
    return d


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

    if result.count < scenario.sensor.markers_per_fix:
        raise PlanningError(f"placement chose {result.count} markers, fewer than markers_per_fix = "
                            f"{scenario.sensor.markers_per_fix}: nothing to write")
    data = None
    if scenario.text:
        try:
            if scn.loads(scenario.text, source=scenario.source) == scenario:
                data = tomllib.loads(scenario.text)
        except (scn.PefsimError, tomllib.TOMLDecodeError):
            data = None
    if data is None:
        data = _scenario_dict(scenario)
    data["markers"] = [_marker_dict(site_marker(i, p, f)) for (i, p), f in _facing_pairs(result)]
    if scenario.routes is not None and scenario.routes.source:
        # a relative graph file would be looked up beside the new scenario: name it absolutely
        data["routes"]["file"] = str(Path(scenario.routes.source).resolve())
    if isinstance(data.get("floorplan"), dict):
        data["floorplan"].pop("marker_layer", None)  # the placed markers replace the drawing's too
    text = tomli_w.dumps(data)
    out = Path(path)
    scn.loads(text, source=str(out), base=out.parent)  # a bug here must not leave a broken file behind
    with output_errors(out, "write the placed scenario"):
        out.write_text(text, encoding="utf-8")
    return out


# numba keys a cache on its own file only: flush the kernels above when a file they inline changed
compiled.keep_fresh(__name__)
