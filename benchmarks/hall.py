"""Big floors: the 120 x 80 m hall (``benchmarks/hall_scenario.py``) through ``pefsim map/plan/place``.

Run: ``python benchmarks/hall.py [--skip-place] [--repeat N] [--pitch M] [--face-reflectors N]``
(the rack rows' spacing and the reflectors on each rack face: another hall). The hall is written into a
temporary folder (nothing is written elsewhere). Each command runs as a subprocess, measured by
``os.wait4``: wall time, CPU (user + sys) and peak RSS; ``map`` and ``plan`` run ``--repeat``
times (default 3) after a warm-up run, and the medians are printed.

Budgets (:data:`BUDGETS`, wall time on a quiet 2-core machine, numba's cache warm;
``benchmarks/commands.py`` has the cold start): ``map --resolution 0.05 --json`` (3.84 M cells)
<= 2 s; ``plan`` <= 2 s; ``place`` from the empty floor <= 60 s and <= 1.5 GB with at most 1.2 x
its lower bound. Each is printed against its figure: within where the wall time is, or where the
CPU time (user + sys) is: none of these commands waits on anything but its own threads, so on an
idle machine its wall time is at most its CPU time, and on a shared one the CPU time is the figure
that does not grow with the load. Where both are over and the load average is above 1, the
budget is not shown either way (the threads overlap on a quiet machine: its wall time is less
than the CPU time); over on a quiet machine is OVER. The machine may be shared: compare CPU
times, and the baselines measured in this same run:

- every command: ``pefsim plan --help`` (Python and the command line: no scenario, no kernel), the
  floor every command pays, printed as the command's CPU over the floor's;

- map: a vectorised numpy PEF (the plan's line-of-sight rule of planner.pef.sight written out for
  boxes and the reflectors' bodies, every visible pair scored) on a random subsample of free
  cells, as cells per second against the map's cells per second (the subprocess's wall time,
  all of it: imports, loading, the grid, the summary), the largest relative difference of tau
  on the subsample, and whether the two agree on which cells have no fix (tau = inf);
- place: the greedy cover against the improved solver (LP rounding and local search) on the
  same cover problem (the cover target the command reports), in process; for the default flat
  reflectors and for posts (``--skip-post`` leaves the posts out).

The last line is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

import numpy as np  # noqa: E402

ROOT = HERE.parent


BUDGETS = {"map_s": 2.0, "plan_s": 2.0, "place_s": 60.0, "place_ratio": 1.2, "place_mb": 1536.0}
"""The budgets of the module docstring: seconds (wall, quiet 2-core machine), x the lower bound, MB."""


def budget(name: str, wall: float, cpu: float) -> str:
    """Say whether a command's wall or CPU seconds are within its budget ``BUDGETS[name]`` (module docstring)."""
    limit = BUDGETS[name]
    if wall <= limit:
        return f"within {limit:g} s (wall)"
    if cpu <= limit:
        return f"within {limit:g} s by its CPU time (the wall time over it is the machine's load)"
    load = os.getloadavg()[0]
    if load > 1.0:
        # the CPU time bounds the quiet wall time from above only (the kernels' threads overlap)
        return (f"not shown at load {load:.1f}: wall and CPU both over {limit:g} s (CPU x{cpu / limit:.2f}); "
                "measure on a quiet machine")
    return f"OVER {limit:g} s (wall x{wall / limit:.2f} the budget)"


def bench_floor(folder: Path, repeat: int) -> dict:
    """``pefsim plan --help`` (no scenario, no kernel): the floor every command pays, median of ``repeat`` runs."""
    return median_of(repeat, ["plan", "--help"], folder)


def _load_hall_module():
    import importlib.util

    spec = importlib.util.spec_from_file_location("hall_scenario", HERE / "hall_scenario.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def measured(args: list[str], cwd: Path, **env_extra: str) -> dict:
    """Run ``python -m cli ARGS``: wall [s], CPU (user + sys, ``os.wait4``) [s], peak RSS [MB], exit, output."""
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""), **env_extra)
    with tempfile.TemporaryFile("w+") as fo, tempfile.TemporaryFile("w+") as fe:
        t0 = time.perf_counter()
        p = subprocess.Popen([sys.executable, "-m", "cli", *args], cwd=cwd, env=env, stdout=fo, stderr=fe)
        _, status, ru = os.wait4(p.pid, 0)
        wall = time.perf_counter() - t0
        p.returncode = os.waitstatus_to_exitcode(status)
        fo.seek(0)
        fe.seek(0)
        return {"wall_s": wall, "cpu_s": ru.ru_utime + ru.ru_stime, "rss_mb": ru.ru_maxrss / 1024.0,
                "code": p.returncode, "stdout": fo.read(), "stderr": fe.read()}


