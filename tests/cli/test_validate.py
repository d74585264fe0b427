"""``pefsim validate`` end to end on real episodes.

Every built-in scenario passes, and the negative controls (a sensor 3x noisier than declared,
a filter with 100x too little process noise, gaussian fixes 3x noisier than their covariance)
fail the check they must.

Sizes fit CI on 2 workers (about 2 minutes in all): paper-two-markers 20 runs, paper-docks
10, warehouse 6; negative controls 6 runs each (their statistics are far outside the
acceptance regions: 3x noise gives ~70 % containment misses, q_scale 0.01 a NEES of ~100).
Each statistical check has false-alarm probability 0.0017 (family alpha 0.01 over 6 checks);
seeds are the scenarios' own, so the verdicts are reproducible.
"""

from __future__ import annotations

import contextlib
import io
import json
import shutil

import pytest

import cli
import scenarios
from tests.cli.json_capture import printed, run_json

PASS, FAIL, NA = "pass", "FAIL", "not applicable"


def _validate(capsys, argv: list[str]) -> tuple[int, dict]:
    code = cli.main(["validate", *argv, "--json"])
    out = capsys.readouterr().out
    return code, json.loads(out)


def _status(report: dict) -> dict[str, str]:
    return {c["name"]: c["status"] for c in report["checks"]}


def _bad(capsys, argv: list[str], match: str) -> None:
    code = cli.main(["validate", *argv])
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pefsim: error: "), err
    assert match in lines[0], lines[0]


def _variant(tmp_path, name: str, extra: str, replace: tuple[str, str] = ("", "")) -> str:
    text = scenarios.load(name).text.replace(*replace) + "\n" + extra
    path = tmp_path / f"{name}-variant.toml"
    path.write_text(text)
    return str(path)


UNIFORM_BUILTIN = {"containment": PASS, "promise": PASS, "bound": PASS, "tightness": PASS, "coverage": NA,
                   "nees": PASS, "nis": PASS, "nees_nrun": PASS, "nis_nrun": PASS, "plan": PASS,
                   "blocking": NA}  # a lone robot: no robot blocks its lines of sight


@pytest.fixture(scope="module")
def two_markers(tmp_path_factory):
    """paper-two-markers, 20 runs, kept for the --from tests."""
    out = tmp_path_factory.mktemp("two") / "mc"
    buf = io.StringIO()  # a module-scoped fixture cannot use capsys
    with contextlib.redirect_stdout(buf):
        code = cli.main(["validate", "paper-two-markers", "--runs", "20", "--workers", "2", "--out", str(out),
                         "--json"])
    return out, code, json.loads(buf.getvalue())


@pytest.mark.e2e  # a real sweep; the checks and their negative controls run on tables in tests/validation
def test_paper_two_markers_passes(two_markers):
    _, code, report = two_markers
    assert code == 0, report["failed"]
    assert _status(report) == UNIFORM_BUILTIN
    assert report["runs"] == 20 and report["alpha_per_check"] == pytest.approx(0.01 / 6)


@pytest.mark.e2e  # a real sweep; the checks and their negative controls run on tables in tests/validation
@pytest.mark.parametrize(("name", "runs"), [("paper-docks", 10), ("warehouse", 6)])
def test_builtin_scenario_passes(capsys, tmp_path, name, runs):
    code, report = _validate(capsys, [name, "--runs", str(runs), "--workers", "2"])
    assert code == 0, report["failed"]
    assert _status(report) == UNIFORM_BUILTIN
    assert report["sweep"] is None  # a temporary sweep


def test_from_directory_reproduces_the_verdicts_and_prints_a_table(capsys, small_validated_sweep):
    out, _, report = small_validated_sweep
    code, again = _validate(capsys, ["--from", str(out)])
    assert code == 0
    assert again["checks"] == report["checks"]  # same tables, same seeded null model
    code = cli.main(["validate", "paper-two-markers", "--from", str(out), "--alpha", "0.05"])
    text = capsys.readouterr().out
    n = round(0.01 / report["alpha_per_check"])   # the statistical checks that apply to these tables
    assert f"family alpha 0.05 over {n} statistical checks: {0.05 / n:.3g} each" in text
    header = next(line for line in text.splitlines() if line.startswith("check"))
    assert header.split() == ["check", "statistic", "acceptance", "region", "alpha", "verdict"]
    # a family alpha of 5 % fails an honest sweep 1 time in 20: the verdict line and the exit code agree
    passed = text.rstrip().endswith("all applicable checks passed")
    assert code == (0 if passed else 1) and (passed or "FAILED: " in text)


