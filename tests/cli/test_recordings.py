"""Recordings written by the CLI from real episodes and maps, read back with rerun's reader."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import scenarios
from sim.episode.drive import run_episode
from tests.interop.recording.readback import Readback


@pytest.fixture(scope="module")
def run_rrd(tmp_path_factory):
    path = tmp_path_factory.mktemp("rrd") / "run.rrd"
    p = subprocess.run([sys.executable, "-m", "cli", "run", "paper-two-markers", "--seed", "4",
                        "--rrd", str(path), "--json"], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    return path, json.loads(p.stdout)


def test_run_recording_holds_the_episode(run_rrd):
    path, summary = run_rrd
    rb = Readback(path)
    for entity in ("world/pef", "world/region", "world/routes/chosen", "world/schedule", "world/robot/true",
                   "world/robot/estimate", "world/robot/covariance", "world/fix/fault_area",
                   "world/fix/predicted", "world/fix/snapshot", "world/fix/rays", "metrics/error",
                   "metrics/predicted_tau", "metrics/eps_max", "metrics/nees", "metrics/nis"):
        assert rb.chunks.get(entity), f"{entity} missing"
    # the same episode again in-process: the recording's error series is its error array
    r = run_episode(scenarios.load("paper-two-markers"), 0, seed=4)
    times, rows = rb.column("metrics/error", "Scalars:scalars")
    values = np.array([row[0] if isinstance(row, list) else row for row in rows], dtype=float)
    assert len(values) == len(r.steps.error) == summary["steps"]
    assert np.allclose(values, r.steps.error, rtol=0, atol=1e-12)
    assert np.allclose(np.asarray(times) * 1e-9, r.steps.t, atol=1e-6)
    _, polys = rb.column("world/fix/fault_area", "LineStrips2D:strips")
    assert sum(len(p) if isinstance(p, list) else 1 for p in polys) >= summary["fixes"] > 0
    # the rerun of this interpreter's environment, whether or not it is on PATH (an unactivated venv)
    verify = subprocess.run([sys.executable, "-m", "rerun", "rrd", "verify", str(path)], capture_output=True, text=True,
                            env={"CI": "1", "PATH": __import__("os").environ["PATH"]})
    assert verify.returncode == 0, verify.stderr


def test_unwritable_recording_is_refused_before_the_episode(tmp_path):
    p = subprocess.run([sys.executable, "-m", "cli", "run", "paper-two-markers", "--rrd",
                        str(tmp_path / "missing" / "x.rrd"), "--json"], capture_output=True, text=True)
    assert p.returncode == 2
    assert p.stdout == ""  # refused before the episode is driven
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "cannot write recording" in lines[0] and "Traceback" not in p.stderr


def test_map_recording_has_the_static_layers(tmp_path):
    from cli import main

    path = tmp_path / "map.rrd"
    assert main(["map", "paper-docks", "--rrd", str(path), "--json"]) == 0
    rb = Readback(path)
    for entity in ("world/workspace", "world/obstacles", "world/markers", "world/docks", "world/pef",
                   "world/region"):
        assert rb.chunks.get(entity), f"{entity} missing"
    assert not rb.chunks.get("metrics/error")  # static layers only


def test_plan_recording_has_routes_and_schedule(tmp_path):
    from cli import main

    path = tmp_path / "plan.rrd"
    assert main(["plan", "paper-docks", "-o", str(tmp_path / "plan.png"), "--rrd", str(path), "--json"]) == 0
    rb = Readback(path)
    for entity in ("world/pef", "world/region", "world/routes/candidates", "world/routes/chosen",
                   "world/schedule"):
        assert rb.chunks.get(entity), f"{entity} missing"
