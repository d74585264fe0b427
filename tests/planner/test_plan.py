"""plan_route: brute-force route choice, admissibility of chosen paths, infeasible requests."""

from __future__ import annotations

import dataclasses
import itertools
import math
from types import SimpleNamespace

import numpy as np
import pytest

import scenarios
from planner import plan
from planner.pef.map import PEF
from planner.routes import candidates, criteria
from scenarios.errors import PlanningError, ScenarioError
from scenarios.route_network import RouteNetwork
from scenarios.schema import Dock, Obstacle, Weights


class FakePEF:
    """An analytic τ field (no markers involved), to test the planner on its own."""

    def __init__(self, fn):
        self.fn = fn

    def at(self, points, widen=0.0):
        p = np.asarray(points, float).reshape(-1, 2)
        return SimpleNamespace(tau=self.fn(p))

    def stretch_bound(self, points, widen, target=np.inf):
        """Return the field itself: it is given, not a marker geometry whose change over a stretch is bounded."""
        return self.fn(np.asarray(points, float).reshape(-1, 2))

    def grid(self, resolution=None):
        res = resolution or 0.1
        x = (np.arange(int(round(20 / res))) + 0.5) * res
        y = (np.arange(int(round(12 / res))) + 0.5) * res
        xx, yy = np.meshgrid(x, y)
        tau = self.fn(np.column_stack([xx.ravel(), yy.ravel()])).reshape(xx.shape)
        return SimpleNamespace(x=x, y=y, tau=tau, free=np.ones_like(tau, bool), cell_size=(res, res))


def bumpy_tau(p):
    """Slowly varying τ with a bump near (10, 3) and a forbidden one on segment s-u."""
    x, y = p[:, 0], p[:, 1]
    return (0.003 + 0.002 * y / 12 + 0.006 * np.exp(-((x - 10) ** 2 + (y - 3) ** 2) / 4)
            + 0.03 * np.exp(-((x - 12.5) ** 2 + (y - 9) ** 2) / 0.5))


NODES = {"A": (2.0, 6.0), "B": (18.0, 6.0), "p": (5.0, 3.0), "q": (5.0, 9.0), "r": (10.0, 3.0),
         "s": (10.0, 9.0), "t": (15.0, 3.0), "u": (15.0, 9.0), "v": (12.5, 1.2)}
SEGMENTS = (("A", "p"), ("A", "q"), ("p", "q"), ("p", "r"), ("q", "s"), ("r", "t"), ("s", "u"),
            ("t", "B"), ("u", "B"), ("q", "r"), ("s", "t"), ("r", "v"), ("v", "t"), ("t", "u"), ("r", "s"))
TRAFFIC = {"p-r": 0.9, "r-t": 0.6, "q-s": 0.1, "v-t": 0.3}


@pytest.fixture(scope="module")
def small():
    base = scenarios.load("paper-docks")
    return dataclasses.replace(base, routes=RouteNetwork(NODES, SEGMENTS, TRAFFIC))


def brute_paths():
    edges = {frozenset(s) for s in SEGMENTS}
    inner = [n for n in NODES if n not in "AB"]
    for k in range(len(inner) + 1):
        for mid in itertools.permutations(inner, k):
            seq = ("A", *mid, "B")
            if all(frozenset(p) in edges for p in zip(seq[:-1], seq[1:], strict=False)):
                yield seq


@pytest.fixture(scope="module")
def brute(small):
    """All routes enumerated here, scored with the planner's scoring of a single route."""
    seqs = list(brute_paths())
    g = {frozenset((a, b)): small.routes.traffic_of(a, b) for a, b in SEGMENTS}
    specs = [candidates.RouteSpec(str(i), [np.array([NODES[n] for n in seq])], seq,
                            [g[frozenset(p)] for p in zip(seq[:-1], seq[1:], strict=True)])
             for i, seq in enumerate(seqs)]
    tau_fn = lambda p: FakePEF(bumpy_tau).at(p).tau
    cands = candidates.make_candidates(small, specs, tau_fn)
    # The planner compares criteria at 9 significant digits (documented in planner.routes.criteria),
    # so that floating-point noise neither breaks ties nor gets stretched by normalisation.
    values = np.array([[float(f"{x:.9g}") for x in c.vector()] for c in cands])
    adm = np.array([c.admissible for c in cands])
    return seqs, values, adm


