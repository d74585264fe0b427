"""``pefsim plan``: JSON fields and their consistency, figure, one-line errors with exit 2."""

from __future__ import annotations

import json

import numpy as np
import pytest

import scenarios
from cli import main
from planner.pef.map import PEF
from planner.routes import criteria


def run_cli(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture(scope="module")
def docks_json(tmp_path_factory):
    out = tmp_path_factory.mktemp("plan") / "p.png"
    import contextlib
    import io
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["plan", "paper-docks", "--json", "-o", str(out)])
    return code, json.loads(buf.getvalue()), out


def test_json_fields_and_consistency(docks_json):
    code, doc, png = docks_json
    assert code == 0
    sc = scenarios.load("paper-docks")
    assert doc["eps_max"] == sc.planning.eps_max
    keys = {"id", "nodes", "length", "time", "max_tau", "mean_tau", "traffic", "min_clearance", "turning",
            "admissible", "pareto"}
    ids = [c["id"] for c in doc["candidates"]]
    for c in doc["candidates"]:
        assert keys <= set(c)
        assert c["nodes"][0] == "A" and c["nodes"][-1] == "B"
        assert c["admissible"] == (c["max_tau"] < doc["eps_max"] and c["min_clearance"] >= sc.robot.radius)
        assert not c["pareto"] or c["admissible"]
        assert c["time"] > c["length"] / sc.robot.max_speed
    chosen = doc["candidates"][ids.index(doc["chosen"])]
    assert chosen["admissible"] and doc["chosen_index"] == ids.index(doc["chosen"])
    path = np.array(doc["path"])
    assert path.shape[1] == 2 and len(path) > 10
    np.testing.assert_allclose(path[0], sc.dock("A").position)
    np.testing.assert_allclose(path[-1], sc.dock("B").position)
    assert criteria.polyline_length(path) == pytest.approx(chosen["length"], rel=1e-9)
    tau = PEF(sc).at(path).tau
    assert tau.max() == pytest.approx(chosen["max_tau"], rel=1e-9)
    fixes = doc["schedule"]
    assert fixes and {"x", "y", "markers", "tau"} <= set(fixes[0])
    for f in fixes:
        assert set(f["markers"]) <= set(sc.marker_ids()) and len(f["markers"]) == sc.sensor.markers_per_fix
        assert f["tau"] < doc["eps_max"]
        assert np.min(np.hypot(*(path - [f["x"], f["y"]]).T)) < sc.planning.resolution
    assert png.stat().st_size > 10_000 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_text_output_writes_nothing_unasked(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli(capsys, "plan", "paper-two-markers")
    assert code == 0 and err == ""
    assert "chosen: F1" in out and "schedule:" in out and "wrote" not in out
    assert list(tmp_path.iterdir()) == []
    code, out, _ = run_cli(capsys, "plan", "paper-two-markers", "--json")
    assert code == 0 and list(tmp_path.iterdir()) == []


def test_free_flag(capsys, tmp_path):
    code, out, _ = run_cli(capsys, "plan", "paper-docks", "--free", "--json", "-o", str(tmp_path / "f.png"))
    doc = json.loads(out)
    assert code == 0 and all(c["nodes"] is None for c in doc["candidates"])


@pytest.mark.parametrize("argv,pattern", [
    (["--from", "A", "--to", "Z"], "unknown dock 'Z'"),
    (["--from", "A"], "give both start and goal"),
])
def test_bad_requests_exit_2_with_one_line(capsys, tmp_path, argv, pattern):
    code, out, err = run_cli(capsys, "plan", "paper-docks", *argv, "-o", str(tmp_path / "x.png"))
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("pefsim: error:") and pattern in err


def test_infeasible_eps_exit_2(capsys, tmp_path):
    text = scenarios.load("paper-docks").text.replace("eps_max = 0.02", "eps_max = 0.001")
    assert "eps_max = 0.001" in text
    f = tmp_path / "tight.toml"
    f.write_text(text)
    for extra in ([], ["--free"]):
        code, out, err = run_cli(capsys, "plan", str(f), *extra, "-o", str(tmp_path / "x.png"))
        assert code == 2 and out == "" and err.count("\n") == 1
        assert "no admissible route" in err or "outside the navigation region" in err
        assert "tau" in err
        assert err.startswith(f"pefsim: error: {f}: "), err  # the scenario is named
    assert not (tmp_path / "x.png").exists()
