"""``pefsim place``: JSON fields, a loadable placed scenario with full coverage, exit codes."""

from __future__ import annotations

import json

import numpy as np

import scenarios
from cli import main
from planner.pef.map import PEF
from planner.placement.sites import cover_points


def run_cli(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_json_and_written_scenario(capsys, tmp_path):
    toml, png = tmp_path / "placed.toml", tmp_path / "placed.png"
    code, out, _ = run_cli(capsys, "place", "paper-docks", "--json", "-o", str(toml), "--png", str(png))
    assert code == 0
    doc = json.loads(out)
    assert {"markers", "count", "lower_bound", "optimal", "uncovered"} <= set(doc)
    assert doc["count"] == len(doc["markers"]) and doc["uncovered"] == []
    assert isinstance(doc["optimal"], bool) and doc["lower_bound"] <= doc["count"]
    assert all({"id", "position", "kind", "new"} <= set(m) and len(m["position"]) == 2 for m in doc["markers"])
    assert all(m["new"] for m in doc["markers"]) and doc["kept"] == [] and len(doc["new"]) == doc["count"]
    placed = scenarios.load(toml)
    written = [[m.id, list(m.position)] for m in placed.markers]
    assert written == [[m["id"], m["position"]] for m in doc["markers"]]
    original = scenarios.load("paper-docks")
    assert placed.planning == original.planning and placed.routes == original.routes
    tau = PEF(placed).at(cover_points(placed)).tau
    assert np.all(tau < placed.planning.eps_max)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_text_summary(capsys):
    code, out, _ = run_cli(capsys, "place", "paper-two-markers")
    assert code == 0
    assert "markers (optimal" in out and "cover" in out
    assert sum(line.startswith("  P") for line in out.splitlines()) == int(out.split(": ")[1].split()[0])


def uncoverable_file(tmp_path):
    text = scenarios.load("paper-docks").text
    path = tmp_path / "short.toml"
    # 3 m: too short to cover the routes along the walls (4 m covered all but the dropped n2-n5 diagonal)
    path.write_text(text.replace("max_range = 20.0", "max_range = 3.0"))
    return path


def test_uncoverable_points_exit_2(capsys, tmp_path):
    path = uncoverable_file(tmp_path)
    code, out, err = run_cli(capsys, "place", str(path))
    assert code == 2
    # the phases go to stderr too ("place [ 1.0 s] cover: ..."); the error is one line after them
    lines = [line for line in err.splitlines() if not line.startswith("place [")]
    assert len(lines) == 1 and "points cannot be covered by any candidate sites (first: (" in lines[0]
    assert "markers" in out  # the summary is still printed
    code, out, err_json = run_cli(capsys, "place", str(path), "--json")
    assert code == 2
    doc = json.loads(out)  # stdout holds the JSON alone
    n = int(err.split(f"pefsim: error: {path}: ")[1].split()[0])  # the scenario named first
    assert len(doc["uncovered"]) == n > 0 and all(len(p) == 2 for p in doc["uncovered"])
    # the refusal's one line goes to stderr under --json too (the phase lines carry their times)
    assert [ln for ln in err_json.splitlines() if not ln.startswith("place [")] == lines


def test_bad_time_limit(capsys):
    code, _, err = run_cli(capsys, "place", "paper-docks", "--time-limit", "0")
    assert code == 2 and "time_limit: expected a positive number of seconds" in err


def test_keep_lists_new_markers_text_and_json(capsys, tmp_path):
    text = scenarios.load("warehouse").text.replace("eps_max = 0.03", "eps_max = 0.02")
    path = tmp_path / "keep.toml"
    path.write_text(text + '\n[placement]\nexisting = "keep"\n')
    code, out, _ = run_cli(capsys, "place", str(path), "--cover-only")
    assert code == 0
    rows = [line.split() for line in out.splitlines() if line.startswith("  ")]
    kept = [r[0] for r in rows if r[-1] == "kept"]
    new = [r[0] for r in rows if r[-1] == "new"]
    assert kept == [m.id for m in scenarios.load("warehouse").markers] and new
    assert f"12 markers kept, {len(new)} added" in out
    code, out, _ = run_cli(capsys, "place", str(path), "--cover-only", "--json")
    doc = json.loads(out)
    assert code == 0 and doc["new"] == new and doc["count"] == len(new) and doc["kept"] == kept


def test_output_format_from_extension_refused_before_work(capsys, tmp_path):
    code, _, err = run_cli(capsys, "place", "warehouse", "-o", str(tmp_path / "placed.txt"))
    assert code == 2 and err.count("\n") == 1 and "expected a .toml file" in err
    code, _, err = run_cli(capsys, "place", "warehouse", "--png", str(tmp_path / "placed.jpg"))
    assert code == 2 and err.count("\n") == 1 and "expected a .png file" in err
    assert not list(tmp_path.iterdir())


def test_placed_scenario_names_its_files_relative_and_says_what_it_is(capsys, tmp_path):
    import shutil
    import tomllib

    src = tmp_path / "src"
    src.mkdir()
    from scenarios.load import LIBRARY

    shutil.copy(LIBRARY / "hall.dxf", src / "hall.dxf")
    text = (LIBRARY / "hall.toml").read_text().replace('marker_layer = "AGV-REFL"\n', "")
    (src / "my-hall.toml").write_text(text)
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    code, _, _ = run_cli(capsys, "place", str(src / "my-hall.toml"), "-o", str(out_dir / "placed.toml"),
                         "--cover-only")
    assert code == 0
    data = tomllib.loads((out_dir / "placed.toml").read_text())
    assert data["floorplan"]["file"] == "../src/hall.dxf"
    placed = scenarios.load(out_dir / "placed.toml")
    assert placed.description.startswith(f"hall with {len(placed.markers)} markers placed by pefsim place")
    assert "12 reflectors" not in placed.description


def test_cli_prints_what_the_library_returns(capsys):
    import pefsim

    code, out, _ = run_cli(capsys, "place", "paper-two-markers", "--json", "--time-limit", "20")
    res = pefsim.place("paper-two-markers", time_limit=20.0)
    assert code == 0 and json.loads(out) == json.loads(json.dumps(res.to_dict()))
    assert res.target <= scenarios.load("paper-two-markers").planning.eps_max and res.unplanned == ()
