"""``pefsim watch``: an edit updates the view, a bad edit is one error line and the view stays.

The command runs as a child process on a copy of a built-in (``--save``, so no viewer), its
output read line by line while the test edits the file; the saved recording is checked with
rerun's own verifier and read back.
"""

from __future__ import annotations

import os
import queue
import shutil
import signal
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np

from interop.recording import entities as E
from interop.recording.live import EDIT_TIMELINE
from scenarios.load import LIBRARY
from tests.interop.recording.readback import Readback

ROOT = Path(__file__).resolve().parents[3]
WAIT = 120.0  # [s] a first view compiles or loads numba kernels; generous against a loaded machine


class Child:
    """A ``pefsim watch`` child whose stdout and stderr lines arrive in one queue, tagged."""

    def __init__(self, args: list[str], cwd: Path):
        env = dict(os.environ, CI="1", PYTHONPATH=str(ROOT))
        # Ctrl-C's SIGINT as a terminal delivers it: a test run started in the background of a
        # non-interactive shell ignores SIGINT, and a child would inherit that and never end
        self.p = subprocess.Popen([sys.executable, "-m", "cli", "watch", *args], cwd=cwd, env=env, text=True,
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                  preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
        self.lines: queue.Queue = queue.Queue()
        for name, stream in (("out", self.p.stdout), ("err", self.p.stderr)):
            threading.Thread(target=self._pump, args=(name, stream), daemon=True).start()

    def _pump(self, name: str, stream) -> None:
        for line in stream:
            self.lines.put((name, line.rstrip("\n")))

    def next(self) -> tuple[str, str]:
        return self.lines.get(timeout=WAIT)

    def rest(self) -> list[tuple[str, str]]:
        out = []
        while True:
            try:
                out.append(self.lines.get(timeout=1.0))
            except queue.Empty:
                return out


def _copy(tmp_path: Path) -> Path:
    path = tmp_path / "docks.toml"
    shutil.copy(LIBRARY / "paper-docks.toml", path)
    return path


def _verify(path: Path) -> None:
    verify = subprocess.run([sys.executable, "-m", "rerun", "rrd", "verify", str(path)], capture_output=True,
                            text=True, env=dict(os.environ, CI="1"))
    assert verify.returncode == 0, verify.stderr


def _marker_positions(path: Path) -> list[list]:
    """``world/markers`` positions of each update, in update order."""
    _, rows = Readback(path).column(E.MARKERS, "Points2D:positions", timeline=EDIT_TIMELINE)
    return rows


def test_edit_error_edit(tmp_path):
    scenario = _copy(tmp_path)
    good = scenario.read_text()
    assert 'position = [6.0, 12.0]' in good
    moved = good.replace('position = [6.0, 12.0]', 'position = [7.5, 12.0]', 1)
    rrd = tmp_path / "live.rrd"
    child = Child([scenario.name, "--save", rrd.name, "--interval", "0.05", "--max-updates", "3"], tmp_path)
    first = child.next()
    assert first[0] == "out" and first[1].startswith("updated in ")
    assert first[1].endswith("docks.toml: 6 markers, 1 task planned"), first

    scenario.write_text(moved)
    second = child.next()
    assert second[0] == "out" and second[1].startswith("updated in ") and second[1].endswith(
        "docks.toml: 6 markers, 1 task planned"), second

    scenario.write_text(moved.replace("[planning]", "[planning]\nbogus_key = 1", 1))
    error = child.next()
    assert error[0] == "err" and error[1].startswith("pefsim: error: docks.toml") and "bogus_key" in error[1], error
    assert child.p.poll() is None  # it lives on

    scenario.write_text(moved.replace('position = [14.0, 12.0]', 'position = [13.0, 12.0]', 1))
    third = child.next()
    assert third[0] == "out" and third[1].startswith("updated in "), third
    assert child.p.wait(timeout=WAIT) == 0
    rest = child.rest()
    assert rest == [("out", f"wrote {rrd.name}")], rest  # no second error line, no traceback

    _verify(rrd)
    back = Readback(rrd)
    for entity in (E.PEF, E.PEF_NO_FIX, E.REGION, E.NETWORK_OK, E.of_task(E.CHOSEN, 0), E.of_task(E.SCHEDULE, 0),
                   E.VIEW_TEXT):
        assert back.chunks[entity], entity
    views = _marker_positions(rrd)
    assert len(views) == 3  # one per update; the refused version logged nothing
    assert np.allclose(views[0][0], [6.0, 12.0]) and np.allclose(views[1][0], [7.5, 12.0])
    assert np.allclose(views[2][0], [7.5, 12.0]) and np.allclose(views[2][1], [13.0, 12.0])


def test_ctrl_c_ends_cleanly(tmp_path):
    scenario = _copy(tmp_path)
    rrd = tmp_path / "live.rrd"
    child = Child([scenario.name, "--save", rrd.name, "--interval", "0.05"], tmp_path)
    assert child.next()[1].startswith("updated in ")
    child.p.send_signal(signal.SIGINT)
    assert child.p.wait(timeout=WAIT) == 0
    assert child.rest() == [("out", f"wrote {rrd.name}")]
    _verify(rrd)
    assert len(_marker_positions(rrd)) == 1


def test_first_version_bad_then_fixed(tmp_path):
    """A file that is bad from the start is reported, and watched until it is fixed."""
    scenario = _copy(tmp_path)
    good = scenario.read_text()
    scenario.write_text(good.replace("[planning]", "[planning]\nbogus_key = 1", 1))
    rrd = tmp_path / "live.rrd"
    child = Child([scenario.name, "--save", rrd.name, "--interval", "0.05", "--max-updates", "1"], tmp_path)
    error = child.next()
    assert error[0] == "err" and "bogus_key" in error[1]
    scenario.write_text(good)
    assert child.next()[1].startswith("updated in ")
    assert child.p.wait(timeout=WAIT) == 0
    _verify(rrd)


def test_refused_before_watching(tmp_path, capsys):
    """An unknown scenario, a recording that cannot be written or is not .rrd: one line, exit 2, nothing written."""
    from cli import main

    scenario = _copy(tmp_path)
    for args, said in (([str(tmp_path / "nope.toml"), "--save", str(tmp_path / "a.rrd")], "nope.toml"),
                       ([str(scenario), "--save", str(tmp_path / "no" / "a.rrd")], "does not exist"),
                       ([str(scenario), "--save", str(tmp_path / "a.txt")], "expected a .rrd file")):
        assert main(["watch", *args]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("pefsim: error: ") and said in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["docks.toml"]


def test_route_colours_keep_no_fix_apart():
    """τ = ∞ is not the colour of the worst finite τ; the ramp runs green, yellow, red up to ε_max."""
    from interop.recording.live import tau_colors

    c = tau_colors(np.array([0.0, 0.015, 0.03, 0.09, np.inf]), 0.03)
    assert [tuple(x) for x in c] == [E.TAU_GOOD, E.TAU_MID, E.TAU_LIMIT, E.TAU_LIMIT, E.NO_FIX]
    assert E.NO_FIX not in (E.TAU_GOOD, E.TAU_MID, E.TAU_LIMIT)