def test_from_rejects_another_scenario_and_sweep_flags(capsys, small_validated_sweep):
    out = str(small_validated_sweep[0])
    _bad(capsys, ["paper-docks", "--from", out], "was made from another scenario")
    _bad(capsys, ["--from", out, "--runs", "3"], "--runs: not with --from")
    _bad(capsys, ["--from", out, "--q-scale", "0.1"], "--q-scale: not with --from")


def test_bad_input_exits_2(capsys, tmp_path):
    _bad(capsys, [], "scenario: expected a scenario name or file")
    _bad(capsys, ["paper-docks", "--alpha", "1.5"], "alpha: expected a family false-alarm probability in (0, 1)")
    _bad(capsys, ["paper-docks", "--q-scale", "-1"], "q_scale: expected a positive number")
    _bad(capsys, ["paper-docks", "--runs", "0"], "runs: expected a positive number")
    _bad(capsys, ["--from", str(tmp_path)], "not a pefsim mc directory")
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("x")
    _bad(capsys, ["paper-docks", "--out", str(tmp_path / "full")], "output directory is not empty")


@pytest.mark.e2e  # a real sweep; the checks and their negative controls run on tables in tests/validation
def test_negative_control_sensor_three_times_noisier(capsys, tmp_path):
    scenario = _variant(tmp_path, "paper-two-markers",
                        "[sensor.actual]\nrelative_error = 2.0e-4\nabsolute_error = 0.0003\n")
    code, report = _validate(capsys, [scenario, "--runs", "6", "--workers", "2"])
    assert code == 1
    s = _status(report)
    # (the bound is the moving fix's promise, which carries a shift margin: 3x the range noise
    # need not exceed it in 6 runs; containment is the sharp test of the range bounds)
    assert s["containment"] == FAIL
    assert s["nis"] == FAIL  # innovations 3x the predicted std
    assert {"containment", "nis"} <= set(report["failed"])


@pytest.mark.e2e  # a real sweep; the checks and their negative controls run on tables in tests/validation
def test_negative_control_filter_with_too_little_process_noise(capsys, tmp_path):
    out = tmp_path / "mc"
    code, report = _validate(capsys, ["paper-two-markers", "--runs", "6", "--workers", "2",
                                      "--q-scale", "0.01", "--out", str(out)])
    assert code == 1
    nees = next(c for c in report["checks"] if c["name"] == "nees")
    assert nees["status"] == FAIL and "overconfident" in nees["detail"]
    assert report["q_scale"] == 0.01
    # The sweep remembers it was a negative control.
    code = cli.main(["validate", "--from", str(out)])
    text = capsys.readouterr().out
    assert code == 1 and "NEGATIVE CONTROL" in text and "FAILED: " in text and "nees" in text


@pytest.mark.e2e  # a real sweep; the checks and their negative controls run on tables in tests/validation
def test_gaussian_coverage_and_its_negative_control(capsys, tmp_path):
    gauss = ('noise = "uniform"', 'noise = "gaussian"')
    code, report = _validate(capsys, [_variant(tmp_path, "paper-two-markers", "", gauss), "--runs", "12",
                                      "--workers", "2"])
    assert code == 0, report["failed"]
    status = _status(report)
    # with 12 runs the thinned per-step NEES may keep fewer than 10 steps (then not applicable)
    assert status.pop("nees_nrun") in (PASS, NA)
    assert status == {"containment": NA, "promise": NA, "bound": NA, "tightness": NA, "coverage": PASS,
                      "nees": PASS, "nis": PASS, "nis_nrun": PASS, "plan": PASS, "blocking": NA}
    noisy = _variant(tmp_path, "paper-two-markers", "[sensor.actual]\nrelative_error = 2.0e-4\n"
                     "absolute_error = 0.0003\n", gauss)
    code, report = _validate(capsys, [noisy, "--runs", "6", "--workers", "2"])
    assert code == 1 and _status(report)["coverage"] == FAIL


def test_mc_prints_the_sweeps_dict(capsys, monkeypatch, small_validated_sweep, tmp_path):
    out = tmp_path / "mc"
    shutil.copytree(small_validated_sweep[0], out)  # resumed with nothing left to run: no episode
    argv = ["mc", "paper-two-markers", "--out", str(out), "--resume", "--no-report"]
    doc, result = run_json(capsys, monkeypatch, "sweep", argv)
    assert doc == printed(result.to_dict())
    assert doc["runs"] == 4 and doc["executed"] == 0


def test_validate_prints_the_reports_dict(capsys, monkeypatch, small_validated_sweep):
    doc, result = run_json(capsys, monkeypatch, "validate", ["validate", "--from", str(small_validated_sweep[0])])
    assert doc == printed(result.to_dict())
    assert doc["sweep"] == str(small_validated_sweep[0]) and doc["wall_time"] > 0