def _shadow_rows(m: np.ndarray, poly: np.ndarray, widen: float) -> np.ndarray | None:
    """Half-planes ``a x + b y + c < 0`` (rows) of convex ``poly``'s (V, 2, CCW) shadow from ``m``, widened.

    The shadow: the points beyond every edge turned to ``m``, inside the cone from ``m`` over the
    polygon's silhouette; every line moved out by ``widen`` [m] (mitred), as planner.pef.sight
    states it. None when ``m`` is inside.
    """
    e = np.roll(poly, -1, axis=0) - poly
    n = np.column_stack([e[:, 1], -e[:, 0]]) / np.hypot(e[:, 0], e[:, 1])[:, None]
    c = (n * poly).sum(1)
    facing = n @ m - c > 0.0
    if not facing.any():
        return None
    k = len(poly)
    first = next(i for i in range(k) if facing[i] and not facing[i - 1])
    last = next((i + 1) % k for i in range(k) if facing[i] and not facing[(i + 1) % k])
    rows = [np.array([n[i, 0], n[i, 1], -c[i]]) for i in np.flatnonzero(facing)]
    a, b = poly[first] - m, poly[last] - m
    rows.append(np.array([-a[1], a[0], a[1] * m[0] - a[0] * m[1]]))     # left of the first silhouette ray
    rows.append(np.array([b[1], -b[0], -(b[1] * m[0] - b[0] * m[1])]))  # right of the last
    rows = np.array(rows)
    rows[:, 2] -= widen * np.hypot(rows[:, 0], rows[:, 1])
    return rows


def _grown(poly: np.ndarray, by: float) -> np.ndarray:
    """Convex ``poly`` (V, 2, CCW) with every edge moved out by ``by`` [m] (corners where the moved lines meet)."""
    e = np.roll(poly, -1, axis=0) - poly
    n = np.column_stack([e[:, 1], -e[:, 0]]) / np.hypot(e[:, 0], e[:, 1])[:, None]
    c = (n * poly).sum(1) + by
    pn, pc = np.roll(n, 1, axis=0), np.roll(c, 1)
    det = pn[:, 0] * n[:, 1] - pn[:, 1] * n[:, 0]
    return np.column_stack([(pc * n[:, 1] - c * pn[:, 1]) / det, (c * pn[:, 0] - pc * n[:, 0]) / det])


