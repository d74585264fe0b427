"""The traffic-aware measurement schedule: each robot's fixes planned knowing where the others are.

Starting from every robot's schedule as if it drove alone and the fleet's predicted timeline,
each round gives every task a new schedule (:func:`planner.schedule.schedule.make_schedule` on
the chosen route's own speed profile) with the probability that other robots hide each marker
along it (:func:`planner.fleet.exposure.risk`), then chains and re-times the fleet (slow-downs
move the others' blocking). Rounds stop when no schedule changes, or after :data:`ROUNDS`.

What a risky fix is (``block_limit``): the single-failure test judges a run by the fixes that lose
one counted line of sight; a fix without a fallback that loses one breaks the run. The plan must
reach ``montecarlo.success_target``, so blocking may cost at most a share
:data:`BLOCK_SHARE` of the failure budget ``1 - success_target``: a fix whose subset is hidden
with a larger probability than that share is risky. The schedule then avoids such a subset where
another serves, and holds a fix that stays risky to the single-failure test (a fallback for each
marker, or its neighbours covering its loss), slowing down where it cannot (more fixes per
metre where the others are near). Where even the slowest fixes cannot pass, the task keeps the
schedule that avoids risky subsets without that test, and the unprotected exposure is reported
(:attr:`planner.fleet.exposure.RobotBlocking.expected_unprotected`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import partial

import numpy as np

from planner.fleet import exposure
from planner.fleet.sampled import sampled_drives
from planner.fleet.zones import predict_timeline
from planner.plan import Plan
from planner.routes.smoothing import speed_profile
from planner.schedule.clearance import ClearanceError, cleared_schedule
from planner.schedule.pathtime import Kinematics
from planner.schedule.search import StretchError
from scenarios.errors import PlanningError
from scenarios.schema import Scenario

ROUNDS = 3
"""Most rounds of re-scheduling against the others' timelines."""
EXEMPT_TRIES = 4
"""Most schedules tried for one task of a fleet with a declared spread, each exempting from the risk
the stretches where the last found no protected schedule (:func:`reschedule`)."""
EXEMPT_REACH = 0.5
"""How far either side of a stretch without a protected schedule the exemption reaches [m]: the
search names the sample where the error ran out; the fixes that could have served it lie within
a few fix gaps (0.2 m at 1 m/s and 5 Hz) before it."""
BLOCK_SHARE = 0.5
"""Share of the plan's failure budget ``1 - montecarlo.success_target`` one fix's blocking may take."""


@dataclass(frozen=True)
class TrafficNote:
    """How the traffic-aware schedule came about: rounds run, tasks left unprotected, the limit used."""

    rounds: int
    block_limit: float
    unprotected: tuple[tuple[str, int], ...]


def block_limit(scenario: Scenario) -> float:
    """Probability above which a fix's subset is risky (module docstring)."""
    return BLOCK_SHARE * (1.0 - scenario.montecarlo.success_target)


def _signature(plan: Plan) -> tuple:
    return tuple((round(f.s, 6), f.markers) for f in plan.schedule.fixes)


def _exempting(block, stretches: list[tuple[float, float]]):
    """``block`` with no risk within EXEMPT_REACH of ``stretches`` (arc lengths of the task [m])."""
    if not stretches:
        return block

    def masked(s: np.ndarray, xy: np.ndarray) -> np.ndarray:
        p = np.array(block(s, xy), dtype=float, copy=True)
        s = np.asarray(s, float)
        for a, b in stretches:
            p[:, (s >= a - EXEMPT_REACH) & (s <= b + EXEMPT_REACH)] = 0.0
        return p

    return masked


