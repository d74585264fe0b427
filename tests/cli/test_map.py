"""``pefsim map``: PNG, NPZ and JSON with the documented contents; default output; exit 2."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import scenarios
from cli import main
from planner.pef.map import PEF
from validation.report.scene import display_field

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def run_cli(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_png_npz_and_json(tmp_path, capsys):
    png, npz = tmp_path / "m.png", tmp_path / "m.data"  # any name: numpy must not add ".npz"
    code, out, err = run_cli(capsys, "map", "warehouse", "--resolution", "0.5", "-o", str(png),
                             "--npz", str(npz), "--json")
    assert code == 0 and err == ""
    doc = json.loads(out)
    assert png.read_bytes()[:8] == PNG_MAGIC and png.stat().st_size > 20_000

    sc = scenarios.load("warehouse")
    ref = PEF(sc).grid(0.5)
    with np.load(npz) as z:
        assert set(z.files) == {"tau", "x", "y", "best"}
        tau, x, y, best = z["tau"], z["x"], z["y"], z["best"]
    assert tau.shape == (40, 60) and x.shape == (60,) and y.shape == (40,) and best.shape == (40, 60, 2)
    np.testing.assert_array_equal(tau, ref.tau)
    np.testing.assert_array_equal(best, ref.best)
    np.testing.assert_allclose(x, (np.arange(60) + 0.5) * 0.5)
    assert np.isinf(tau[~ref.free]).all() and np.isfinite(tau).any()

    assert doc["model"] == "parallelogram" and doc["resolution"] == 0.5
    assert doc["eps_max"] == sc.planning.eps_max and doc["cells"] == 2400
    free_tau = ref.tau[ref.free]
    finite = free_tau[np.isfinite(free_tau)]
    assert doc["fraction_navigable"] == pytest.approx(np.mean(free_tau < sc.planning.eps_max))
    assert 0.5 < doc["fraction_navigable"] < 1.0
    assert doc["tau_min"] == pytest.approx(finite.min())
    assert doc["tau_median"] == pytest.approx(np.median(finite))
    assert doc["tau_max"] == pytest.approx(finite.max())


def test_model_option_and_json_only_writes_no_file(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, _ = run_cli(capsys, "map", "paper-two-markers", "--model", "gdop", "--resolution", "0.25",
                           "--json")
    assert code == 0
    doc = json.loads(out)
    assert doc["model"] == "gdop" and doc["cells"] == 400
    assert list(tmp_path.iterdir()) == []
    ref = PEF(scenarios.load("paper-two-markers"), model="gdop").grid(0.25)
    assert doc["tau_max"] == pytest.approx(ref.tau[np.isfinite(ref.tau)].max())


def test_default_prints_a_summary_and_writes_nothing(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, _ = run_cli(capsys, "map", "paper-docks", "--resolution", "0.5")
    assert code == 0
    assert "navigation region" in out and "mm" in out and "wrote" not in out
    assert list(tmp_path.iterdir()) == []
    code, out, _ = run_cli(capsys, "map", "paper-docks", "--resolution", "0.5", "-o", "m.png")
    assert (tmp_path / "m.png").read_bytes()[:8] == PNG_MAGIC and "wrote m.png" in out


def test_bad_model_and_resolution_are_bad_input(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["map", "warehouse", "--model", "bogus"])
    assert exc.value.code == 2
    assert "bogus" in capsys.readouterr().err
    code, _, err = run_cli(capsys, "map", "warehouse", "--resolution", "-1", "--json")
    assert code == 2 and "resolution" in err and len(err.strip().splitlines()) == 1


def test_unwritable_output_exits_2_naming_the_path(tmp_path):
    bad = tmp_path / "no-such-dir" / "map.png"
    proc = subprocess.run([sys.executable, "-m", "cli", "map", "paper-two-markers", "--resolution", "0.5",
                           "-o", str(bad)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and str(bad) in lines[0] and "Traceback" not in proc.stderr
    assert not bad.exists()


def test_cells_without_a_fix_are_drawn_grey_not_clipped():
    tau = np.array([[1.0, np.inf], [500.0, 0.01]])
    shown = display_field(tau, 0.1, 100.0)
    assert shown.mask.tolist() == [[False, True], [False, False]]
    assert shown.compressed().tolist() == [1.0, 100.0, 0.1]