def numpy_reference(sc, points: np.ndarray) -> np.ndarray:
    """Parallelogram tau at ``points`` (N, 2) [m], vectorised numpy, under the plan's line-of-sight rule.

    Axis-aligned box obstacles only. The rule of planner.pef.sight, written out here for boxes
    and the reflectors' round bodies (each its circumscribed octagon): range within
    ``max_range - margin``; a flat marker's incidence wedge and its mount face's wedge held
    within the margin; the segment clear of the marker's mount (Liang-Barsky against the box
    shrunk by BOX_SHRINK); every other box and every other body, grown by the physics ray's
    reach, outside the segment for every position within the margin (their shadows widened by
    the margin).
    """
    from planner.pef.sight import sight_rule
    from planner.pef.visibility import BOX_SHRINK

    rule = sight_rule(sc.sensor)
    mk = sc.marker_positions()
    normals = sc.marker_normals()
    boxes = np.array([[o.center[0] - o.size[0] / 2, o.center[1] - o.size[1] / 2,
                       o.center[0] + o.size[0] / 2, o.center[1] + o.size[1] / 2] for o in sc.obstacles])
    s = sc.sensor
    cos_inc = math.cos(s.max_incidence)
    x0, y0, x1, y1 = sc.workspace.bounds
    ang = np.pi / 8.0 + np.arange(8) * np.pi / 4.0
    octagon = rule.radius / math.cos(np.pi / 8.0) * np.column_stack([np.cos(ang), np.sin(ang)])
    reach = rule.reach - BOX_SHRINK
    # per marker: its mount boxes (within grow), its wedges (d.n >= off + |d| b), the shadows of the rest
    mounts, wedges, shadows = [], [], []
    for i, m in enumerate(mk):
        g = rule.grow - BOX_SHRINK
        on = ((m[0] >= boxes[:, 0] - g) & (m[0] <= boxes[:, 2] + g)
              & (m[1] >= boxes[:, 1] - g) & (m[1] <= boxes[:, 3] + g))
        w = []
        if np.any(normals[i]):
            w.append((normals[i], rule.wedge_offset(cos_inc), cos_inc))
        faces = []
        for bx in boxes[on]:
            for d, n in ((bx[0] - m[0], (-1.0, 0.0)), (m[0] - bx[2], (1.0, 0.0)),
                         (bx[1] - m[1], (0.0, -1.0)), (m[1] - bx[3], (0.0, 1.0))):
                along = (bx[1], bx[3], m[1]) if n[1] == 0.0 else (bx[0], bx[2], m[0])
                if abs(d) <= rule.radius and along[0] - rule.radius <= along[2] <= along[1] + rule.radius:
                    faces.append((abs(d), n))
        for d, n in ((m[0] - x0, (1.0, 0.0)), (x1 - m[0], (-1.0, 0.0)),
                     (m[1] - y0, (0.0, 1.0)), (y1 - m[1], (0.0, -1.0))):  # the border walls
            if abs(d) <= rule.radius:
                faces.append((abs(d), n))
        seen = []
        for _, n in sorted(faces):
            if n not in seen:
                seen.append(n)
        w += [(np.array(n), rule.offset, rule.slope) for n in seen[:2]]
        rows = []
        for bx in boxes[~on]:
            box = np.array([[bx[0], bx[1]], [bx[2], bx[1]], [bx[2], bx[3]], [bx[0], bx[3]]])
            if np.hypot(*np.maximum(0.0, np.maximum(bx[:2] - m, m - bx[2:]))) <= s.max_range + rule.margin:
                rows.append(_shadow_rows(m, _grown(box, reach), rule.margin))
        for j, other in enumerate(mk):
            if j != i and np.hypot(*(other - m)) <= s.max_range + rule.margin + rule.radius:
                rows.append(_shadow_rows(m, _grown(other + octagon, reach), rule.margin))
        mounts.append(boxes[on] - np.array([-BOX_SHRINK, -BOX_SHRINK, BOX_SHRINK, BOX_SHRINK]))
        wedges.append(w)
        shadows.append([r for r in rows if r is not None])
    out = np.full(len(points), np.inf)
    rho_of = lambda r: s.relative_error * r + s.absolute_error  # noqa: E731
    i_pair, j_pair = np.triu_indices(len(mk), 1)
    for lo in range(0, len(points), 100):
        p = points[lo:lo + 100]
        d = p[:, None, :] - mk[None, :, :]                     # (n, M, 2) marker -> point
        r = np.hypot(d[..., 0], d[..., 1])
        vis = r <= rule.usable_range(s.max_range)
        for i in range(len(mk)):
            di = d[:, i]
            for n, off, b in wedges[i]:
                dot = di @ n - off
                vis[:, i] &= (dot >= 0.0) & (dot * dot >= (di ** 2).sum(1) * b * b)
            # Liang-Barsky: the segment marker + t d, t in [0, 1], against each mount box (open)
            with np.errstate(divide="ignore", invalid="ignore"):
                for bx in mounts[i]:
                    t0, t1 = np.zeros(len(p)), np.ones(len(p))
                    for axis, (bmin, bmax) in enumerate(((bx[0], bx[2]), (bx[1], bx[3]))):
                        o, v = mk[i, axis], di[:, axis]
                        ta, tb = (bmin - o) / v, (bmax - o) / v
                        lo_t, hi_t = np.minimum(ta, tb), np.maximum(ta, tb)
                        inside = bmin < o < bmax
                        lo_t = np.where(v == 0, -np.inf if inside else np.inf, lo_t)
                        hi_t = np.where(v == 0, np.inf if inside else -np.inf, hi_t)
                        t0, t1 = np.maximum(t0, lo_t), np.minimum(t1, hi_t)
                    vis[:, i] &= ~(t0 < t1)
            for rows in shadows[i]:
                vis[:, i] &= ~np.all(p @ rows[:, :2].T + rows[:, 2] < 0.0, axis=1)
        u = d / np.where(r > 0, r, 1.0)[..., None]
        rho = rho_of(r)
        for c in range(len(p)):
            ok = vis[c, i_pair] & vis[c, j_pair]
            if not ok.any():
                continue
            a, b = i_pair[ok], j_pair[ok]
            cos = np.clip((u[c, a] * u[c, b]).sum(-1), -1.0, 1.0)
            sin = np.abs(u[c, a, 0] * u[c, b, 1] - u[c, a, 1] * u[c, b, 0])
            r1, r2 = rho[c, a], rho[c, b]
            with np.errstate(divide="ignore"):
                diag = 2.0 / sin * np.sqrt(r1 ** 2 + r2 ** 2 + 2 * r1 * r2 * np.abs(cos))
            out[lo + c] = diag.min()
    return out


