"""The command line's output paths and its smaller defects.

An output file's format comes from its extension or is refused in one line (exit 2) before any
work; exactly the path given is written and printed; ``pefsim`` alone prints the help and
``pefsim --version`` the version.
"""

from __future__ import annotations

import json
import os
import re
from importlib.metadata import version

import pytest

import cli
import pefsim
import scenarios
from sim.montecarlo import lock
from sim.montecarlo.engine import sweep
from tests.sim.montecarlo import fake_episode as fe


def _refused(capsys, argv: list[str], match: str) -> str:
    code = cli.main(argv)
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert code == 2 and captured.out == "", captured
    assert len(lines) == 1 and lines[0].startswith("pefsim: error: ") and match in lines[0], lines
    return lines[0]


@pytest.fixture
def no_work(monkeypatch):
    """Make every PEF grid, plan and episode fail loudly: a refusal must come before them."""
    from planner.pef import map as pef_map
    from sim.episode import drive

    def boom(*_a, **_k):
        raise AssertionError("the work started before the output was checked")

    monkeypatch.setattr(pef_map.PEF, "__init__", boom)
    monkeypatch.setattr(drive, "prepare", boom)
    monkeypatch.setattr(drive, "run_episode", boom)


def test_version_and_bare_command(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"pefsim {version('pefsim')}"
    assert cli.main([]) == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: pefsim") and all(c in out for c in cli.COMMANDS)


@pytest.mark.parametrize("cmd", ["map", "plan"])
@pytest.mark.parametrize("name", ["map.txt", "plan"])
def test_figure_format_from_the_extension_or_refused_before_work(capsys, tmp_path, no_work, cmd, name):
    target = tmp_path / name
    line = _refused(capsys, [cmd, "paper-two-markers", "-o", str(target)], str(target))
    assert "expected .png, .pdf, .svg" in line
    assert list(tmp_path.iterdir()) == []  # neither the path nor path.png


def test_plan_writes_exactly_the_path_given(capsys, tmp_path):
    target = tmp_path / "plan.SVG"  # the extension's case does not matter
    assert cli.main(["plan", "paper-two-markers", "-o", str(target)]) == 0
    assert f"wrote {target}\n" in capsys.readouterr().out
    assert [p.name for p in tmp_path.iterdir()] == ["plan.SVG"] and target.read_bytes().startswith(b"<?xml")


def test_run_tum_folder_refused_before_the_episode(capsys, tmp_path, no_work):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    _refused(capsys, ["run", "paper-two-markers", "--tum", str(blocker / "tum")], "cannot write TUM trajectories")


def test_run_prints_a_wrote_line_per_file(capsys, tmp_path):
    rrd, tum = tmp_path / "run.rrd", tmp_path / "tum"
    assert cli.main(["run", "paper-two-markers", "--seed", "1", "--rrd", str(rrd), "--tum", str(tum)]) == 0
    wrote = [line for line in capsys.readouterr().out.splitlines() if line.startswith("wrote ")]
    assert wrote == [f"wrote {tum / 'groundtruth.txt'}", f"wrote {tum / 'estimate.txt'}", f"wrote {rrd}"]
    assert rrd.stat().st_size > 0 and (tum / "estimate.txt").stat().st_size > 0


def test_default_sweep_folder_is_a_plain_name_in_the_working_directory(tmp_path, monkeypatch):
    text = re.sub(r'(?m)^name = ".*"$', 'name = "../../up/and/away"', scenarios.load("paper-docks").text,
                  count=1)
    assert 'name = "../../up/and/away"' in text
    sc = scenarios.loads(text, source="evil.toml")
    work = tmp_path / "a" / "b"
    work.mkdir(parents=True)
    monkeypatch.chdir(work)
    summary = sweep(sc, runs=1, workers=1, api=fe.API, progress=False)
    assert os.sep not in summary.out and summary.out.startswith("mc-")
    assert [p.name for p in work.iterdir()] == [summary.out]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a"] and [p.name for p in (tmp_path / "a").iterdir()] == ["b"]


def test_validate_from_a_sweep_being_written_says_so(capsys, tmp_path):
    out = tmp_path / "sw"
    sweep(scenarios.load("paper-docks"), out, runs=2, workers=1, api=fe.API, progress=False)
    holder = lock.me()  # this very process: alive, so the lock is not stale
    lock.lock_path(out).write_text(json.dumps(holder.__dict__) + "\n")
    line = _refused(capsys, ["validate", "--from", str(out)], f"{out} is being written by pid {holder.pid}")
    assert "once that sweep has finished" in line
    lock.lock_path(out).unlink()
    with pytest.raises(pefsim.PefsimError, match="holds no finished run|made from another"):
        pefsim.validate(out, scenario="paper-two-markers")  # unlocked: read as usual (and judged)


def _plan_text(name: str) -> str:
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert cli.main(["plan", name]) == 0
    return buf.getvalue()


def test_plan_counts_every_fix_it_slows_down():
    """The fixes slowed down and their time are those of the chosen route's slow column.

    ``paper-two-markers`` slows its route down (the hall, where whole stretches were slowed,
    no longer is under the line-of-sight rule).
    """
    text = _plan_text("paper-two-markers")
    chosen = next(line for line in text.splitlines() if "CHOSEN" in line)
    slow_column = float(chosen.split()[6])
    m = re.search(r"; (\d+) fixes slowed down \(\+([\d.]+) s\)", text)
    assert m, text
    assert float(m.group(2)) == slow_column > 0 and int(m.group(1)) > 0


def test_plan_notes_give_tau_in_the_table_unit():
    """The notes of inadmissible routes give tau in mm, as the table does."""
    notes = [line for line in _plan_text("warehouse").splitlines() if "inadmissible: tau" in line]
    assert notes
    for line in notes:
        max_tau_mm = float(line.split()[4])  # the max tau [mm] column
        m = re.search(r"inadmissible: tau ([\d.]+) mm >= eps_max 30 mm", line)
        assert m and abs(float(m.group(1)) - max_tau_mm) < 0.01, line
