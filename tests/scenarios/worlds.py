"""Scenario texts and small worlds that several test modules share.

``MINIMAL`` and ``BAD`` (a valid scenario and the bad variants of it, each with the one-line
message it must give), floor-plan scenario texts, a hall with a U-shaped cup, a room with flat
reflectors, and built-ins moved to another origin.
"""

from __future__ import annotations

import tomllib

import scenarios

MINIMAL = """
name = "mini"
seed = 3
[workspace]
size = [10.0, 8.0]
[[obstacles]]
center = [5.0, 4.0]
size = [2.0, 1.0]
yaw_deg = 30.0
[[markers]]
id = "M1"
position = [0.0, 0.0]
[[markers]]
id = "M2"
position = [10.0, 0.0]
[[markers]]
id = "M3"
position = [10.0, 8.0]
[sensor]
relative_error = 1e-4
absolute_error = 0.001
noise = "gaussian"
bearing_error_deg = 0.5
[sensor.actual]
relative_error = 3e-4
[robot]
wheel_radius = 0.1
[robot.actual]
wheel_radius_error = 0.004
[planning]
eps_max = 0.05
[[docks]]
name = "A"
pose = [1.0, 1.0, 90.0]
[[docks]]
name = "B"
pose = [9.0, 7.0, 0.0]
[[tasks]]
from = "A"
to = "B"
"""


def _bad(old: str, new: str, count: int = 1) -> str:
    assert old in MINIMAL, old
    return MINIMAL.replace(old, new, count)


BAD = [
    # (label, toml text, regex the one-line message must match)
    ("malformed", MINIMAL + "\n[workspace\n", r"^mini\.toml: malformed TOML"),
    ("missing key", _bad('name = "mini"\n', ""), r"^mini\.toml: name: missing required key$"),
    ("unknown key", _bad("seed = 3", "seed = 3\nsead = 4"), r"^mini\.toml: sead: unknown key, got 4$"),
    ("unknown nested key", _bad("eps_max = 0.05", "eps_max = 0.05\nepsmax = 1"),
     r"^mini\.toml: planning\.epsmax: unknown key"),
    ("wrong type", _bad("eps_max = 0.05", 'eps_max = "small"'),
     r'^mini\.toml: planning\.eps_max: expected a number, got "small"$'),
    ("nan", _bad("relative_error = 1e-4", "relative_error = nan"),
     r"^mini\.toml: sensor\.relative_error: expected a finite number, got nan$"),
    ("negative error", _bad("absolute_error = 0.001", "absolute_error = -0.001"),
     r"^mini\.toml: sensor\.absolute_error: expected a number >= 0, got -0\.001$"),
    ("marker outside", _bad("position = [10.0, 8.0]", "position = [31.0, 2.0]"),
     r"^mini\.toml: markers\[2\]\.position: expected \[x, y\] inside the workspace, got \[31\.0, 2\.0\]$"),
    ("marker inside obstacle", _bad("position = [10.0, 8.0]", "position = [5.0, 4.0]"),
     r"^mini\.toml: markers\[2\]\.position: expected \[x, y\] outside obstacles"),
    ("dock outside", _bad("pose = [9.0, 7.0, 0.0]", "pose = [9.0, 9.0, 0.0]"),
     r"^mini\.toml: docks\[1\]\.pose: expected .* inside the workspace, got \[9\.0, 9\.0, 0\.0\]$"),
    ("dock inside obstacle", _bad("pose = [9.0, 7.0, 0.0]", "pose = [5.2, 4.1, 0.0]"),
     r"^mini\.toml: docks\[1\]\.pose: expected .* outside obstacles"),
    ("k too large", _bad('noise = "gaussian"', 'noise = "gaussian"\nmarkers_per_fix = 4'),
     r"^mini\.toml: sensor\.markers_per_fix: expected at most the number of markers \(3\), got 4$"),
    ("bad enum", _bad('noise = "gaussian"', 'noise = "laplace"'),
     r'^mini\.toml: sensor\.noise: expected one of "uniform", "gaussian", got "laplace"$'),
    ("bad vector", _bad("size = [10.0, 8.0]", "size = [10.0]"),
     r"^mini\.toml: workspace\.size: expected \[width, height\] in metres, got \[10\.0\]$"),
    ("unknown dock in task", _bad('to = "B"', 'to = "Z"'),
     r'^mini\.toml: tasks\[0\]\.to: expected a dock name \(A, B\), got "Z"$'),
    ("duplicate marker id", _bad('id = "M2"', 'id = "M1"'),
     r'^mini\.toml: markers\[1\]\.id: expected a unique marker id, got "M1"$'),
    ("bool is not a number", _bad("eps_max = 0.05", "eps_max = true"),
     r"^mini\.toml: planning\.eps_max: expected a number, got true$"),
    ("unknown key in actual", _bad("relative_error = 3e-4", "relative_eror = 3e-4"),
     r"^mini\.toml: sensor\.actual\.relative_eror: unknown key"),
    ("negative hold", MINIMAL + "\n[montecarlo]\nhold = -5.0\n",
     r"^mini\.toml: montecarlo\.hold: expected a number >= 0, got -5\.0$"),
]