def median_of(repeat: int, args: list[str], cwd: Path) -> dict:
    """:func:`measured` ``repeat`` times: the medians of wall, CPU and RSS, the last run's exit and output."""
    runs = [measured(args, cwd) for _ in range(max(1, repeat))]
    one = dict(runs[-1])
    for key in ("wall_s", "cpu_s", "rss_mb"):
        one[key] = float(np.median([r[key] for r in runs]))
    return one


def bench_map(folder: Path, hall: Path, n_ref: int, repeat: int = 3) -> dict:
    import scenarios
    from planner.pef.map import PEF

    measured(["map", str(hall), "--resolution", "2.0", "--json"], folder)  # numba cache warm-up
    m = median_of(repeat, ["map", str(hall), "--resolution", "0.05", "--json"], folder)
    summary = json.loads(m["stdout"])
    sc = scenarios.load(hall)
    pm = PEF(sc).grid(0.05)
    rng = np.random.default_rng(1)
    iy, ix = np.nonzero(pm.free)
    pick = rng.choice(len(iy), n_ref, replace=False)
    pts = np.column_stack([pm.x[ix[pick]], pm.y[iy[pick]]])
    t0 = time.perf_counter()
    ref = numpy_reference(sc, pts)
    t_ref = time.perf_counter() - t0
    ours = pm.tau[iy[pick], ix[pick]]
    both = np.isfinite(ref) & np.isfinite(ours)
    rel = float(np.max(np.abs(ours[both] - ref[both]) / ref[both])) if both.any() else 0.0
    cells = summary["cells"]
    return {"map_wall_s": m["wall_s"], "map_cpu_s": m["cpu_s"], "map_rss_mb": m["rss_mb"], "map_code": m["code"],
            "map_cells": cells, "map_cells_per_s": cells / m["wall_s"], "numpy_ref_points": n_ref,
            "numpy_ref_cells_per_s": n_ref / t_ref, "map_vs_numpy": cells / m["wall_s"] / (n_ref / t_ref),
            "ref_max_rel_diff": rel, "ref_inf_agree": bool(np.array_equal(np.isinf(ref), np.isinf(ours)))}


def bench_plan(folder: Path, hall: Path, repeat: int = 3) -> dict:
    measured(["plan", str(hall), "--json"], folder)  # numba cache warm-up
    m = median_of(repeat, ["plan", str(hall), "--json"], folder)
    chosen = json.loads(m["stdout"])["chosen"] if m["code"] == 0 else None
    return {"plan_wall_s": m["wall_s"], "plan_cpu_s": m["cpu_s"], "plan_rss_mb": m["rss_mb"],
            "plan_code": m["code"], "plan_chosen": chosen}


