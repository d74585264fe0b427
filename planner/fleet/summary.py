"""What a fleet's plan says per robot: tasks, expected blocking, waits, what traffic costs, fix density.

:func:`summarize` turns a :class:`planner.fleet.plan.FleetPlan` into one :class:`RobotSummary`
per robot (``pefsim plan`` on a fleet prints them).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

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
        ``A -> B`` per task, in driving order.
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
            name=r.name, tasks=[f"{p.start} -> {p.goal}" for p in r.plans], fixes=len(b.s),
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
