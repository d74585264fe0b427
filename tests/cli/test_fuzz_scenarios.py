"""The input contract under mutation: every command exits 0, or 2 with one line and no traceback.

Hypothesis mutates the built-in scenarios (keys changed, deleted or retyped, numbers pushed to
extremes, NaN and inf, empty lists, points outside the workspace, swapped ids; and plausible
edits, numbers scaled by 0.5-2 and points moved by up to a metre, so that many mutants still
load and reach the planner, the grid and the physics) and runs ``map``,
``plan`` and ``run`` in-process through :func:`cli.main`. A bug shows as an exception (the
CLI lets anything but ``PefsimError`` through), a second stderr line, or a numpy / matplotlib
warning. The profile is derandomised, so CI sees the same examples every time.
"""

from __future__ import annotations

import contextlib
import io
import math
import tempfile
import tomllib
import warnings
from pathlib import Path

import pytest
import tomli_w
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st

from cli import main
from scenarios.load import LIBRARY

EXTREMES = [0, -1, 1, 2, 10**9, 2**63 - 1, -(2**63), 0.0, -0.0, 1e-9, -1e-9, 1e12, -1e12, 1e308, -1e308,
            math.inf, -math.inf, math.nan, 5e-324, "", "x", "exact", True, False, [], {}, [1e12, 1e12],
            [math.nan, 0.0], [-5.0, -5.0], [1e8, 1e8], [0.0, 0.0, 0.0], [[0.0, 0.0]], {"x": 1}]

