"""The PEF along each segment of a route network: what an exported route graph carries.

Each segment is judged by the one admissibility of ``place``, ``plan`` and ``watch``
(:func:`planner.routes.admissible.judge_paths`: samples at the PEF resolution, each standing for
its stretch) and the visibility over the same stretches: the largest and the arc-length mean τ,
the fewest markers visible, the clearance; admissible as a route is: τ < ε_max everywhere
along it, clearance ≥ the robot radius, and not marked inadmissible when the graph was read (an
imported edge too close to an obstacle).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.routes import criteria
from planner.routes.admissible import judge_paths, stretch_widen
from scenarios.schema import Scenario


@dataclass(frozen=True)
class SegmentReport:
    """The PEF along one segment of the route network.

    Attributes
    ----------
    index : int
        Index into ``scenario.routes.segments``.
    max_tau, mean_tau : float
        Largest and arc-length mean τ along the segment [m]; inf where a sample has no fix.
    min_visible : int
        Fewest markers visible from a sample of the segment.
    min_clearance : float
        Smallest distance to an obstacle or wall [m].
    why_not : str
        Why the segment is not admissible ("" if it is): the reason it was marked when read,
        else τ or clearance, naming the value and where.
    points : ndarray, shape (N, 2)
        The samples [m].
    """

    index: int
    max_tau: float
    mean_tau: float
    min_visible: int
    min_clearance: float
    why_not: str
    points: np.ndarray

    @property
    def admissible(self) -> bool:
        return not self.why_not


def segment_reports(scenario: Scenario, pef) -> list[SegmentReport]:
    """Evaluate the PEF along every segment of ``scenario.routes`` (none without a network).

    Parameters
    ----------
    scenario : Scenario
    pef : planner.pef.map.PEF
        The PEF (``at`` and ``visible``).

    Returns
    -------
    list of SegmentReport
        In segment order.
    """
    net = scenario.routes
    if net is None or not net.segments:
        return []
    res = scenario.planning.resolution
    radius = scenario.robot.radius
    verdicts = judge_paths(scenario, pef, [np.array([net.nodes[a], net.nodes[b]], float) for a, b in net.segments],
                           res)
    pts = np.vstack([v.points for v in verdicts])
    # one visibility evaluation for every segment: the kernels work best on many points
    vis_all = (pef.visible(pts, widen=stretch_widen(res)).sum(axis=1) if len(scenario.markers)
               else np.zeros(len(pts), int))
    clear_all = criteria.clearance(pts, scenario)
    out, start = [], 0
    for i, verdict in enumerate(verdicts):
        p, s, tau = verdict.points, verdict.s, verdict.tau
        stop = start + len(p)
        vis, clear = vis_all[start:stop], clear_all[start:stop]
        start = stop
        worst = verdict.worst
        length = float(s[-1])
        if np.all(np.isfinite(tau)) and length > 0:
            mean = float(np.sum(np.diff(s) * 0.5 * (tau[1:] + tau[:-1])) / length)
        else:
            mean = math.inf if not np.all(np.isfinite(tau)) else float(tau.mean())
        why = net.why_not(i) or verdict.why_not
        if not why and clear.min() < radius:
            why = f"clearance {clear.min():.3f} m < robot radius {radius:g} m"
        out.append(SegmentReport(index=i, max_tau=float(tau[worst]), mean_tau=mean, min_visible=int(vis.min()),
                                 min_clearance=float(clear.min()), why_not=why, points=p))
    return out