WEIGHTS = [Weights(), Weights(1, 0, 0, 0, 0), Weights(0, 1, 0, 0, 0), Weights(0, 0, 1, 0, 0),
           Weights(0, 0, 0, 1, 0), Weights(0, 0, 0, 0, 1), Weights(0.2, 3.0, 1.0, 0.1, 0.7)]


@pytest.mark.parametrize("weights", WEIGHTS)
def test_weighted_choice_matches_brute_force(small, brute, weights):
    seqs, values, adm = brute
    assert 3 <= adm.sum() < len(seqs)  # the test network has both kinds
    sc = dataclasses.replace(small, planning=dataclasses.replace(small.planning, weights=weights))
    p = plan.plan_route(sc, "A", "B", pef=FakePEF(bumpy_tau), schedule=False)
    assert {c.nodes for c in p.candidates} == set(seqs)
    # Brute force: min-max over the admissible routes, weighted sum.
    w = np.array([weights.accuracy, weights.length, weights.traffic, weights.clearance, weights.smoothness])
    lo, hi = values[adm].min(axis=0), values[adm].max(axis=0)
    norm = np.where(hi > lo, (values - lo) / np.where(hi > lo, hi - lo, 1), 0.0)
    score = norm @ w
    chosen = p.candidates[p.chosen]
    i = seqs.index(chosen.nodes)
    assert adm[i] and score[i] == pytest.approx(score[adm].min(), abs=1e-9)
    for c in p.candidates:
        j = seqs.index(c.nodes)
        assert c.admissible == adm[j]
        if c.admissible:
            assert c.score == pytest.approx(score[j], abs=1e-7)
    # Pareto front by brute force over the admissible routes.
    for c in p.candidates:
        j = seqs.index(c.nodes)
        dominated = any(adm[k] and np.all(values[k] <= values[j]) and np.any(values[k] < values[j])
                        for k in range(len(seqs)))
        assert c.pareto == (bool(adm[j]) and not dominated), c.id


@pytest.mark.parametrize("order", [("traffic", "length"), ("clearance", "smoothness"), ("accuracy",),
                                   ("smoothness", "traffic", "accuracy")])
def test_lexicographic_choice_matches_brute_force(small, brute, order):
    seqs, values, adm = brute
    sc = dataclasses.replace(small, planning=dataclasses.replace(small.planning, order=order))
    p = plan.plan_route(sc, "A", "B", pef=FakePEF(bumpy_tau), schedule=False)
    idx = [criteria.CRITERIA.index(c) for c in order]
    best = min(tuple(values[j, idx]) for j in np.flatnonzero(adm))
    got = tuple(values[seqs.index(p.candidates[p.chosen].nodes), idx])
    np.testing.assert_allclose(got, best, rtol=1e-8)
    assert "lexicographic" in p.reason


def test_chosen_path_fields_and_speed(small):
    p = plan.plan_route(small, "A", "B", pef=FakePEF(bumpy_tau), schedule=False)
    c = p.candidates[p.chosen]
    np.testing.assert_allclose(p.path[0], NODES["A"])
    np.testing.assert_allclose(p.path[-1], NODES["B"])
    assert np.all(np.diff(p.s) <= small.planning.resolution + 1e-9)
    assert p.speed[-1] == 0.0 and np.all(p.speed <= small.robot.max_speed + 1e-12)
    assert c.time > c.length / small.robot.max_speed  # turns and fixes cost time
    assert p.reason.startswith(c.id)
    # The bump on segment s-u makes every route along it inadmissible, named by its tau.
    for c in p.candidates:
        su = {frozenset(e) for e in zip(c.nodes[:-1], c.nodes[1:], strict=False)} & {frozenset("su")}
        assert c.admissible == (not su and c.min_clearance >= small.robot.radius)
        if su:
            assert "tau" in c.why_not and abs(c.worst_point[0] - 12.5) < 0.2


def fine_tau(pef, path, spacing):
    pts, _ = criteria.sample_polyline(path, spacing)
    return pef.at(pts).tau


@pytest.mark.parametrize("name,free", [("warehouse", None), ("paper-docks", None), ("paper-docks", True),
                                       ("paper-two-markers", None), ("warehouse", True)])
