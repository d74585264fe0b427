"""Every JSON document the program prints is ``to_dict()`` of the result the library returned.

Each test runs a command with ``--json`` in-process while recording what the facade function it
calls returned, and compares the printed document with that result's ``to_dict()``: a key the
command added, dropped or computed itself shows as a difference. The sweep commands read the
session's small real sweep (``tests/conftest.py``) instead of running one.
"""

from __future__ import annotations

import contextlib
import io
import json
import shutil

import cli
import pefsim


def _printed(obj) -> dict:
    """Return ``obj`` as the program prints JSON (numpy values plain, inf refused), read back."""
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        cli.print_json(obj)
    return json.loads(buf.getvalue())


def _run(capsys, monkeypatch, name: str, argv: list[str]) -> tuple[dict, object]:
    """Run ``pefsim ARGV --json``; return the printed document and what ``pefsim.<name>`` returned."""
    returned = []
    real = getattr(pefsim, name)

    def recording(*args, **kwargs):
        returned.append(real(*args, **kwargs))
        return returned[-1]

    monkeypatch.setattr(pefsim, name, recording)
    code = cli.main([*argv, "--json"])
    out = capsys.readouterr().out
    assert code in (0, 1) and len(returned) == 1, (code, returned)
    return json.loads(out), returned[0]


def test_map_prints_the_maps_dict(capsys, monkeypatch):
    doc, result = _run(capsys, monkeypatch, "pef_map", ["map", "paper-two-markers", "--resolution", "0.5"])
    assert doc == _printed(result.to_dict())
    assert doc["resolution"] == 0.5 and doc["speed"] is None


def test_plan_prints_the_plans_dict(capsys, monkeypatch):
    doc, result = _run(capsys, monkeypatch, "plan", ["plan", "paper-two-markers"])
    assert doc == _printed(result.to_dict(pefsim.load("paper-two-markers")))
    assert doc["candidates"] and doc["schedule"]


def test_place_prints_the_placements_dict(capsys, monkeypatch):
    doc, result = _run(capsys, monkeypatch, "place", ["place", "paper-two-markers", "--cover-only"])
    assert doc == _printed(result.to_dict())


def test_mc_prints_the_sweeps_dict(capsys, monkeypatch, small_validated_sweep, tmp_path):
    out = tmp_path / "mc"
    shutil.copytree(small_validated_sweep[0], out)  # resumed with nothing left to run: no episode
    doc, result = _run(capsys, monkeypatch, "sweep", ["mc", "paper-two-markers", "--out", str(out), "--resume",
                                                      "--no-report"])
    assert doc == _printed(result.to_dict())
    assert doc["runs"] == 4 and doc["executed"] == 0


def test_validate_prints_the_reports_dict(capsys, monkeypatch, small_validated_sweep):
    doc, result = _run(capsys, monkeypatch, "validate", ["validate", "--from", str(small_validated_sweep[0])])
    assert doc == _printed(result.to_dict())
    assert doc["sweep"] == str(small_validated_sweep[0]) and doc["wall_time"] > 0


def test_export_prints_what_was_written(capsys, monkeypatch, tmp_path):
    doc, result = _run(capsys, monkeypatch, "export", ["export", "paper-two-markers", "--markers",
                                                       str(tmp_path / "m.csv")])
    assert doc == _printed(result.to_dict()) == {"markers": str(tmp_path / "m.csv")}


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
    assert json.loads(capsys.readouterr().out) == _printed([w.to_dict() for w in drawn])


def test_a_document_the_command_changed_is_seen(capsys, monkeypatch):
    """Negative control: one value the command computed itself differs from the library's dict."""
    doc, result = _run(capsys, monkeypatch, "pef_map", ["map", "paper-two-markers", "--resolution", "0.5"])
    expected = _printed(result.to_dict())
    doc["fraction_navigable"] += 1e-9
    assert doc != expected
