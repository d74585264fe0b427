"""What a fleet's plan says per robot: tasks, expected blocking, waits, what traffic costs, fix density.

:func:`summarize` turns a :class:`planner.fleet.plan.FleetPlan` into one :class:`RobotSummary`
per robot; :class:`FleetPlanSummary` holds them with the plan and prints them (``pefsim plan`` on a
fleet).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from scenarios.jsonable import json_number
from scenarios.schema import Scenario

NEAR = 1.0
"""A place of a robot's path is *where the others are* when it lies within this arc length [m] of a
fix that its schedule planned as if alone would take with a risky subset (a blocking probability
above the limit of :func:`planner.fleet.traffic.block_limit`): where the others hide what a lone
robot counts on. The same places with traffic on and off, so their fix densities compare."""


@dataclass(frozen=True)
class RobotSummary:
    """One robot of a planned fleet.

    Attributes
    ----------
    name : str
    tasks : list of str
        ``A -> B`` per task, in driving order (``A -> P (park)``: the leg to its parking place).
    fixes : int
        Scheduled fixes.
    expected_blocked_los : float
        Expected number of scheduled lines of sight other robots hide.
    expected_blocked_fixes : float
        Expected number of fixes with one of them hidden.
    expected_unprotected : float
        Expected number of blocked fixes without a fallback for every marker.
    expected_traffic_los : float
        Expected number of scheduled lines of sight hidden by traffic that is not simulated (``routes.traffic``).
    wait_time : float
        Predicted time waiting for zones [s].
    time : float
        Predicted time from its start to its final dock, waits included [s].
    alone_time : float
        Its drive time planned as if alone (the single-robot schedule, no waits) [s].
    traffic_cost : float
        ``time - alone_time`` [s]: waits and the slow-downs of the traffic-aware schedule.
    near_length, far_length : float
        Length of its path where the others are (:data:`NEAR`) and elsewhere [m].
    fixes_per_m_near, fixes_per_m_far : float
        Scheduled fixes per metre there [1/m] (NaN where the length is 0).
    """

    name: str
    tasks: list[str]
    fixes: int
    expected_blocked_los: float
    expected_blocked_fixes: float
    expected_unprotected: float
    expected_traffic_los: float
    wait_time: float
    time: float
    alone_time: float
    traffic_cost: float
    near_length: float
    far_length: float
    fixes_per_m_near: float
    fixes_per_m_far: float

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def _near(s: np.ndarray, risky: np.ndarray, near: float) -> np.ndarray:
    """(N,) bool: each arc length of ``s`` within ``near`` of one in ``risky`` [m]."""
    s = np.asarray(s, float)
    out = np.zeros(len(s), bool)
    for x in np.asarray(risky, float):
        out |= np.abs(s - x) <= near
    return out


def summarize(scenario: Scenario, fleet) -> list[RobotSummary]:
    """Per robot of ``fleet`` (a :class:`~planner.fleet.plan.FleetPlan`) what its plan says."""
    from planner.fleet.traffic import block_limit

    limit = block_limit(scenario)
    out = []
    for r in fleet.robots:
        a = r.alone_blocking if r.alone_blocking is not None else r.blocking
        risky = a.s[a.p_fix > limit]
        fine = np.linspace(0.0, float(r.s[-1]), max(2, int(r.s[-1] / 0.01) + 1))
        near = _near(fine, risky, NEAR)
        near_len = float(near.mean() * r.s[-1])
        far_len = float(r.s[-1]) - near_len
        b = r.blocking
        fix_near = _near(b.s, risky, NEAR)
        n_near, n_far = int(fix_near.sum()), int((~fix_near).sum())
        out.append(RobotSummary(
            name=r.name, tasks=[f"{p.start} -> {p.goal}" + (" (park)" if r.park is not None and q == len(r.plans) - 1
                                                            else "") for q, p in enumerate(r.plans)], fixes=len(b.s),
            expected_blocked_los=b.expected_blocked_los, expected_blocked_fixes=b.expected_blocked_fixes,
            expected_unprotected=b.expected_unprotected, expected_traffic_los=float(b.p_traffic.sum()),
            wait_time=float(r.timeline.wait_time), time=r.time, alone_time=float(r.alone_time),
            traffic_cost=r.time - float(r.alone_time), near_length=near_len, far_length=far_len,
            fixes_per_m_near=n_near / near_len if near_len > 0 else float("nan"),
            fixes_per_m_far=n_far / far_len if far_len > 0 else float("nan")))
    return out


def fleet_density(summaries: list[RobotSummary]) -> tuple[float, float]:
    """Scheduled fixes per metre of the whole fleet where the others are and elsewhere [1/m].

    Pooled over the robots: fixes near the others over the length near them, likewise
    elsewhere (the places are the same with traffic on and off, :data:`NEAR`), so that the
    traffic-aware and the alone schedules compare. NaN where the length is 0.

    Parameters
    ----------
    summaries : list of RobotSummary

    Returns
    -------
    near, far : float
    """
    near_len = sum(s.near_length for s in summaries)
    far_len = sum(s.far_length for s in summaries)
    # each robot's count is its density times its length (NaN where its length is 0: no fixes there)
    near = sum(s.fixes_per_m_near * s.near_length for s in summaries if s.near_length > 0)
    far = sum(s.fixes_per_m_far * s.far_length for s in summaries if s.far_length > 0)
    return (near / near_len if near_len > 0 else float("nan"), far / far_len if far_len > 0 else float("nan"))


@dataclass(frozen=True)
class FleetPlanSummary:
    """A planned fleet as ``pefsim.plan`` returns it: the plan, one :class:`RobotSummary` per robot, the totals.

    Attributes
    ----------
    scenario : str
        The scenario's name.
    eps_max : float
        Its error budget [m].
    fleet : planner.fleet.plan.FleetPlan
        Per robot its plans, timeline and predicted blocking.
    robots : list of RobotSummary
        Per robot what its plan says, in ``scenario.robots`` order.
    """

    scenario: str
    eps_max: float
    fleet: Any
    robots: list[RobotSummary]

    @property
    def traffic(self) -> bool:
        """Whether the schedules are traffic-aware (False: each planned as if its robot drove alone)."""
        return self.fleet.traffic

    def to_dict(self) -> dict[str, Any]:
        """Return the summary as a JSON-ready dict (inf and NaN as None): per robot and the fleet's fix densities."""
        near, far = fleet_density(self.robots)
        return {"scenario": self.scenario, "traffic": self.traffic,
                "robots": [{k: json_number(v) for k, v in r.to_dict().items()} for r in self.robots],
                "fleet": {"fixes_per_m_near": json_number(near), "fixes_per_m_far": json_number(far)}}

    def lines(self) -> list[str]:
        """Return the printout: a head line, a row per robot and one for the fleet, what is unprotected, a legend."""
        rows = self.robots
        mode = "traffic-aware schedules" if self.traffic else "each scheduled as if it drove alone"
        out = [f"{self.scenario}: a fleet of {len(rows)} robots, eps_max {self.eps_max * 1000:g} mm, {mode}"]
        head = (f"{'robot':<8} {'tasks':<22} {'fixes':>5} {'E blocked LOS':>13} {'E blocked fixes':>15} "
                f"{'unprotected':>11} {'wait[s]':>7} {'time[s]':>7} {'alone[s]':>8} {'traffic[s]':>10} "
                f"{'fix/m near':>10} {'fix/m else':>10}")
        out += [head, "-" * len(head)]
        for r in rows:
            tasks = ", ".join(r.tasks)
            tasks = tasks if len(tasks) <= 22 else tasks[:19] + "..."
            out.append(f"{r.name:<8} {tasks:<22} {r.fixes:5d} {r.expected_blocked_los:13.2f} "
                       f"{r.expected_blocked_fixes:15.2f} {r.expected_unprotected:11.2f} {r.wait_time:7.1f} "
                       f"{r.time:7.1f} {r.alone_time:8.1f} {r.traffic_cost:+10.1f} {r.fixes_per_m_near:10.2f} "
                       f"{r.fixes_per_m_far:10.2f}")
        near, far = fleet_density(rows)
        los, fixes = sum(r.expected_blocked_los for r in rows), sum(r.expected_blocked_fixes for r in rows)
        out.append(f"{'fleet':<8} {'':<22} {sum(r.fixes for r in rows):5d} {los:13.2f} {fixes:15.2f} "
                   f"{sum(r.expected_unprotected for r in rows):11.2f} {'':>7} {'':>7} {'':>8} {'':>10} "
                   f"{near:10.2f} {far:10.2f}")
        note = self.fleet.note
        if note is not None and note.unprotected:
            left = ", ".join(f"{name} task {q}" for name, q in note.unprotected)
            out.append(f"not protected (no schedule survives a hidden marker there even slowed): {left}")
        out.append("E: expected over the timing spread of the robots; unprotected: blocked fixes without a fallback "
                   "for every marker; traffic: time - alone (waits and slow-downs); near: within 1 m of a fix that, "
                   "planned alone, others would likely hide; fleet: the robots' fixes near and elsewhere over their "
                   "lengths there")
        return out

    def __str__(self) -> str:
        return "\n".join(self.lines())