def reschedule(scenario: Scenario, robot, own: Scenario, pef, tracks, i: int, limit: float, risk_of=None
               ) -> tuple[list[Plan], list[int]]:
    """Schedule robot ``i``'s tasks anew against the others' ``tracks``; return them and the tasks left unprotected.

    ``risk_of(i, offset)`` gives a task's ``block`` argument instead of :func:`planner.fleet.exposure.risk`
    on ``tracks`` (a fleet with a declared spread: its sampled drives). Such a fleet's task is not
    left wholly unprotected where one stretch has no protected schedule: the stretches the search
    names are exempted from the risk (planned as if no robot were near) and the rest protected,
    up to EXEMPT_TRIES schedules; the task then counts as left unprotected.
    """
    plans, loose = [], []
    for q, (plan, off) in enumerate(zip(robot.plans, robot.offsets, strict=True)):
        cand = plan.candidates[plan.chosen]
        base = speed_profile(cand.path, own.robot)
        block = exposure.risk(scenario, tracks, i, float(off)) if risk_of is None else risk_of(i, float(off))
        # the body's clearance holds at the new speeds too (slowed where it needs, as the plan was)
        sched = None
        tries = EXEMPT_TRIES if risk_of is not None else 1
        exempt: list[tuple[float, float]] = []
        for _ in range(tries):
            try:
                sched = cleared_schedule(own, pef, cand.path.points, base, plan.start, plan.goal,
                                         block=_exempting(block, exempt), block_limit=limit)
                break
            except ClearanceError:
                raise
            except StretchError as exc:
                # no protected schedule through these stretches: plan them as if no robot were near
                exempt += [exc.stretch, *exc.more]
            except PlanningError:
                break
        if sched is None or exempt:
            loose.append(q)
        if sched is None:
            sched = cleared_schedule(own, pef, cand.path.points, base, plan.start, plan.goal, block=block,
                                     block_limit=limit, protect=False)
        plans.append(replace(plan, speed=sched.speed, schedule=sched))
    return plans, loose


def plan_traffic(scenario: Scenario, robots: list, owns: list[Scenario], pefs: list, zones_of, chain
                 ) -> TrafficNote:
    """Re-schedule ``robots`` (``FleetRobotPlan``, modified in place) knowing where the others are.

    Parameters
    ----------
    scenario : Scenario
    robots : list of FleetRobotPlan
        Planned alone, with their timelines.
    owns : list of Scenario
        Each robot's scenario (its own declared robot).
    pefs : list of PEF
        Each robot's PEF.
    zones_of, chain : callable
        :func:`planner.fleet.plan.zones_of` and :func:`planner.fleet.plan.chain`.
    """
    limit = block_limit(scenario)
    loose: dict[str, list[int]] = {}
    rounds = 0
    for rounds in range(1, ROUNDS + 1):  # noqa: B007 (the count of rounds run is reported)
        tracks = exposure.tracks_of(robots)
        risk_of = None
        if exposure.declares_spread(robots):
            # the spread's own draws through the fleet's zone gate: the model the prediction uses
            drives = sampled_drives(scenario, robots)
            risk_of = partial(exposure.risk_sampled, scenario, robots, drives)
        changed = False
        new = []
        for i, r in enumerate(robots):
            plans, lost = reschedule(scenario, r, owns[i], pefs[i], tracks, i, limit, risk_of)
            loose[r.name] = lost
            changed |= [_signature(p) for p in plans] != [_signature(p) for p in r.plans]
            new.append(plans)
        for r, plans in zip(robots, new, strict=True):
            r.plans = plans
            r.path, r.s, r.speed, r.offsets = chain(plans)
        timelines = predict_timeline(zones_of(robots), [Kinematics(r.s, r.speed) for r in robots],
                                     [r.start_time for r in robots])
        for r, tl in zip(robots, timelines, strict=True):
            r.timeline = tl
        if not changed:
            break
    return TrafficNote(rounds=rounds, block_limit=limit,
                       unprotected=tuple((name, q) for name, qs in loose.items() for q in qs))


def alone_time(robots: list) -> np.ndarray:
    """Each robot's drive time as if alone: its chained speed profile, no waits [s]."""
    return np.array([float(Kinematics(r.s, r.speed).t_v[-1]) for r in robots])
