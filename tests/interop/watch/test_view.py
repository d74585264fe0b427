"""The live view's content: the PEF map of a moved marker recomputed in a window equals a whole map."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from interop.watch.files import FileSet
from interop.watch.view import ViewBuilder
from planner.pef.map import PEF
from scenarios import load
from scenarios.load import LIBRARY
from scenarios.schema import Marker


def _moved(sc, index: int, position: tuple[float, float], **sensor):
    markers = list(sc.markers)
    markers[index] = dataclasses.replace(markers[index], position=position)
    sc = dataclasses.replace(sc, markers=tuple(markers))
    if sensor:
        sc = dataclasses.replace(sc, sensor=dataclasses.replace(sc.sensor, **sensor))
    return sc


@pytest.mark.parametrize("name", ["warehouse", "hall"])
def test_moved_marker_window_equals_whole_map(name):
    """max_range shorter than the floor, so the window is a part of it: equal to the whole map, bit for bit."""
    sc = load(name)
    sc = dataclasses.replace(sc, sensor=dataclasses.replace(sc.sensor, max_range=min(sc.workspace.size) / 3))
    builder = ViewBuilder()
    first = builder.build_map(sc)
    assert first.map_work == "computed"
    before = first.pef_map.tau.copy()  # the builder updates its map in place
    x0, y0 = sc.markers[0].position
    moved = _moved(sc, 0, (x0 + 0.7, y0) if x0 + 0.7 < sc.workspace.size[0] else (x0 - 0.7, y0))
    view = builder.build_map(moved)
    assert view.map_work == "window"
    whole = PEF(moved).grid()
    assert np.array_equal(view.pef_map.tau, whole.tau)
    assert np.array_equal(view.pef_map.best, whole.best)
    # negative control: the old map is not the new one (reusing it unchanged would fail the check above)
    assert not np.array_equal(before, whole.tau)
    assert builder.build_map(moved).map_work == "reused"  # the same markers again: nothing to compute


def test_other_changes_compute_the_whole_map():
    sc = load("warehouse")
    builder = ViewBuilder()
    builder.build_map(sc)
    fewer = dataclasses.replace(sc, markers=sc.markers[:-1])
    assert builder.build_map(fewer).map_work == "computed"
    wider = dataclasses.replace(fewer, sensor=dataclasses.replace(fewer.sensor, max_range=fewer.sensor.max_range + 1))
    assert builder.build_map(wider).map_work == "computed"


def test_map_first_then_plans():
    """build_map shows the map and segments before the plans; plan() then gives what build() gives."""
    sc = load("paper-docks")  # one task: this compares two ways to the same plans, each plans it
    builder = ViewBuilder()
    view = builder.build_map(sc)
    assert not view.planned and view.plans == [] and "plans" not in view.seconds
    assert view.summary() == f"{len(sc.markers)} markers, planning 1 task"
    done = builder.plan(view)
    assert done.planned and done.pef_map is view.pef_map and done.reports is view.reports
    whole = ViewBuilder().build(sc)
    assert [p.chosen for p in done.plans] == [p.chosen for p in whole.plans]
    assert [p.candidates[p.chosen].max_tau for p in done.plans] == [p.candidates[p.chosen].max_tau for p in whole.plans]
    with pytest.raises(ValueError):
        ViewBuilder().plan(view)  # a view of another builder


def test_watch_shows_the_map_then_the_plans(tmp_path):
    """With show_plans the map part is shown first, the plans after; the line gives both times."""
    from interop.watch.loop import watch_files

    scenario = tmp_path / "wh.toml"
    scenario.write_text((LIBRARY / "warehouse.toml").read_text())  # it reads no other file
    events, updates = [], []
    watch_files(scenario, lambda step, view: events.append(("map", step, view.planned)),
                show_plans=lambda step, view: events.append(("plans", step, view.planned)),
                on_update=updates.append, max_updates=1, interval=0.01)
    assert events == [("map", 0, False), ("plans", 0, True)]
    (u,) = updates
    assert u.planned_seconds is not None and u.planned_seconds >= u.seconds
    assert u.line().startswith(f"updated in {u.seconds:.2f} s, planned in {u.planned_seconds:.2f} s: wh.toml: ")
    assert u.line().endswith("tasks planned")


def test_summary_counts_unplanned_tasks():
    sc = load("warehouse")
    view = ViewBuilder().build(dataclasses.replace(sc, markers=(Marker("only", sc.markers[0].position),)))
    assert view.summary() == f"1 marker, 0 of {len(sc.tasks)} tasks planned"
    assert set(view.unplanned) == set(range(len(sc.tasks)))


def test_file_set_sees_content_not_touches(tmp_path):
    a, b = tmp_path / "a.toml", tmp_path / "b.dxf"
    a.write_text("x = 1\n")
    files = FileSet([a, b])                  # b does not exist yet
    assert files.changed() == []
    a.write_text("x = 1\n")                  # saved without a change
    assert files.changed() == []
    a.write_text("x = 2\n")
    b.write_text("drawing")
    assert files.changed() == [a, b]
    b.unlink()
    assert files.changed() == [b]


def test_reused_values_plan_as_from_scratch():
    """After a move, the view's route τ and plans (values reused away from the marker) equal a fresh view's."""
    sc = load("warehouse")
    sc = dataclasses.replace(sc, sensor=dataclasses.replace(sc.sensor, max_range=min(sc.workspace.size) / 2))
    builder = ViewBuilder()
    builder.build(sc)
    x0, y0 = sc.markers[1].position
    moved = _moved(sc, 1, (x0 + 0.5, y0) if x0 + 0.5 < sc.workspace.size[0] else (x0 - 0.5, y0))
    view, fresh = builder.build(moved), ViewBuilder().build(moved)
    assert view.map_work == "window" and fresh.map_work == "computed"
    assert [r.max_tau for r in view.reports] == [r.max_tau for r in fresh.reports]
    assert [r.why_not for r in view.reports] == [r.why_not for r in fresh.reports]
    for a, b in zip(view.plans, fresh.plans, strict=True):
        assert (a is None) == (b is None)
        if a is not None:
            assert a.chosen == b.chosen and np.array_equal(a.path, b.path)
            assert [(f.position, f.markers, f.tau) for f in a.schedule.fixes] == \
                   [(f.position, f.markers, f.tau) for f in b.schedule.fixes]


def test_scenario_lists_every_file_it_read(tmp_path):
    """Scenario.files: what ``pefsim watch`` follows (the TOML, a DXF, a ROS map and its image, a graph file)."""
    from tests.scenarios import drawings as dr
    from tests.scenarios import graphfiles as gf
    from tests.scenarios.worlds import scenario_text

    hall = load("hall")
    assert [p.name for p in hall.files] == ["hall.toml", "hall.dxf"] and all(p.is_absolute() for p in hall.files)

    yaml_path = dr.write_map(tmp_path, dr.map_image(h=200, w=200))  # 10 x 10 m: the markers of REST inside
    ros = tmp_path / "ros.toml"
    ros.write_text(scenario_text(f'file = "{yaml_path.name}"'))
    assert [p.name for p in load(ros).files] == ["ros.toml", yaml_path.name, "map.pgm"]

    gf.write(tmp_path / "g.geojson", gf.nav2_graph())
    graph = tmp_path / "graph.toml"
    graph.write_text(gf.scenario_text('file = "g.geojson"'))
    assert load(graph).files == (graph.resolve(), (tmp_path / "g.geojson").resolve())
    assert load("warehouse").files[0].name == "warehouse.toml" and len(load("warehouse").files) == 1


def test_saving_a_file_the_scenario_reads_updates(tmp_path):
    """The route graph file is followed too: saving it (changed) updates, naming it; saving it unchanged does not."""
    import json
    import threading
    import time

    from interop.watch.loop import watch_files
    from tests.scenarios import graphfiles as gf

    graph_file = gf.write(tmp_path / "g.geojson", gf.nav2_graph())
    scenario = tmp_path / "graph.toml"
    scenario.write_text(gf.scenario_text('file = "g.geojson"'))
    updates, errors, shown, stop = [], [], [], threading.Event()
    thread = threading.Thread(target=watch_files, args=(scenario, lambda step, view: shown.append(step)),
                              kwargs={"on_update": updates.append, "on_error": errors.append, "interval": 0.02,
                                      "stop": stop})
    thread.start()

    def wait_for(n: int) -> None:
        deadline = time.monotonic() + 60.0
        while len(updates) + len(errors) < n and time.monotonic() < deadline:
            time.sleep(0.02)

    try:
        wait_for(1)
        graph_file.write_text(graph_file.read_text())        # saved, same bytes
        doc = json.loads(graph_file.read_text())
        doc["features"][0]["geometry"]["coordinates"][0] += 0.5
        graph_file.write_text(json.dumps(doc))
        wait_for(2)
    finally:
        stop.set()
        thread.join(timeout=60.0)
    assert not errors and shown == [0, 1]
    assert [[p.name for p in u.changed] for u in updates] == [["graph.toml"], ["g.geojson"]]
    assert updates[1].line().startswith("updated in ") and ": g.geojson: 4 markers, " in updates[1].line()
    assert updates[1].view.scenario.routes.nodes != updates[0].view.scenario.routes.nodes
