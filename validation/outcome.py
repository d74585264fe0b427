"""What the runs did, first: one line per cause that made runs fail, and the ``runs`` check.

A run that touched anything but the floor, stuck or deadlocked (its status, :mod:`sim.episode.outcome`)
did not do what was asked, whatever its statistics say; a run that crashed did not run to its end.
:func:`causes` names each such cause once, with how many runs it took and where it first struck;
:func:`runs` fails whenever one run is not ``ok`` (a contact, a stall or a deadlock cannot happen to a
plan that holds: false-alarm probability 0). :func:`waits` compares a fleet's predicted waits with the
simulated ones. All are pure functions of the runs table.
"""

from __future__ import annotations

import math

import numpy as np

from validation.data import CheckResult, CheckStatus, SweepData


def _rows(data: SweepData) -> list[dict]:
    out = data.runs.outcome
    return [] if out is None else out.to_pylist()


def _run_of(data: SweepData, unit: int) -> int:
    """Return the sweep's run of a row (a fleet's rows are numbered per robot and run, ``fleet_units``)."""
    n = len(data.scenario.robots)
    return unit // n if n else unit


def _task(data: SweepData, row: dict) -> str:
    sc, t = data.scenario, row.get("task")
    who = f"robot {row['robot']}, " if row.get("robot") else ""
    if t is None or not 0 <= t < len(sc.tasks):
        return who.rstrip(", ")
    return f"{who}task {sc.tasks[t].start} -> {sc.tasks[t].goal}"


def _at(x, y, s=None) -> str:
    where = f"({x:.2f}, {y:.2f})" if x is not None and y is not None and math.isfinite(x) else "(?)"
    return where + (f" s={s:.1f} m" if s is not None and math.isfinite(s) else "")


def _count(data: SweepData, rows: list[dict]) -> str:
    """``k of n runs`` (a fleet's runs, not its robot rows)."""
    every = {_run_of(data, r["run"]) for r in _rows(data)}
    hit = {_run_of(data, r["run"]) for r in rows}
    return f"{len(hit)} of {len(every)} runs"


def causes(data: SweepData) -> list[str]:
    """Return one line per cause that made runs fail: contact, stall, deadlock, crash (in that order).

    Each line counts the runs it struck and says where it first did (the lowest run with it).
    """
    rows = _rows(data)
    lines: list[str] = []
    if not rows:   # tables built by hand without the runs' outcome
        return lines
    hit = [r for r in rows if (r.get("collisions") or 0) > 0]
    if hit:
        r = hit[0]
        what = r.get("contact_with") or "something"
        kind = ("an obstacle" if what.startswith("obstacle") else "a wall" if "wall" in what
                else "a marker post" if what.startswith("marker") else "another robot" if what.startswith("robot")
                else "something")
        t = r.get("contact_t")
        when = f" t={t:.1f} s" if t is not None and math.isfinite(t) else ""
        at = _at(r.get("contact_x"), r.get("contact_y"), r.get("contact_s"))
        lines.append(f"{_count(data, hit)} touched {kind}; first at {at}{when}, {_task(data, r)} ({what}, "
                     f"{r['collisions']} contact(s) in that run)")
    stuck = [r for r in rows if r.get("stuck")]
    if stuck:
        r = stuck[0]
        at = _at(r.get("stall_x"), r.get("stall_y"), r.get("stall_s"))
        lines.append(f"{_count(data, stuck)} stuck: no progress along the path for {r['stall_time']:.1f} s "
                     f"(bound {r['stuck_bound']:.1f} s) from {at}, {_task(data, r)}")
    dead = [r for r in rows if r.get("deadlocked")]
    if dead:
        r = dead[0]
        who = r.get("robot") or "the robot"
        other = f" for {r['waited_for']}" if r.get("waited_for") else ""
        lines.append(f"{_count(data, dead)} deadlocked: {who} waited {r['longest_wait']:.1f} s at "
                     f"{_at(r.get('wait_x'), r.get('wait_y'))}{other} (bound {r['wait_bound']:.1f} s)")
    crashed = [r for r, ran in zip(rows, data.runs.ok.tolist(), strict=True) if not ran]
    if crashed:
        lines.append(f"{_count(data, crashed)} crashed: {crashed[0]['status']}")
    return lines


def _seconds(v) -> str:
    return f"{v:.1f} s" if v is not None and math.isfinite(v) else "none"


def _spread(v: np.ndarray) -> str:
    """``median m (95 % q, max M)`` of per-run waits [s], NaN (a run without the column) left out."""
    v = v[np.isfinite(v)]
    if not len(v):
        return "not recorded"
    return f"median {np.median(v):.1f} s (95 % {np.quantile(v, 0.95):.1f} s, max {v.max():.1f} s)"


def waits(data: SweepData) -> list[str]:
    """Return one line per fleet robot: the plan's waits for zones against the simulated ones [s].

    Both its waits together (the plan's ``Timeline.wait_time`` against the run's ``wait_time``) and
    its longest unbroken one (the plan's against the run's ``longest_wait``, what the deadlock bound
    of :mod:`sim.episode.outcome` grows from), each simulated one as median, 95 % quantile and
    maximum over the runs. Sweeps written before the plan's total was recorded print ``none`` for it.
    """
    rows = [r for r in _rows(data) if r.get("robot") and r.get("longest_wait") is not None]
    out = []
    for name in dict.fromkeys(r["robot"] for r in rows):
        mine = [r for r in rows if r["robot"] == name]

        def col(key: str, mine=mine) -> np.ndarray:
            return np.array([math.nan if r.get(key) is None else r[key] for r in mine], float)

        out.append(f"{name}: in all predicted {_seconds(mine[0].get('predicted_wait_time'))}, simulated "
                   f"{_spread(col('wait_time'))}; longest predicted {_seconds(mine[0].get('predicted_wait'))}, "
                   f"simulated {_spread(col('longest_wait'))}; {len(mine)} runs")
    return out


def runs_why_not(data: SweepData) -> str | None:
    if data.runs.outcome is None or "status" not in data.runs.outcome.column_names or not len(data.runs):
        return "the sweep has no run status"
    return None


def runs(data: SweepData, alpha: float, rng: np.random.Generator) -> CheckResult:
    """Check that every run ran to its end without a contact, a stall or a deadlock (false alarm 0).

    A plan the robot can drive never touches anything, never stalls and never waits past its bound
    (:mod:`sim.episode.outcome`); one run that does is a defect, whatever the run count.
    """
    status = np.asarray(data.runs.outcome.column("status").to_pylist(), dtype=object)
    n = len(status)
    counts = {s: int(np.sum(status == s)) for s in ("collided", "stuck", "deadlocked")}
    crashed = int(np.sum(~data.runs.ok))
    bad = sum(counts.values()) + crashed
    found = causes(data)
    detail = ("runs (robot runs in a fleet) that touched anything but the floor, made no progress for longer "
              "than their bound or waited for a zone past theirs, or crashed")
    if found:
        detail += ": " + "; ".join(found)
    return CheckResult("runs", CheckStatus.FAIL if bad else CheckStatus.PASS, f"{n - bad}/{n} ok",
                       "every run ok", 0.0, detail, {**counts, "crashed": crashed, "runs": n})