def bench_place(folder: Path, empty: Path, tag: str = "place") -> dict:
    """``pefsim place --json`` on ``empty``; the plain greedy cover of the same problem, in process.

    The count and the lower bound are both for the cover target the command reports (``target``:
    eps_max, or tighter when the tasks needed it), so their ratio compares like with like.
    """
    import scenarios
    from planner.placement import placement

    m = measured(["place", str(empty), "--json"], folder)
    res = json.loads(m["stdout"]) if m["stdout"] else {}
    sc = scenarios.load(empty)
    target = res.get("target") or sc.planning.eps_max
    t0 = time.perf_counter()
    g = placement.place(sc, eps_max=target, method="greedy")  # the command's problem: its sites refined, its widening
    t_greedy = time.perf_counter() - t0
    t = tag
    return {f"{t}_kind": sc.placement.marker_kind.value, f"{t}_wall_s": m["wall_s"], f"{t}_cpu_s": m["cpu_s"],
            f"{t}_rss_mb": m["rss_mb"], f"{t}_code": m["code"], f"{t}_target": res.get("target"),
            f"{t}_count": res.get("count"), f"{t}_lower_bound": res.get("lower_bound"),
            f"{t}_ratio": res["count"] / res["lower_bound"] if res.get("lower_bound") else None,
            f"{t}_method": res.get("method"), f"{t}_sites": res.get("sites"), f"{t}_points": res.get("points"),
            f"{t}_greedy_count": g.count, f"{t}_greedy_s": t_greedy}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skip-place", action="store_true", help="leave out pefsim place (the slow part)")
    ap.add_argument("--skip-post", action="store_true", help="place flat reflectors only, not posts too")
    ap.add_argument("--ref-points", type=int, default=400, help="cells of the numpy reference subsample")
    ap.add_argument("--repeat", type=int, default=3, help="runs of map and plan (medians printed)")
    ap.add_argument("--pitch", type=float, default=5.0, help="distance between rack rows [m] (default 5)")
    ap.add_argument("--face-reflectors", type=int, default=5, help="reflectors on each long rack face (default 5)")
    args = ap.parse_args()
    hs = _load_hall_module()
    shape = {"pitch": args.pitch, "face_markers": args.face_reflectors}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        hall, empty = hs.write_hall(folder, **shape), hs.write_hall(folder, markers=False, **shape)
        base = bench_floor(folder, args.repeat)
        r = {"floor_wall_s": base["wall_s"], "floor_cpu_s": base["cpu_s"], "load_start": os.getloadavg()[0]}
        print(f"floor, pefsim plan --help (median of {args.repeat}): {base['wall_s']:.2f} s wall, "
              f"{base['cpu_s']:.2f} s CPU; load average {r['load_start']:.1f}")
        r |= bench_map(folder, hall, args.ref_points, args.repeat)
        r["map_budget"] = budget("map_s", r["map_wall_s"], r["map_cpu_s"])
        print(f"map 0.05 m ({r['map_cells']} cells, median of {args.repeat}): {r['map_wall_s']:.2f} s wall, "
              f"{r['map_cpu_s']:.2f} s CPU (x{r['map_cpu_s'] / base['cpu_s']:.1f} the floor), "
              f"{r['map_rss_mb']:.0f} MB peak: {r['map_budget']}; {r['map_cells_per_s']:.3g} cells/s end to end "
              f"vs numpy reference {r['numpy_ref_cells_per_s']:.3g} cells/s (x{r['map_vs_numpy']:.0f}), "
              f"max rel diff {r['ref_max_rel_diff']:.1e}, inf cells agree {r['ref_inf_agree']}")
        r |= bench_plan(folder, hall, args.repeat)
        r["plan_budget"] = budget("plan_s", r["plan_wall_s"], r["plan_cpu_s"])
        last = 2 * (hs.n_rows(args.pitch) // 2 + 1)  # the task's goal dock
        print(f"plan D1 -> D{last} (median of {args.repeat}): {r['plan_wall_s']:.2f} s wall, "
              f"{r['plan_cpu_s']:.2f} s CPU (x{r['plan_cpu_s'] / base['cpu_s']:.1f} the floor), "
              f"{r['plan_rss_mb']:.0f} MB: {r['plan_budget']}; exit {r['plan_code']}, chosen {r['plan_chosen']}")
        if not args.skip_place:
            # the default sites on faces are flat reflectors; posts (seen from every side) are
            # the harder cover: more pairs per point, a weaker LP bound
            for tag, kind in (("place", None), ("place_post", "post"))[:1 if args.skip_post else 2]:
                floor = (empty if kind is None
                         else hs.write_hall(folder, markers=False, marker_kind=kind, **shape))
                one = bench_place(folder, floor, tag)
                r |= one
                g = {key[len(tag) + 1:]: v for key, v in one.items()}.__getitem__
                mb, ratio = BUDGETS["place_mb"], BUDGETS["place_ratio"]
                verdict = [budget("place_s", g("wall_s"), g("cpu_s")),
                           ("within" if g("rss_mb") <= mb else "OVER") + f" {mb:g} MB",
                           ("within" if g("ratio") is not None and g("ratio") <= ratio else "OVER")
                           + f" {ratio:g} x the bound"]
                r[f"{tag}_budget"] = "; ".join(verdict)
                print(f"{tag} (empty floor, {g('kind')} sites, {g('sites')} sites, {g('points')} points): "
                      f"{g('wall_s'):.1f} s wall, {g('cpu_s'):.1f} s CPU "
                      f"(x{g('cpu_s') / base['cpu_s']:.0f} the floor), "
                      f"{g('rss_mb'):.0f} MB; {g('count')} reflectors, lower bound {g('lower_bound')} at target "
                      f"{g('target')} m (x{g('ratio'):.3f}; {g('method')}): {r[f'{tag}_budget']}; greedy alone "
                      f"{g('greedy_count')} (x{g('greedy_count') / g('lower_bound'):.2f})")
        r["load_end"] = os.getloadavg()[0]
    print(json.dumps(r))
    return 0


if __name__ == "__main__":
    sys.exit(main())
