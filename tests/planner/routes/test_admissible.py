"""One admissibility, continuous along the path (:mod:`planner.routes.admissible`).

Property (hypothesis, random small worlds of ``pefsim worlds``): where the evaluator finds τ finite
at a sample of a route segment (the samples ``export`` and ``place`` judge, ``planning.resolution``
apart), the plain PEF is finite at every point of the stretch the sample stands for, checked at
an eighth of the spacing: no gap between samples hides a lost line of sight. This holds exactly
(no tolerance): a marker counted at a sample is seen from every point within half the spacing
(the rule's margin widened by it), and each checked point lies within half the spacing of a
sample. Negative control: with the widening switched off, a segment whose samples straddle a
pillar's shadow (:data:`GAP_TOML`) is called admissible and the check finds the gap.
"""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import scenarios
from planner.pef.map import PEF
from planner.routes import admissible
from planner.routes.admissible import judge_paths
from planner.routes.criteria import sample_polyline
from planner.routes.edges import segment_reports
from planner.worlds import world_rng
from scenarios.worlds import SMALLEST_MAX_SIZE, draw_world


def world(index: int, eps: float = 0.05) -> scenarios.Scenario:
    drawn = draw_world(world_rng(46, index), f"random-46-{index:03d}", max_size=SMALLEST_MAX_SIZE)
    drawn.data["planning"]["eps_max"] = eps
    return scenarios.from_dict(drawn.data, source=f"random-46-{index:03d}.toml")


def gaps(sc: scenarios.Scenario) -> list[tuple[float, float]]:
    """Points between samples where the plain PEF is inf though the judged sample next to them is finite."""
    pef = PEF(sc)
    net = sc.routes
    res = sc.planning.resolution
    verdicts = judge_paths(sc, pef, [np.array([net.nodes[a], net.nodes[b]], float) for a, b in net.segments], res)
    out = []
    for v in verdicts:
        fine, _ = sample_polyline(v.points, res / 8)
        # the sample each fine point is nearest to stands for it
        near = np.argmin(np.hypot(*(fine[:, None, :] - v.points[None, :, :]).transpose(2, 0, 1)), axis=1)
        tau = np.asarray(pef.at(fine).tau, float)
        bad = np.isfinite(v.tau[near]) & ~np.isfinite(tau)
        out += [tuple(map(float, p)) for p in fine[bad]]
    return out


@settings(max_examples=2, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(index=st.integers(min_value=0, max_value=40))
def test_no_gap_between_samples(index):
    assert gaps(world(index)) == []


def test_export_uses_the_one_admissibility():
    """``export``'s segment verdicts are the evaluator's, sample for sample."""
    sc = world(0)
    pef = PEF(sc)
    reports = segment_reports(sc, pef)
    net = sc.routes
    verdicts = judge_paths(sc, pef, [np.array([net.nodes[a], net.nodes[b]], float) for a, b in net.segments])
    assert len(reports) == len(verdicts) > 0
    for r, v in zip(reports, verdicts, strict=True):
        assert r.max_tau == float(v.tau[v.worst])
        assert (not net.why_not(r.index) and r.admissible) == (v.admissible and r.min_clearance >= sc.robot.radius)


GAP_TOML = """
name = "gap"
[workspace]
size = [10.0, 6.0]
[[obstacles]]
center = [5.05, 3.0]
size = [0.03, 0.03]
[[markers]]
id = "M1"
position = [5.05, 5.0]
[[markers]]
id = "M2"
position = [9.0, 5.0]
[sensor]
relative_error = 1e-3
absolute_error = 0.002
max_range = 11.0
[robot]
radius = 0.2
wheel_base = 0.3
wheel_radius = 0.04
[planning]
eps_max = 1.0
resolution = 0.1
[routes]
nodes = { a = [3.0, 1.0], b = [9.5, 1.0] }
segments = [["a", "b"]]
"""
"""A segment whose samples (x = 3.0, 3.1, ...) straddle the shadow a 3 cm pillar casts from M1 (x
in about 5.01-5.09): with two markers, τ = inf in it and finite at every sample."""


def test_a_shadow_between_samples_is_seen():
    sc = scenarios.loads(GAP_TOML, "gap.toml")
    assert gaps(sc) == []
    (rep,) = segment_reports(sc, PEF(sc))
    assert not rep.admissible and "tau inf" in rep.why_not, rep.why_not


def test_negative_control_unwidened_samples_hide_the_shadow(monkeypatch):
    """Without the widening the samples alone call the segment admissible, over a stretch with τ = inf."""
    monkeypatch.setattr(admissible, "stretch_widen", lambda spacing: 0.0)
    sc = scenarios.loads(GAP_TOML, "gap.toml")
    (rep,) = segment_reports(sc, PEF(sc))
    assert rep.admissible
    assert len(gaps(sc)) > 0