def test_chosen_path_admissible_on_builtins(name, free):
    sc = scenarios.load(name)
    pef = PEF(sc)
    t = sc.tasks[0]
    p = plan.plan_route(sc, t.start, t.goal, free=free, pef=pef, schedule=False)
    # Independent re-check at a twentieth of the resolution with the real PEF.
    tau = fine_tau(pef, p.path, sc.planning.resolution / 20)
    assert np.all(tau < sc.planning.eps_max), f"max tau {tau.max()} >= {sc.planning.eps_max}"
    pts, _ = criteria.sample_polyline(p.path, sc.planning.resolution / 20)
    assert criteria.clearance(pts, sc).min() >= sc.robot.radius
    if free:
        assert all(c.nodes is None for c in p.candidates)
    np.testing.assert_allclose(p.path[0], sc.dock(t.start).position)
    np.testing.assert_allclose(p.path[-1], sc.dock(t.goal).position)


def test_plan_with_schedule():
    sc = scenarios.load("paper-docks")
    p = plan.plan_task(sc, 0)
    assert p.schedule is not None and p.schedule.fixes
    assert p.schedule.worst < sc.planning.eps_max
    assert p.schedule.fixes[0].s == pytest.approx(0.0)


def test_infeasible_requests(small):
    fake = FakePEF(bumpy_tau)
    with pytest.raises(PlanningError, match="unknown dock 'Z'"):
        plan.plan_route(small, "A", "Z", pef=fake)
    with pytest.raises(ScenarioError, match=r"^task: expected 0 \.\. \d+ \(\d+ tasks in .*\), got 5$"):
        plan.plan_task(small, 5, pef=fake)
    tight = dataclasses.replace(small, planning=dataclasses.replace(small.planning, eps_max=0.004))
    with pytest.raises(PlanningError, match=r"no admissible route from 'A' to 'B'.*best R\d+: tau .* at \("):
        plan.plan_route(tight, "A", "B", pef=fake, schedule=False)
    tighter = dataclasses.replace(small, planning=dataclasses.replace(small.planning, eps_max=0.0035))
    with pytest.raises(PlanningError, match="dock 'A' at .* outside the navigation region: tau 0.004"):
        plan.plan_route(tighter, "A", "B", free=True, pef=fake, schedule=False)
    # A free-space region split by the forbidden bump ring: no connection, named with its tau.
    ring = lambda p: np.where(np.abs(p[:, 0] - 10) < 0.5, 0.05, 0.003)
    with pytest.raises(PlanningError, match=r"does not connect them.*tau 0.05 m"):
        plan.plan_route(small, "A", "B", free=True, pef=FakePEF(ring), schedule=False)
    # A dock walled in by obstacles.
    walls = (Obstacle((2.0, 7.0), (2.0, 0.4)), Obstacle((2.0, 5.0), (2.0, 0.4)),
             Obstacle((1.0, 6.0), (0.4, 2.0)), Obstacle((3.0, 6.0), (0.4, 2.4)))
    boxed = dataclasses.replace(small, obstacles=small.obstacles + walls, routes=None)
    with pytest.raises(PlanningError, match="outside the navigation region|unreachable"):
        plan.plan_route(boxed, "A", "B", pef=fake, schedule=False)


def test_dock_off_network_is_attached(small):
    docks = (*small.docks, Dock("C", (8.0, 10.5, 0.0)))
    sc = dataclasses.replace(small, docks=docks)
    p = plan.plan_route(sc, "C", "B", pef=FakePEF(bumpy_tau), schedule=False)
    assert all(c.nodes[0] == "C" and c.nodes[1] == "s" for c in p.candidates)  # nearest reachable node
    np.testing.assert_allclose(p.path[0], (8.0, 10.5))
    # Hidden behind walls from every node: unreachable.
    walls = (Obstacle((8.0, 9.9), (3.0, 0.2)), Obstacle((6.6, 10.9), (0.2, 2.0)),
             Obstacle((9.4, 10.9), (0.2, 2.0)))
    hidden = dataclasses.replace(sc, obstacles=sc.obstacles + walls)
    with pytest.raises(PlanningError, match="unreachable dock 'C'"):
        plan.plan_route(hidden, "C", "B", pef=FakePEF(bumpy_tau), schedule=False)


def test_free_candidates_are_distinct_and_admissible(small):
    p = plan.plan_route(small, "A", "B", free=True, pef=FakePEF(bumpy_tau), schedule=False)
    assert len(p.candidates) >= 2
    for c in p.candidates:
        assert c.admissible and c.max_tau < small.planning.eps_max and c.traffic == 0.0
        assert c.min_clearance >= small.robot.radius
        assert math.isclose(c.length, c.path.length)
