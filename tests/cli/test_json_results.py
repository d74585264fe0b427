"""Every JSON document the program prints is ``to_dict()`` of the result the library returned.

Each test runs a command with ``--json`` in-process while recording what the facade function it
calls returned, and compares the printed document with that result's ``to_dict()``: a key the
command added, dropped or computed itself shows as a difference. ``mc`` and ``validate`` are
compared in ``tests/cli/test_validate.py``, beside the small real sweep they read.
"""

from __future__ import annotations

import json

import cli
import pefsim
from tests.cli.json_capture import printed, run_json


def test_map_prints_the_maps_dict(capsys, monkeypatch):
    doc, result = run_json(capsys, monkeypatch, "pef_map", ["map", "paper-two-markers", "--resolution", "0.5"])
    assert doc == printed(result.to_dict())
    assert doc["resolution"] == 0.5 and doc["speed"] is None


def test_plan_prints_the_plans_dict(capsys, monkeypatch):
    doc, result = run_json(capsys, monkeypatch, "plan", ["plan", "paper-two-markers"])
    assert doc == printed(result.to_dict(pefsim.load("paper-two-markers")))
    assert doc["candidates"] and doc["schedule"]


def test_place_prints_the_placements_dict(capsys, monkeypatch):
    doc, result = run_json(capsys, monkeypatch, "place", ["place", "paper-two-markers", "--cover-only"])
    assert doc == printed(result.to_dict())


def test_export_prints_what_was_written(capsys, monkeypatch, tmp_path):
    argv = ["export", "paper-two-markers", "--markers", str(tmp_path / "m.csv")]
    doc, result = run_json(capsys, monkeypatch, "export", argv)
    assert doc == printed(result.to_dict()) == {"markers": str(tmp_path / "m.csv")}


def test_worlds_print_each_worlds_record(capsys, monkeypatch, tmp_path):
    drawn = []
    real = pefsim.iter_worlds

    def recording(*args, **kwargs):
        for w in real(*args, **kwargs):
            drawn.append(w)
            yield w

    monkeypatch.setattr(pefsim, "iter_worlds", recording)
    code = cli.main(["worlds", "--count", "1", "--seed", "3", "--max-size", "12", "--bounded", "--out",
                     str(tmp_path), "--json"])
    assert code == 0 and len(drawn) == 1
    assert json.loads(capsys.readouterr().out) == printed([w.to_dict() for w in drawn])


def test_list_prints_each_scenarios_overview(capsys):
    assert cli.main(["list", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc == printed([pefsim.load(n).overview() for n in pefsim.builtin_names()]) and len(doc) > 5


def test_a_document_the_command_changed_is_seen(capsys, monkeypatch):
    """Negative control: one value the command computed itself differs from the library's dict."""
    doc, result = run_json(capsys, monkeypatch, "pef_map", ["map", "paper-two-markers", "--resolution", "0.5"])
    expected = printed(result.to_dict())
    doc["fraction_navigable"] += 1e-9
    assert doc != expected
