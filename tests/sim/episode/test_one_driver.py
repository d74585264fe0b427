"""One robot's drive is written once: a lone robot and every robot of a fleet are a RobotDriver.

Two ways a second copy of the loop would show. Driven: every step row a run logs, lone or fleet,
comes from :meth:`RobotDriver.control` (a counted wrapper sees exactly as many calls as rows), and
the facade's :func:`pefsim.run_episode` hands a lone and a fleet scenario to the same
:func:`sim.episode.run.run`. Read: in the library's source, the per-robot step (the control tick
that logs a row, fix starts, odometry reads between ticks, the hold at the goal, the certified bound)
is defined or built in one module only, and no module outside the fleet's own scheduling asks a
scenario whether it is a fleet. The negative controls run the same source checks on a module that
copies the loop (and on one that asks), and must fail.
"""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

import pefsim
import scenarios
from scenarios import loads
from sim.episode import run
from sim.episode.driver import RobotDriver
from tests.sim.fleets import CROSS

ROOT = Path(__file__).resolve().parents[3]
LIBRARY = [p for top in ("scenarios", "estimators", "planner", "sim", "pefsim", "cli", "validation", "interop")
           for p in sorted((ROOT / top).rglob("*.py")) if (ROOT / top).is_dir()]
DRIVER = "sim/episode/driver.py"
#: Names that only one robot's drive defines: the step, the fixes, the odometry reads, the hold.
STEP_NAMES = frozenset({"start_fix", "read_odometry", "read_span", "hold_at_goal", "hold_fix", "_hold_fix"})
#: Calls that only one robot's drive makes: its control tick, fix recorder and certified bound.
STEP_CALLS = frozenset({"ControlTick", "FixRecorder", "certified_bound", "single_failure_excused"})
#: The modules that may ask whether a scenario is a fleet: its definition, and ``pefsim plan``, whose
#: route plan and fleet plan print themselves differently until the route plan owns its printout.
FLEET_ASKERS = frozenset({"scenarios/schema.py", "sim/cli/plan.py", "cli/plan.py"})


def _step_sites(source: str) -> set[str]:
    """Return the step names a module defines and the step calls it makes."""
    found = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name in STEP_NAMES:
            found.add(node.name)
        elif isinstance(node, ast.Call):
            f = node.func
            name = f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else None
            if name in STEP_CALLS:
                found.add(name)
    return found


def _asks_is_fleet(source: str) -> bool:
    return any(isinstance(n, ast.Attribute) and n.attr == "is_fleet" for n in ast.walk(ast.parse(source)))


def _modules_with_steps(files: dict[str, str]) -> dict[str, set[str]]:
    return {rel: found for rel, src in files.items() if (found := _step_sites(src))}


def _library() -> dict[str, str]:
    return {p.relative_to(ROOT).as_posix(): p.read_text(encoding="utf-8") for p in LIBRARY}


def test_only_the_driver_module_defines_a_robots_step():
    sites = _modules_with_steps(_library())
    assert set(sites) == {DRIVER}, f"a robot's step outside {DRIVER}: {sites}"
    assert sites[DRIVER] >= {"start_fix", "read_odometry", "ControlTick", "certified_bound"}


def test_no_module_asks_whether_a_scenario_is_a_fleet():
    askers = {rel for rel, src in _library().items() if _asks_is_fleet(src)}
    assert askers <= FLEET_ASKERS, f"is_fleet asked outside the fleet's scheduling: {sorted(askers - FLEET_ASKERS)}"


def test_a_copied_loop_or_a_fleet_question_fails_the_source_checks():
    """Negative controls: the driver's loop copied into a second module, and a module that asks ``is_fleet``."""
    files = _library()
    files["sim/episode/copy.py"] = files[DRIVER]
    assert set(_modules_with_steps(files)) != {DRIVER}
    # a closure-style copy, as a lone robot's episode once had it
    files = {DRIVER: files[DRIVER], "sim/episode/lone.py": (
        "def drive(world):\n    def read_odometry():\n        pass\n    tick = ControlTick(1, 2, 3, 4, 5)\n")}
    assert set(_modules_with_steps(files)) == {DRIVER, "sim/episode/lone.py"}
    assert _asks_is_fleet("def f(sc):\n    return 1 if sc.is_fleet else 2\n")
    assert not _asks_is_fleet("def f(sc):\n    return 1 if sc.robots else 2\n")


@pytest.fixture
def counted(monkeypatch):
    """Count :meth:`RobotDriver.control` calls per driver."""
    calls: dict[int, int] = {}
    control = RobotDriver.control

    def counting(self, t):
        calls[id(self)] = calls.get(id(self), 0) + 1
        return control(self, t)

    monkeypatch.setattr(RobotDriver, "control", counting)
    return calls


def test_a_lone_robot_and_a_fleet_log_every_row_through_the_driver(counted):
    lone = scenarios.load("paper-two-markers")
    res = run.run(lone, 0, seed=1, time_limit=2.0)
    assert [r.name for r in res.robots] == [None]
    assert list(counted.values()) == [len(res.steps.t)] and len(res.steps.t) > 60
    counted.clear()
    fleet = loads(CROSS, source="cross.toml")
    res = run.run(fleet, seed=1, time_limit=2.0)
    assert [r.name for r in res.robots] == ["east", "north"]
    assert sorted(counted.values()) == sorted(len(r.result.steps.t) for r in res.robots)
    assert min(counted.values()) > 60


def test_the_facade_runs_a_lone_and_a_fleet_scenario_the_same_way(monkeypatch):
    seen = []

    def fake_run(scenario, task_index=0, seed=0, **_):
        seen.append((scenario.name, task_index, seed))
        return "ran"

    monkeypatch.setattr(run, "prepare", lambda scenario, task_index=0, **_: None)
    monkeypatch.setattr(run, "run", fake_run)
    assert pefsim.run_episode(scenarios.load("paper-two-markers"), 4) == "ran"
    assert pefsim.run_episode(loads(CROSS, source="cross.toml"), 5) == "ran"
    assert seen == [("paper-two-markers", 0, 4), ("cross", 0, 5)]
    with pytest.raises(scenarios.ScenarioError, match=r"cross\.toml is a fleet"):
        pefsim.run_episode(loads(CROSS, source="cross.toml"), 5, task=1)


def test_a_lone_run_reads_as_a_fleet_of_one():
    """A lone robot's result gives its one robot, unnamed, as a fleet's gives each of its robots."""
    res = run.run(scenarios.load("paper-two-markers"), 0, seed=1, time_limit=0.5)
    (robot,) = res.robots
    assert robot.name is None and robot.result is res and res.names == []
    assert res.to_dict()["seed"] == res.summary["seed"]
    assert res.lines(scenarios.load("paper-two-markers"))[0].startswith("paper-two-markers: task 0 ")
    assert np.isfinite(res.to_dict()["rmse"])