def profile(max_examples: int) -> settings:
    """Return the fixed, derandomised profile (no example database: CI reruns exactly these)."""
    return settings(max_examples=max_examples, derandomize=True, database=None, deadline=None, print_blob=True,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def _paths(doc, prefix=()):
    """Every key path of a parsed TOML document (tables, arrays and leaves)."""
    out = []
    items = doc.items() if isinstance(doc, dict) else enumerate(doc) if isinstance(doc, list) else ()
    for k, v in items:
        out.append((*prefix, k))
        out += _paths(v, (*prefix, k))
    return out


def _number(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def _parent(doc, path):
    for k in path[:-1]:
        doc = doc[k]
    return doc


@st.composite
def mutated(draw, name: str):
    """Draw a built-in scenario's document with 1 to 3 mutations."""
    doc = tomllib.loads((LIBRARY / f"{name}.toml").read_text())
    for _ in range(draw(st.integers(1, 3))):
        paths = _paths(doc)
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        parent, key = _parent(doc, path), path[-1]
        action = draw(st.sampled_from(["nudge", "nudge", "nudge", "set", "set", "delete", "scale", "swap",
                                       "outside"]))
        value = parent[key]
        if action == "nudge" and _number(value):
            # a plausible edit: what a user changes, still mostly a valid floor
            f = draw(st.floats(0.5, 2.0))
            parent[key] = max(1, round(value * f)) if isinstance(value, int) else value * f
        elif action == "nudge" and isinstance(value, list) and 2 <= len(value) <= 3 and all(map(_number, value)):
            dx, dy = draw(st.floats(-1.0, 1.0)), draw(st.floats(-1.0, 1.0))
            parent[key] = [value[0] + dx, value[1] + dy, *value[2:]]
        elif action == "nudge":
            continue
        elif action == "delete":
            del parent[key]
        elif action == "scale" and isinstance(parent[key], (int, float)) and not isinstance(parent[key], bool):
            parent[key] = parent[key] * draw(st.sampled_from([-1, 0, 0.5, 2, 1e-9, 1e9, 1e300]))
        elif action == "swap" and isinstance(parent, list) and len(parent) > 1:
            other = draw(st.integers(0, len(parent) - 1))
            parent[key], parent[other] = parent[other], parent[key]
        elif action == "outside" and isinstance(parent[key], list) and len(parent[key]) in (2, 3):
            parent[key] = [1e4, -1e4, *parent[key][2:]]
        else:
            parent[key] = draw(st.sampled_from(EXTREMES))
    return doc


def _run_cli(doc, command: list[str]) -> tuple[int, str]:
    """Run ``pefsim COMMAND scenario`` on ``doc``; return the exit code and stderr."""
    try:
        text = tomli_w.dumps(doc)
    except (TypeError, ValueError):
        assume(False)  # not expressible in TOML
    out, err = io.StringIO(), io.StringIO()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "mutant.toml"
        path.write_text(text)
        with warnings.catch_warnings(record=True) as caught, contextlib.redirect_stdout(out), \
                contextlib.redirect_stderr(err):
            warnings.simplefilter("always")
            code = main([command[0], str(path), *command[1:]])
    assert not caught, [f"{w.category.__name__}: {w.message} ({w.filename}:{w.lineno})" for w in caught]
    return code, err.getvalue()


def _check(code: int, err: str) -> None:
    event(f"exit {code}")  # --hypothesis-show-statistics: how many mutants still run
    assert "Traceback" not in err
    if code == 0:
        assert err == "", err
        return
    assert code == 2, (code, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pefsim: error: "), err


@profile(60)
@given(st.sampled_from(["warehouse", "paper-docks", "paper-two-markers", "corridor-gaussian"]).flatmap(mutated))
def test_map_keeps_the_contract(doc):
    _check(*_run_cli(doc, ["map", "--json"]))


@profile(40)
@given(st.sampled_from(["paper-docks", "warehouse"]).flatmap(mutated))
def test_plan_keeps_the_contract(doc):
    _check(*_run_cli(doc, ["plan", "--json"]))


@profile(8)
@given(mutated("paper-docks"))
def test_run_keeps_the_contract(doc):
    _check(*_run_cli(doc, ["run", "--json"]))


# --------------------------------------------------------------------------- hand-made ones

def _mini(extra_planning: str = "", sensor: str = "", workspace: str = "size = [10.0, 10.0]",
          routes: str = "") -> str:
    return (f'name = "mini"\n[workspace]\n{workspace}\n'
            '[[obstacles]]\ncenter = [5.0, 5.0]\nsize = [2.0, 2.0]\n'
            '[[markers]]\nid = "a"\nposition = [0.0, 0.0]\n[[markers]]\nid = "b"\nposition = [10.0, 0.0]\n'
            f'[sensor]\n{sensor}\n[planning]\n{extra_planning or "eps_max = 0.05"}\n'
            '[[docks]]\nname = "A"\npose = [1.0, 1.0, 0.0]\n[[docks]]\nname = "B"\npose = [9.0, 9.0, 0.0]\n'
            f'{routes}[[tasks]]\nfrom = "A"\nto = "B"\n')


BAD = [
    ("eps huge", _mini("eps_max = 1e308"), "planning.eps_max: expected a number <= 100"),
    ("eps nan", _mini("eps_max = nan"), "planning.eps_max: expected a finite number, got nan"),
    ("eps inf", _mini("eps_max = inf"), "planning.eps_max: expected a finite number, got inf"),
    ("resolution tiny", _mini("eps_max = 0.05\nresolution = 1e-9"), "planning.resolution: expected a cell size "
     "giving at most 2e+08 grid cells over the 10 x 10 m workspace (1e+20 cells), got 1e-09"),
    ("workspace huge", _mini(workspace="size = [1e12, 1e12]"), "workspace.size: expected [width, height] in "
     "metres of magnitude at most 1e+08"),
    ("range huge", _mini(sensor="max_range = 1e308"), "sensor.max_range: expected a number <= 10000"),
    ("range inf", _mini(sensor="max_range = inf"), "sensor.max_range: expected a finite number, got inf"),
    ("k huge", _mini(sensor="markers_per_fix = 1000"), "sensor.markers_per_fix: expected an integer <= 8"),
    ("position inf", _mini().replace("position = [10.0, 0.0]", "position = [inf, 0.0]"),
     "markers[1].position: expected [x, y], got [inf, 0.0]"),
    ("segment through the box", _mini(routes='[routes]\nnodes = { A = [1.0, 1.0], B = [9.0, 9.0] }\n'
                                             'segments = [["A", "B"]]\n'),
     "routes.segments[0]: A-B crosses obstacles[0]"),
]


@pytest.mark.parametrize("label,text,message", BAD, ids=[b[0] for b in BAD])
@pytest.mark.parametrize("command", ["map", "plan", "run"])
def test_absurd_values_exit_2_naming_the_key(tmp_path, capsys, label, text, message, command):
    path = tmp_path / "mini.toml"
    path.write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main([command, str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"pefsim: error: {path}: "), err
    assert message in err, err
