"""A route graph from Nav2's own examples loads: repeated edge ids are one warning, not a refusal.

``tests/data/nav2/turtlebot4_graph.geojson`` (Nav2's depot graph, see its README) reuses six
edge ids, each on two edges to different nodes.
"""

from __future__ import annotations

import json
import shutil
import warnings
from collections import Counter
from pathlib import Path

import pytest

import scenarios
from cli import main
from scenarios.errors import ScenarioWarning

GRAPH = Path(__file__).resolve().parents[1] / "data" / "nav2" / "turtlebot4_graph.geojson"
REPEATED = ("10006", "10007", "10012", "10013", "10020", "10021")

SCENARIO = """
name = "depot"
[workspace]
size = [30.0, 14.0]
[[markers]]
id = "M1"
position = [0.0, 0.0]
[[markers]]
id = "M2"
position = [30.0, 0.0]
[sensor]
[robot]
radius = 0.3
wheel_base = 0.38
[planning]
eps_max = 0.05
resolution = 0.2
[routes]
file = "{graph}"
"""


def file_edges():
    doc = json.loads(GRAPH.read_text())
    return [(str(f["properties"]["id"]), str(f["properties"]["startid"]), str(f["properties"]["endid"]))
            for f in doc["features"] if f["geometry"]["type"] != "Point"]


@pytest.fixture
def scenario_file(tmp_path):
    shutil.copy(GRAPH, tmp_path / GRAPH.name)
    path = tmp_path / "depot.toml"
    path.write_text(SCENARIO.format(graph=GRAPH.name))
    return path


def test_the_file_repeats_six_edge_ids():  # the test data is what the test is about
    counts = Counter(i for i, _, _ in file_edges())
    assert sorted(i for i, c in counts.items() if c > 1) == list(REPEATED)


def test_loads_with_one_warning_naming_the_repeated_ids_and_keeps_both_edges(scenario_file):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sc = scenarios.load(scenario_file)
    mine = [w for w in caught if issubclass(w.category, ScenarioWarning)]
    assert len(mine) == 1 and len(caught) == 1
    msg = str(mine[0].message)
    assert "\n" not in msg and GRAPH.name in msg and all(i in msg for i in REPEATED)
    kept = sorted((i, a, b) for e in sc.routes.edges for i, (a, b) in zip(e.ids, e.ends, strict=True))
    assert kept == sorted(file_edges())  # every directed edge, with its own id and ends


def test_repeated_node_ids_are_still_refused(tmp_path):
    doc = json.loads(GRAPH.read_text())
    points = [f for f in doc["features"] if f["geometry"]["type"] == "Point"]
    points[1]["properties"]["id"] = points[0]["properties"]["id"]
    (tmp_path / GRAPH.name).write_text(json.dumps(doc))
    (tmp_path / "depot.toml").write_text(SCENARIO.format(graph=GRAPH.name))
    with pytest.raises(scenarios.ScenarioError, match="expected a unique node id"), pytest.warns(ScenarioWarning):
        scenarios.load(tmp_path / "depot.toml")


def test_export_keeps_the_ids_as_given(scenario_file, tmp_path, capsys):
    out = tmp_path / "out.geojson"
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        code = main(["export", str(scenario_file), "--routes", str(out)])
    err = capsys.readouterr().err
    assert code == 0
    assert err.count("pefsim: warning:") == 1 and err.count("\n") == 1 and "10006" in err
    doc = json.loads(out.read_text())
    edges = sorted((str(f["properties"]["id"]), str(f["properties"]["startid"]), str(f["properties"]["endid"]))
                   for f in doc["features"] if f["geometry"]["type"] == "LineString")
    assert edges == sorted(file_edges())
    nodes = {str(f["properties"]["id"]) for f in doc["features"] if f["geometry"]["type"] == "Point"}
    assert nodes == {str(f["properties"]["id"]) for f in json.loads(GRAPH.read_text())["features"]
                     if f["geometry"]["type"] == "Point"}
    assert not any("source_id" in f["properties"] for f in doc["features"])


def test_writing_the_placed_scenario_says_the_warning_no_more(scenario_file, tmp_path):
    """The placed scenario is read back to check it; the graph's warning, said at load, is not said again.

    Negative control: reading the written file on its own says it (it is a new load).
    """
    import numpy as np

    from planner.placement.placement import PlacementResult, write_scenario_with_markers

    with pytest.warns(ScenarioWarning):
        sc = scenarios.load(scenario_file)
    result = PlacementResult(markers=[("P1", (0.0, 7.0)), ("P2", (30.0, 7.0))], count=2, lower_bound=2,
                             optimal=True, uncovered=np.zeros((0, 2)), method="test", sites=np.zeros((0, 2)),
                             points=np.zeros((0, 2)), chosen=np.arange(2))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = write_scenario_with_markers(sc, result, tmp_path / "placed.toml")
    assert [str(w.message) for w in caught] == []
    with pytest.warns(ScenarioWarning, match="repeated edge ids 10006"):
        again = scenarios.load(out)
    assert [m.id for m in again.markers] == ["P1", "P2"]


def test_validating_a_sweep_of_it_says_the_warning_no_more(scenario_file, tmp_path):
    """A sweep's stored scenario, read back to validate the scenario it was made from, warns nothing.

    Negative control: validating the directory on its own (``--from`` without the scenario) says it once.
    """
    from scenarios.errors import OutputError
    from sim.montecarlo.results import SweepLayout, write_atomic
    from validation.data import load_sweep

    with pytest.warns(ScenarioWarning):
        sc = scenarios.load(scenario_file)
    layout = SweepLayout(tmp_path / "mc")
    layout.make_dirs()
    write_atomic(layout.scenario_toml, sc.text.encode())
    with warnings.catch_warnings(record=True) as caught, pytest.raises(OutputError, match="holds no finished run"):
        warnings.simplefilter("always")
        load_sweep(layout.root, sc)
    assert [str(w.message) for w in caught] == []
    with pytest.warns(ScenarioWarning, match="repeated edge ids 10006"), \
            pytest.raises(OutputError, match="holds no finished run"):
        load_sweep(layout.root)
