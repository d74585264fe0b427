"""Bad scenario files through the command line: one line on stderr naming file and key, exit 2."""

from __future__ import annotations

import subprocess
import sys

import pytest

from cli import main
from tests.scenarios.worlds import BAD, MINIMAL


@pytest.mark.parametrize("label,text,pattern", BAD, ids=[b[0] for b in BAD])
def test_every_command_that_loads_a_scenario_reports_one_line(tmp_path, capsys, label, text, pattern):
    path = tmp_path / "mini.toml"
    path.write_text(text)
    for command in (["map", str(path), "--json"], ["run", str(path), "--json"]):
        assert main(command) == 2
        err = capsys.readouterr().err
        lines = err.strip().splitlines()
        assert len(lines) == 1, err
        # the file as the user gave it, then the key path and value as in the loader's message
        assert lines[0].startswith(f"pefsim: error: {path}: "), lines[0]
        assert pattern.removeprefix("^mini\\.toml: ").split(":")[0].replace("\\", "") in lines[0]


def test_no_traceback_in_a_real_process(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(MINIMAL.replace("eps_max = 0.05", "eps_max = -1.0"))
    p = subprocess.run([sys.executable, "-m", "cli", "map", str(path)], capture_output=True, text=True)
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert p.stderr.strip() == f"pefsim: error: {path}: planning.eps_max: expected a number > 0, got -1.0"


def test_missing_file_and_unknown_builtin(tmp_path, capsys):
    assert main(["map", str(tmp_path / "nope.toml")]) == 2
    assert "nope.toml: no such scenario file" in capsys.readouterr().err
    assert main(["map", "warehose"]) == 2
    assert "warehose: not a file and not a built-in scenario" in capsys.readouterr().err