REST = """
[[markers]]
id = "M1"
position = [3.0, 3.0]
[[markers]]
id = "M2"
position = [3.5, 3.0]
[sensor]
[planning]
eps_max = 0.05
[[docks]]
name = "A"
pose = [3.0, 2.0, 0.0]
"""


def scenario_text(floorplan: str, extra: str = "") -> str:
    return f'name = "fp"\n{extra}\n[floorplan]\n{floorplan}\n{REST}'


DXF = 'file = "hall.dxf"\nobstacle_layers = ["A-WALL", "A-RACK", "S-COLS"]\nmarker_layer = "AGV-REFL"'


# A 20 x 14 m hall; dock A sits in the cup of a U that opens upwards, dock B below the U:
# the straight line runs through the U's bottom bar, the route must climb out of the cup.
HALL = """
name = "cup"
[workspace]
size = [20.0, 14.0]
[[obstacles]]
polygon = [[6, 3], [14, 3], [14, 10], [12.5, 10], [12.5, 4.5], [7.5, 4.5], [7.5, 10], [6, 10]]
[[obstacles]]
center = [3.0, 11.5]
radius = 0.6
[[obstacles]]
polygon = [[15.5, 11], [19, 11], [19, 13.5], [15.5, 13.5]]
holes = [[[16.5, 11.8], [18, 11.8], [18, 12.7], [16.5, 12.7]]]
{markers}
[sensor]
relative_error = 1e-4
absolute_error = 0.001
max_range = 40.0
[robot]
radius = 0.4
[planning]
eps_max = 0.05
resolution = 0.1
[[docks]]
name = "A"
pose = [10.0, 7.0, 90.0]
[[docks]]
name = "B"
pose = [10.0, 1.2, 0.0]
[[tasks]]
from = "A"
to = "B"
"""


MARKERS = [(0, 2), (0, 7), (0, 12), (20, 2), (20, 7), (20, 12), (4, 0), (10, 0), (16, 0), (5, 14), (10, 14),
           (14, 14), (10, 4.5), (7.5, 8), (12.5, 8), (6, 6), (14, 6)]


def hall():
    text = "".join(f'[[markers]]\nid = "M{i}"\nposition = [{float(x)}, {float(y)}]\n'
                   for i, (x, y) in enumerate(MARKERS))
    return scenarios.loads(HALL.format(markers=text), "cup.toml")


def shifted(name: str, dx: float, dy: float) -> scenarios.Scenario:
    """Load built-in ``name`` with every position, and the workspace origin, moved by (dx, dy) [m]."""
    d = tomllib.loads(scenarios.load(name).text)
    move = lambda p: [p[0] + dx, p[1] + dy, *p[2:]]  # noqa: E731 - keeps a dock's yaw
    d["workspace"]["origin"] = [dx, dy]
    for ob in d.get("obstacles", []):
        if "polygon" in ob:
            ob["polygon"] = [move(v) for v in ob["polygon"]]
            ob["holes"] = [[move(v) for v in h] for h in ob.get("holes", [])]
        else:
            ob["center"] = move(ob["center"])
    for m in d["markers"]:
        m["position"] = move(m["position"])
    for k in d.get("docks", []):
        k["pose"] = move(k["pose"])
    if "routes" in d:
        d["routes"]["nodes"] = {n: move(p) for n, p in d["routes"]["nodes"].items()}
    if "placement" in d and "candidates" in d["placement"]:
        d["placement"]["candidates"] = [move(p) for p in d["placement"]["candidates"]]
    return scenarios.from_dict(d, f"{name}-shifted")


FLAT_TOML = """
name = "flat-test"
[workspace]
size = [12.0, 8.0]
[[obstacles]]
center = [6.0, 4.0]
size = [3.0, 1.0]
[[markers]]
id = "P1"
position = [0.0, 0.0]
[[markers]]
id = "P2"
position = [12.0, 8.0]
[[markers]]
id = "F1"
position = [6.0, 3.5]
kind = "flat"
facing_deg = -90.0
[[markers]]
id = "F2"
position = [0.0, 4.0]
kind = "flat"
facing_deg = 0.0
[[markers]]
id = "F3"
position = [12.0, 2.0]
kind = "flat"
facing_deg = 180.0
[[markers]]
id = "F4"
position = [6.0, 8.0]
kind = "flat"
facing_deg = -90.0
[[markers]]
id = "P3"
position = [3.0, 8.0]
[sensor]
relative_error = 1e-3
absolute_error = 0.002
max_range = 11.0
max_incidence_deg = 50.0
[planning]
eps_max = 0.05
resolution = 0.25
redundancy = REDUNDANCY
"""


def flat_scenario(redundancy: int = 0, text: str = FLAT_TOML) -> scenarios.Scenario:
    return scenarios.loads(text.replace("REDUNDANCY", str(redundancy)), "flat-test.toml")
