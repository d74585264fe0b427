"""Hostile inputs: files from other people's tools, bounded in time and memory, refused in one line.

Each case runs ``pefsim map`` in-process through :func:`cli.main` with stderr captured and
every warning recorded, and holds the input contract: exit 0, or exit 2 with exactly one line
``pefsim: error: ...`` of at most 1000 characters; no traceback, no library warning. A few
cases that used to exhaust memory or hang run in a child process under an address-space cap
(``resource.setrlimit``) and a time limit.

- one test per defect found with such files (a DXF block that inserts itself, a NaN arc, a 50000 x 50000
  PNG, a YAML alias bomb, a FIFO as the map image, ...), each naming what the message must say;
- hypothesis strategies for drawings (ezdxf documents with random entities, non-finite and
  huge values, nested and self-referencing blocks), maps (random headers, sizes, YAML) and route
  graphs (random JSON shapes and depths). The profiles are derandomised (CI sees the same
  examples every run) and small enough for the fast tier.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import struct
import subprocess
import sys
import warnings
import zlib
from pathlib import Path

import ezdxf
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st
from PIL import Image

from cli import main
from scenarios.errors import MAX_MESSAGE
from scenarios.limits import MAX_DXF_ENTITIES, MAX_MAP_PIXELS, MAX_NESTING, MAX_YAML_NODES

NAN, INF = math.nan, math.inf
TAIL = '[sensor]\n[planning]\neps_max = 0.05\nresolution = 0.5\n'
MINI = ('name = "mini"\n[workspace]\nsize = [10.0, 10.0]\n'
        '[[obstacles]]\ncenter = [5.0, 5.0]\nsize = [2.0, 2.0]\n'
        '[[markers]]\nid = "a"\nposition = [0.0, 0.0]\n[[markers]]\nid = "b"\nposition = [10.0, 0.0]\n'
        '[sensor]\n[planning]\neps_max = 0.05\nresolution = 0.5\n{planning}\n[robot]\n{robot}\n'
        '[[docks]]\nname = "A"\npose = [1.0, 1.0, 0.0]\n[[docks]]\nname = "B"\npose = [9.0, 9.0, 0.0]\n'
        '{routes}[[tasks]]\nfrom = "A"\nto = "B"\n{extra}')


def profile(max_examples: int) -> settings:
    """Return the fixed, derandomised profile (no example database: CI reruns exactly these)."""
    return settings(max_examples=max_examples, derandomize=True, database=None, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                           HealthCheck.function_scoped_fixture])


def run(argv: list[str]) -> tuple[int, str]:
    """Run ``pefsim ARGV`` in-process; return the exit code and stderr (no warning may escape)."""
    out, err = io.StringIO(), io.StringIO()
    with warnings.catch_warnings(record=True) as caught, contextlib.redirect_stdout(out), \
            contextlib.redirect_stderr(err):
        warnings.simplefilter("always")
        code = main(argv)
    assert not caught, [f"{w.category.__name__}: {w.message} ({w.filename}:{w.lineno})" for w in caught]
    return code, err.getvalue()


def holds(code: int, err: str) -> str:
    """Assert the input contract; return the error line ("" on exit 0)."""
    assert "Traceback" not in err, err
    if code == 0:
        assert err == "", err
        return ""
    assert code == 2, (code, err)
    lines = err.splitlines()
    assert len(lines) == 1 and err.endswith("\n") and lines[0].startswith("pefsim: error: "), err
    assert len(lines[0]) <= MAX_MESSAGE + len("pefsim: error: "), len(lines[0])
    return lines[0]


def refused(folder: Path, toml: str, *message: str, command: str = "map") -> str:
    """Write ``folder/s.toml``, run the command on it, assert exit 2 naming every ``message`` part."""
    path = folder / "s.toml"
    path.write_text(toml)
    code, err = run([command, str(path)])
    line = holds(code, err)
    assert code == 2, f"exit {code}: {err}"
    for m in message:
        assert m in line, line
    return line


# --------------------------------------------------------------------------- drawings

def drawing_toml(file: str = "f.dxf", marker: bool = False) -> str:
    m = 'marker_layer = "M"\n' if marker else ""
    return f'name = "h"\n[floorplan]\nfile = "{file}"\nobstacle_layers = ["W"]\n{m}units = "m"\n' + TAIL


def walled() -> ezdxf.document.Drawing:
    """Return a drawing of a 10 x 10 m room on layer W and an empty marker layer M."""
    doc = ezdxf.new("R2018")
    doc.layers.add("W")
    doc.layers.add("M")
    doc.modelspace().add_lwpolyline([(0, 0), (10, 0), (10, 10), (0, 10)], close=True, dxfattribs={"layer": "W"})
    return doc


def self_inserting(doc, msp) -> None:
    b = doc.blocks.new("A")
    b.add_line((0, 0), (1, 0), dxfattribs={"layer": "0"})
    for i in range(3):
        b.add_blockref("A", (i, 1), dxfattribs={"layer": "0"})
    msp.add_blockref("A", (2, 2), dxfattribs={"layer": "W", "xscale": 0.1, "yscale": 0.1})


def self_minsert(doc, msp) -> None:
    b = doc.blocks.new("A")
    b.add_line((0, 0), (1, 0), dxfattribs={"layer": "0"})
    b.add_blockref("A", (0, 0), dxfattribs={"layer": "0"}).grid(size=(30, 30), spacing=(1, 1))
    msp.add_blockref("A", (2, 2), dxfattribs={"layer": "W", "xscale": 0.01, "yscale": 0.01})


def fan_out(doc, msp) -> None:
    """No cycle, but 10 levels of 10 inserts each: 1e10 entities once expanded."""
    b = doc.blocks.new("L0")
    b.add_line((0, 0), (0.01, 0), dxfattribs={"layer": "0"})
    for level in range(1, 11):
        b = doc.blocks.new(f"L{level}")
        for _ in range(10):
            b.add_blockref(f"L{level - 1}", (0.0, 0.0), dxfattribs={"layer": "0"})
    msp.add_blockref("L10", (3, 3), dxfattribs={"layer": "W"})


def scaled_insert(doc, msp) -> None:
    b = doc.blocks.new("S")
    b.add_lwpolyline([(0, 0), (1, 0), (1, 1), (0, 1)], close=True, dxfattribs={"layer": "0"})
    msp.add_blockref("S", (5, 5), dxfattribs={"layer": "W", "xscale": 1e300, "yscale": 1e300})


DRAWINGS = [
    ("block inserting itself 3 times", self_inserting, ['block "A" inserts itself', f"{MAX_DXF_ENTITIES}"]),
    ("30 x 30 self-MINSERT", self_minsert, ['block "A" inserts itself', f"{MAX_DXF_ENTITIES}"]),
    ("fan-out 1e10", fan_out,
     [f'block "L10" expands to more than {MAX_DXF_ENTITIES} entities', f"at most {MAX_DXF_ENTITIES}"]),
    ("ARC NaN centre", lambda d, m: m.add_arc((NAN, 5), 1, 0, 90, dxfattribs={"layer": "W"}),
     ['ARC #', 'on layer "W"', "finite"]),
    ("ARC radius inf", lambda d, m: m.add_arc((5, 5), INF, 0, 90, dxfattribs={"layer": "W"}), ["ARC #", "finite"]),
    ("ARC angle NaN", lambda d, m: m.add_arc((5, 5), 1, NAN, 90, dxfattribs={"layer": "W"}), ["ARC #", "finite"]),
    ("degenerate SPLINE", lambda d, m: m.add_spline([(5, 5), (5, 5)], dxfattribs={"layer": "W"}),
     ['SPLINE #', 'on layer "W"']),
    ("CIRCLE r = inf", lambda d, m: m.add_circle((5, 5), INF, dxfattribs={"layer": "W"}), ["CIRCLE #", "finite"]),
    ("CIRCLE NaN centre", lambda d, m: m.add_circle((NAN, 5), 1, dxfattribs={"layer": "W"}), ["CIRCLE #", "finite"]),
    ("INSERT of a missing block",
     lambda d, m: m.new_entity("INSERT", {"name": "NOPE", "insert": (1, 1), "layer": "W"}),
     ['INSERT #', 'no', '"NOPE"']),
    ("LINE NaN", lambda d, m: m.add_line((NAN, 1), (3, 3), dxfattribs={"layer": "W"}), ["LINE #", "finite"]),
    ("LINE 1e300", lambda d, m: m.add_line((1e300, 1), (3, 3), dxfattribs={"layer": "W"}),
     ["LINE #", "at most 1e+08 m", "1e+300"]),
    ("INSERT scaled 1e300", scaled_insert, ['INSERT #', "1e+300"]),
    ("NaN reflector POINT", lambda d, m: m.add_point((NAN, 5), dxfattribs={"layer": "M"}),
     ['POINT #', 'on layer "M"', "finite"]),
]


@pytest.mark.parametrize("label,build,message", DRAWINGS, ids=[d[0] for d in DRAWINGS])
def test_hostile_drawing_is_one_line_naming_the_entity(tmp_path, label, build, message):
    doc = walled()
    build(doc, doc.modelspace())
    doc.saveas(tmp_path / "f.dxf")
    line = refused(tmp_path, drawing_toml(marker=label.startswith("NaN reflector")), *message)
    assert "workspace.size" not in line and "obstacles[" not in line  # the drawing's entity, not a key


def test_nesting_is_followed_deeper_than_16_blocks(tmp_path):
    """A box nested 20 blocks deep is an obstacle, not dropped at a fixed depth."""
    doc = walled()
    prev = None
    for i in range(20):
        b = doc.blocks.new(f"B{i}")
        if prev is None:
            b.add_lwpolyline([(4, 4), (5, 4), (5, 5), (4, 5)], close=True, dxfattribs={"layer": "0"})
        else:
            b.add_blockref(prev, (0, 0), dxfattribs={"layer": "0"})
        prev = f"B{i}"
    doc.modelspace().add_blockref(prev, (0, 0), dxfattribs={"layer": "W"})
    doc.saveas(tmp_path / "f.dxf")
    from scenarios.floorplan.dxf import read_dxf

    found = read_dxf(tmp_path / "f.dxf", obstacle_layers=["W"], units="m")
    assert found.obstacles[0]["holes"] == [[[4.0, 4.0], [4.0, 5.0], [5.0, 5.0], [5.0, 4.0]]]


def test_a_5000_character_file_name_is_one_short_line(tmp_path):
    line = refused(tmp_path, drawing_toml(file="x" * 5000 + ".dxf"), "floorplan.file", "too long")
    assert len(line) < 400


# --------------------------------------------------------------------------- maps

def map_toml() -> str:
    # maps of 30 x 30 px at 5 cm: cells of 5 cm keep the PEF grid above its 2 x 2 floor
    return 'name = "h"\n[floorplan]\nfile = "m.yaml"\n' + TAIL.replace("resolution = 0.5", "resolution = 0.05")


def map_yaml(image: str = "m.pgm", resolution: str = "0.05") -> str:
    return (f"image: {image}\nresolution: {resolution}\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
            "occupied_thresh: 0.65\nfree_thresh: 0.196\n")


def png_claiming(path: Path, w: int, h: int) -> None:
    """Write a PNG whose header says w x h (1 bit per pixel) and whose data is one compressed empty row."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xffffffff)
    ihdr = struct.pack(">IIBBBBB", w, h, 1, 0, 0, 0, 0)
    data = zlib.compress(b"\x00" + b"\xff" * ((w + 7) // 8))
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", data) + chunk(b"IEND", b""))


def alias_bomb() -> str:
    text = 'a: &a ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]\n'
    prev = "a"
    for n in "bcdefghi":
        text += f"{n}: &{n} [" + ", ".join([f"*{prev}"] * 9) + "]\n"
        prev = n
    return text + "image: *i\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\n"


def test_png_of_50000_x_50000_pixels_is_refused_from_its_header(tmp_path):
    (tmp_path / "m.yaml").write_text(map_yaml("m.png"))
    png_claiming(tmp_path / "m.png", 50000, 50000)
    refused(tmp_path, map_toml(), "image:", "50000 x 50000", f"at most {MAX_MAP_PIXELS:.3g}")


def test_pgm_header_claiming_60000_x_60000_is_refused(tmp_path):
    (tmp_path / "m.yaml").write_text(map_yaml())
    (tmp_path / "m.pgm").write_bytes(b"P5\n# a comment\n60000 60000\n255\n" + b"\xff" * 1000)
    refused(tmp_path, map_toml(), "image:", "60000 x 60000", "3.6e+09 pixels")


def test_yaml_alias_bomb_is_refused_without_expanding_it(tmp_path):
    (tmp_path / "m.yaml").write_text(alias_bomb())
    line = refused(tmp_path, map_toml(), "m.yaml", f"{MAX_YAML_NODES}", "aliases")
    assert "lol" not in line


def test_fifo_as_the_map_image_is_refused(tmp_path):
    (tmp_path / "m.yaml").write_text(map_yaml())
    os.mkfifo(tmp_path / "m.pgm")
    refused(tmp_path, map_toml(), "image:", "not a regular file")


def test_map_resolution_5e_2_reads_as_map_server_reads_it(tmp_path):
    (tmp_path / "m.yaml").write_text(map_yaml(resolution="5e-2"))
    (tmp_path / "m.pgm").write_bytes(b"P5\n40 40\n255\n" + bytes([254] * 1600))
    from scenarios.floorplan.rosmap import read_rosmap

    assert read_rosmap(tmp_path / "m.yaml").extent == (0.0, 0.0, 2.0, 2.0)  # 40 px x 0.05 m
    (tmp_path / "s.toml").write_text(map_toml())
    assert holds(*run(["map", str(tmp_path / "s.toml")])) == ""


# --------------------------------------------------------------------------- route graphs

def graph_toml() -> str:
    return MINI.format(planning="", robot="", routes='[routes]\nfile = "g.json"\n', extra="")


def test_route_graph_nested_100000_deep_is_refused(tmp_path):
    (tmp_path / "g.json").write_text("[" * 100_000 + "]" * 100_000)
    refused(tmp_path, graph_toml(), "g.json", "nested 100000 deep", f"at most {MAX_NESTING}")


@pytest.mark.parametrize("layouts", [
    [{"layoutId": "L", "nodes": 5, "edges": []}],
    [{"layoutId": "L", "nodes": [], "edges": []}, {"layoutId": "M", "nodes": 5, "edges": []}],
], ids=["the layout read", "another layout"])
def test_lif_nodes_a_number(tmp_path, layouts):
    (tmp_path / "g.json").write_text(json.dumps({"layouts": layouts}))
    toml = graph_toml().replace('file = "g.json"\n', 'file = "g.json"\nlayout = "L"\n')
    (tmp_path / "s.toml").write_text(toml)
    line = holds(*run(["map", str(tmp_path / "s.toml")]))
    if len(layouts) == 1:
        assert "layouts[0].nodes: expected a list, got 5" in line


# --------------------------------------------------------------------------- scenario values

VALUES = [
    ("max_speed 1e-6", dict(robot="max_speed = 1e-6"), "plan", ["robot.max_speed", "path samples", "at most 1e+07"]),
    ("max_yaw_rate 1e-9", dict(robot="max_yaw_rate = 1e-9"), "plan",
     ["robot.max_yaw_rate", "path samples", "at most 1e+07"]),
    ("redundancy 1000", dict(planning="redundancy = 1000"), "map", ["planning.redundancy", "2^1000", "at most 64"]),
    ("redundancy 24", dict(planning="redundancy = 24"), "map", ["planning.redundancy", "at most 64"]),
    ("resolution 1e-320", {"res": "1e-320"}, "map",
     ["planning.resolution", "inf cells", "at most 2e+08"]),
    ("resolution coarser than the floor", {"res": "8.0"}, "map", ["planning.resolution", "at least 2 cells"]),
    ("obstacle 1e-300 wide", dict(extra="[[obstacles]]\ncenter = [3.0, 5.0]\nsize = [1e-300, 1.0]\n"), "map",
     ["obstacles[1].size", "at least 1e-09"]),
    ("polygon of 20000 vertices",
     dict(extra="[[obstacles]]\npolygon = " + json.dumps(
         [[3 + 0.5 * math.cos(2 * math.pi * i / 20000), 7 + 0.5 * math.sin(2 * math.pi * i / 20000)]
          for i in range(20000)]) + "\n"), "place", ["obstacles[1].polygon", "at most 10000 vertices, got 20000"]),
    ("TOML arrays nested 5000 deep", dict(extra="deep = " + "[" * 5000 + "]" * 5000 + "\n"), "map",
     ["nested 5000 deep", f"at most {MAX_NESTING}"]),
]


@pytest.mark.parametrize("label,parts,command,message", VALUES, ids=[v[0] for v in VALUES])
def test_scenario_value_over_budget_is_refused_before_the_work(tmp_path, label, parts, command, message):
    parts = dict(parts)
    res = parts.pop("res", None)
    text = MINI.format(**{"planning": "", "robot": "", "routes": "", "extra": "", **parts})
    if res is not None:
        text = text.replace("resolution = 0.5", f"resolution = {res}")
    refused(tmp_path, text, *message, command=command)


def test_mc_runs_capped_like_the_file(tmp_path):
    (tmp_path / "s.toml").write_text(MINI.format(planning="", robot="", routes="", extra=""))
    code, err = run(["mc", str(tmp_path / "s.toml"), "--runs", "1000000000000", "--workers", "1",
                     "--out", str(tmp_path / "out")])
    assert "at most 1e+07 runs" in holds(code, err)
    assert not (tmp_path / "out").exists()  # refused before the sweep directory is made


# --------------------------------------------------------------------------- under a memory cap

CHILD = """
import resource, sys
resource.setrlimit(resource.RLIMIT_AS, (8_000_000_000, 8_000_000_000))
from cli import main
sys.exit(main(["map", sys.argv[1]]))
"""


@pytest.mark.parametrize("case", ["self-insert", "alias bomb", "png 50000"])
def test_under_an_8_gb_cap_and_60_s(tmp_path, case):
    if case == "self-insert":
        doc = walled()
        self_inserting(doc, doc.modelspace())
        doc.saveas(tmp_path / "f.dxf")
        (tmp_path / "s.toml").write_text(drawing_toml())
    else:
        (tmp_path / "m.yaml").write_text(alias_bomb() if case == "alias bomb" else map_yaml("m.png"))
        png_claiming(tmp_path / "m.png", 50000, 50000)
        (tmp_path / "s.toml").write_text(map_toml())
    p = subprocess.run([sys.executable, "-c", CHILD, str(tmp_path / "s.toml")], capture_output=True, text=True,
                       timeout=60)
    holds(p.returncode, p.stderr)
    assert p.returncode == 2


# --------------------------------------------------------------------------- hypothesis

HOSTILE = st.sampled_from([NAN, INF, -INF, 0.0, -0.0, 1e300, -1e300, 1e-300, 1e8, 1e12, 5e-324])
NUMBER = st.one_of(st.floats(-20.0, 20.0), st.floats(-20.0, 20.0), HOSTILE)
POINT = st.tuples(NUMBER, NUMBER)


@st.composite
def drawings(draw):
    """Draw an ezdxf drawing: a room on layer W plus random entities, some in (nested, cyclic) blocks."""
    doc = walled()
    msp = doc.modelspace()
    blocks = []
    for b in range(draw(st.integers(0, 3))):
        blocks.append(doc.blocks.new(f"B{b}"))

    def entity(space, layer):
        kind = draw(st.sampled_from(["line", "arc", "circle", "poly", "spline", "ellipse", "point", "insert",
                                     "hatch"]))
        attrs = {"layer": layer}
        if kind == "line":
            space.add_line(draw(POINT), draw(POINT), dxfattribs=attrs)
        elif kind == "arc":
            space.add_arc(draw(POINT), draw(NUMBER), draw(NUMBER), draw(NUMBER), dxfattribs=attrs)
        elif kind == "circle":
            space.add_circle(draw(POINT), draw(NUMBER), dxfattribs=attrs)
        elif kind == "poly":
            pts = [(*draw(POINT), 0.0, 0.0, draw(st.sampled_from([0.0, 0.5, 1.0, NAN, 1e300])))
                   for _ in range(draw(st.integers(0, 5)))]
            space.add_lwpolyline(pts, format="xyseb", close=draw(st.booleans()), dxfattribs=attrs)
        elif kind == "spline":
            space.add_spline([draw(POINT) for _ in range(draw(st.integers(0, 4)))], dxfattribs=attrs)
        elif kind == "ellipse":
            space.add_ellipse(draw(POINT), (*draw(POINT), 0.0), draw(NUMBER), dxfattribs=attrs)
        elif kind == "point":
            space.add_point(draw(POINT), dxfattribs={"layer": "M"})
        elif kind == "hatch":
            h = space.add_hatch(dxfattribs=attrs)
            edges = h.paths.add_edge_path()
            edges.add_arc(draw(POINT), draw(NUMBER), draw(NUMBER), draw(NUMBER))
            edges.add_line(draw(POINT), draw(POINT))
        elif blocks or draw(st.booleans()):
            name = f"B{draw(st.integers(0, max(len(blocks) - 1, 0)))}" if blocks else "MISSING"
            ref = space.add_blockref(name, draw(POINT), dxfattribs={
                **attrs, "xscale": draw(NUMBER), "yscale": draw(NUMBER), "rotation": draw(NUMBER)})
            if draw(st.booleans()):
                ref.grid(size=(draw(st.integers(1, 40)), draw(st.integers(1, 40))), spacing=(1.0, 1.0))

    try:
        for block in blocks:
            for _ in range(draw(st.integers(1, 3))):
                entity(block, draw(st.sampled_from(["0", "W"])))
        for _ in range(draw(st.integers(1, 5))):
            entity(msp, "W")
    except (ValueError, TypeError, ZeroDivisionError, ezdxf.DXFError):
        assume(False)  # ezdxf refuses to write it: not a file a user can have
    return doc


@profile(25)
@given(doc=drawings())
def test_random_drawings_keep_the_contract(tmp_path, doc):
    try:
        doc.saveas(tmp_path / "f.dxf")
    except (ValueError, TypeError, AssertionError, ezdxf.DXFError):
        assume(False)  # ezdxf does not write it (an ELLIPSE ratio out of range, ...)
    (tmp_path / "s.toml").write_text(drawing_toml(marker=bool(doc.modelspace().query('POINT[layer=="M"]'))))
    line = holds(*run(["map", str(tmp_path / "s.toml")]))
    event(line.split(": ")[-2][:40] if line else "exit 0")  # --hypothesis-show-statistics


YAML_VALUES = st.sampled_from(["0.05", "5e-2", "1e-320", "-1", "0", ".nan", ".inf", "abc", "[1, 2]", "{}", "",
                               "1e300", "*x", "&x 0.1"])


@st.composite
def maps(draw, folder: Path):
    """Write a map YAML and an image: random header values, sizes, pixel modes, or raw header bytes."""
    w, h = draw(st.integers(0, 30)), draw(st.integers(0, 30))  # 0: no image
    kind = draw(st.sampled_from(["L", "RGB", "RGBA", "1", "P", "I;16", "pgm-bytes", "png-header", "missing"]))
    image = "m.png"
    if kind == "pgm-bytes":
        image = "m.pgm"
        claimed = draw(st.sampled_from([f"{w} {h}", "60000 60000", "-1 5", "0 0", "99999999999 1", "5"]))
        (folder / image).write_bytes(f"P5\n{claimed}\n255\n".encode() + bytes(draw(st.binary(max_size=200))))
    elif kind == "png-header":
        png_claiming(folder / image, draw(st.integers(1, 2**31 - 1)), draw(st.integers(1, 2**31 - 1)))
    elif kind != "missing" and w and h:
        pixels = draw(st.lists(st.integers(0, 255), min_size=w * h, max_size=w * h))
        img = Image.fromarray(np.array(pixels, dtype=np.uint8).reshape(h, w)).convert(kind)
        img.save(folder / image)
    else:
        image = "missing.png"
    fields = {"image": image, "resolution": draw(st.sampled_from(["0.05", "0.1", "5e-2"])),
              "origin": "[0.0, 0.0, 0.0]", "negate": "0", "occupied_thresh": "0.65", "free_thresh": "0.196",
              "mode": draw(st.sampled_from(["trinary", "scale", "raw"]))}
    if draw(st.integers(0, 2)) == 0:  # a third of the headers have a bad value
        fields[draw(st.sampled_from(sorted(fields)))] = draw(YAML_VALUES)
    text = "".join(f"{k}: {v}\n" for k, v in fields.items())
    if draw(st.integers(0, 4)) == 0:
        text = draw(st.sampled_from([alias_bomb(), "[" * 5000, "a: [" * 200, "- 1\n- 2\n", "image: m.png\n: :"]))
    (folder / "m.yaml").write_text(text)


@profile(25)
@given(data=st.data())
def test_random_maps_keep_the_contract(tmp_path_factory, data):
    folder = tmp_path_factory.mktemp("map")
    data.draw(maps(folder))
    (folder / "s.toml").write_text(map_toml())
    line = holds(*run(["map", str(folder / "s.toml")]))
    event(line.split(": ")[-2][:40] if line else "exit 0")  # --hypothesis-show-statistics


JSON_LEAF = st.one_of(st.none(), st.booleans(), st.integers(-10, 10), st.floats(-20, 20), st.text(max_size=3))
JSON = st.recursive(JSON_LEAF, lambda inner: st.lists(inner, max_size=3) | st.dictionaries(
    st.sampled_from(["type", "features", "layouts", "nodes", "edges", "id", "layoutId", "nodeId", "edgeId",
                     "startNodeId", "endNodeId", "nodePosition", "geometry", "properties", "coordinates", "x", "y",
                     "startid", "endid"]), inner, max_size=4), max_leaves=20)


def nav2(nodes: list, edges: list) -> dict:
    return {"type": "FeatureCollection", "features": [
        *({"type": "Feature", "geometry": {"type": "Point", "coordinates": xy}, "properties": {"id": i}}
          for i, xy in nodes),
        *({"type": "Feature", "geometry": {"type": "LineString", "coordinates": []},
           "properties": {"id": 100 + k, "startid": a, "endid": b}} for k, (a, b) in enumerate(edges))]}


@st.composite
def graphs(draw) -> str:
    """Draw a route graph file: random JSON, a Nav2 or LIF graph with random values, or deep nesting."""
    kind = draw(st.sampled_from(["json", "nav2", "lif", "deep"]))
    if kind == "deep":
        n = draw(st.integers(1, 3000))
        return draw(st.sampled_from(["[" * n + "]" * n, '{"a":' * n + "1" + "}" * n, "[" * n]))
    if kind == "json":
        return json.dumps(draw(JSON))
    ids = st.one_of(st.integers(0, 4), st.sampled_from(["a", "", None, 1.5, True]))
    xy = st.one_of(st.tuples(st.floats(0.5, 9.5), st.floats(0.5, 9.5)).map(list),
                   st.sampled_from([[NAN, 1.0], [1e300, 1.0], [1.0], "x", None]))
    nodes = draw(st.lists(st.tuples(ids, xy), max_size=5))
    edges = draw(st.lists(st.tuples(ids, ids), max_size=5))
    if kind == "nav2":
        doc = nav2(nodes, edges)
    else:
        doc = {"layouts": [{"layoutId": "L", "nodes": [{"nodeId": i, "nodePosition": {"x": p[0], "y": p[1]}
                                                        if isinstance(p, list) and len(p) == 2 else p}
                                                       for i, p in nodes],
                            "edges": [{"edgeId": 100 + k, "startNodeId": a, "endNodeId": b}
                                      for k, (a, b) in enumerate(edges)]}]}
    try:
        return json.dumps(doc)
    except ValueError:
        assume(False)


@profile(40)
@given(text=graphs())
def test_random_route_graphs_keep_the_contract(tmp_path, text):
    (tmp_path / "g.json").write_text(text)
    (tmp_path / "s.toml").write_text(graph_toml())
    line = holds(*run(["map", str(tmp_path / "s.toml")]))
    event(line.split(": ")[-2][:40] if line else "exit 0")  # --hypothesis-show-statistics


# =========================================================================== second round: by class
#
# By class of defect: each test draws its inputs (hypothesis, few examples) and holds the same
# contract; the sizes are drawn just over each budget, so a budget that moved or a check that
# ran after the work would show.

from scenarios.limits import (  # noqa: E402
    MAX_CANDIDATES,
    MAX_FIT_POINTS,
    MAX_GRAPH_NODES,
    MAX_MARKERS,
    MAX_NAME_BYTES,
    MAX_SCENARIO_BYTES,
    MAX_SPLINE_FIT_POINTS,
    MAX_WORLDS,
)


def mini(**parts: str) -> str:
    return MINI.format(**{"planning": "", "robot": "", "routes": "", "extra": "", **parts})


def run_warned(argv: list[str]) -> tuple[int, str, list[str]]:
    """Run ``pefsim ARGV`` in-process; return the exit code, stderr without warnings, and pefsim's warnings.

    The CLI prints pefsim's own warnings as ``pefsim: warning: ...`` lines (each must be one
    line); any other warning fails.
    """
    from scenarios.errors import ScenarioWarning

    out, err = io.StringIO(), io.StringIO()
    with warnings.catch_warnings(record=True) as caught, contextlib.redirect_stdout(out), \
            contextlib.redirect_stderr(err):
        warnings.simplefilter("always")
        code = main(argv)
    others = [w for w in caught if not issubclass(w.category, ScenarioWarning)]
    assert not others, [f"{w.category.__name__}: {w.message} ({w.filename}:{w.lineno})" for w in others]
    lines = [str(w.message) for w in caught]
    assert all("\n" not in line for line in lines), lines  # each warning is one line
    printed = [ln for ln in err.getvalue().splitlines() if ln.startswith("pefsim: warning: ")]
    rest = "".join(ln + "\n" for ln in err.getvalue().splitlines() if not ln.startswith("pefsim: warning: "))
    return code, rest, lines + [ln.removeprefix("pefsim: warning: ") for ln in printed]


@pytest.fixture
def no_work(monkeypatch):
    """Make every PEF fail loudly: a refusal must come before the work."""
    from planner.pef import map as pef_map

    def boom(*_a, **_k):
        raise AssertionError("the work started before the input was refused")

    monkeypatch.setattr(pef_map.PEF, "__init__", boom)


# --- class 1: tracebacks (long integers, link loops, huge splines, long output names) -------------

@profile(6)
@given(digits=st.integers(4301, 6000), where=st.sampled_from(["seed", "position", "size"]))
def test_an_integer_too_long_for_python_is_one_line(tmp_path, digits, where):
    big = "7" * digits
    text = {"seed": mini().replace('name = "mini"', f'name = "mini"\nseed = {big}'),
            "position": mini().replace("position = [0.0, 0.0]", f"position = [{big}, 0.0]"),
            "size": mini().replace("size = [10.0, 10.0]", f"size = [{big}, 10.0]")}[where]
    refused(tmp_path, text, f"an integer of {digits} digits", "s.toml")


@profile(6)
@given(digits=st.integers(4301, 6000), kind=st.sampled_from(["nav2", "lif"]))
def test_a_route_graph_integer_too_long_is_one_line(tmp_path, digits, kind):
    doc = (nav2([(0, [1.0, 123456789]), (1, [9.0, 9.0])], [(0, 1)]) if kind == "nav2" else
           {"layouts": [{"layoutId": "L", "nodes": [{"nodeId": "a", "nodePosition": {"x": 123456789, "y": 1}}],
                         "edges": []}]})
    (tmp_path / "g.json").write_text(json.dumps(doc).replace("123456789", "9" * digits))
    refused(tmp_path, graph_toml(), "g.json", f"an integer of {digits} digits")


@pytest.mark.parametrize("what", ["scenario", "drawing", "route graph", "map yaml"])
def test_a_symbolic_link_loop_is_named_as_one(tmp_path, what):
    names = {"scenario": "s.toml", "drawing": "f.dxf", "route graph": "g.json", "map yaml": "m.yaml"}
    os.symlink(names[what], tmp_path / names[what])  # a link to itself
    if what == "scenario":
        line = holds(*run(["map", str(tmp_path / "s.toml")]))
    else:
        text = {"drawing": drawing_toml(), "route graph": graph_toml(), "map yaml": map_toml()}[what]
        line = refused(tmp_path, text)
    assert "symbolic link loop" in line and names[what] in line, line


@pytest.mark.parametrize("path,cause", [("/dev/zero", "character device"), (".", "directory"),
                                        ("fifo.toml", "FIFO")])
def test_a_scenario_that_is_no_regular_file_is_named_for_what_it_is(tmp_path, monkeypatch, path, cause):
    monkeypatch.chdir(tmp_path)
    if path == "fifo.toml":
        os.mkfifo(tmp_path / path)
    line = holds(*run(["map", path]))
    assert cause in line and "no such" not in line, line


@profile(4)
@given(n=st.integers(MAX_SPLINE_FIT_POINTS + 1, MAX_SPLINE_FIT_POINTS + 3000))
def test_a_spline_over_its_fit_point_budget_is_refused_before_interpolation(tmp_path, n):
    doc = walled()
    doc.modelspace().add_spline(fit_points=[(1 + 8 * i / n, 5 + 0.01 * (i % 2)) for i in range(n)],
                                dxfattribs={"layer": "W"})
    doc.saveas(tmp_path / "f.dxf")
    refused(tmp_path, drawing_toml(), "SPLINE #", f"at most {MAX_SPLINE_FIT_POINTS} fit points", f"found {n}")


def test_splines_over_the_drawings_fit_point_budget_are_refused(tmp_path):
    doc = walled()
    b = doc.blocks.new("S")
    b.add_spline(fit_points=[(i / 500, 0.01 * (i % 2)) for i in range(500)], dxfattribs={"layer": "0"})
    doc.modelspace().add_blockref("S", (1, 5), dxfattribs={"layer": "W"}).grid(
        size=(MAX_FIT_POINTS // 500 + 1, 1), spacing=(0.001, 1.0))
    doc.saveas(tmp_path / "f.dxf")
    refused(tmp_path, drawing_toml(), f"at most {MAX_FIT_POINTS} spline fit points in the drawing")


def test_a_30000_point_spline_under_an_8_gb_cap(tmp_path):
    doc = walled()
    doc.modelspace().add_spline(fit_points=[(1 + i * 2.5e-4, 5 + 0.01 * (i % 2)) for i in range(30_000)],
                                dxfattribs={"layer": "W"})
    doc.saveas(tmp_path / "f.dxf")
    (tmp_path / "s.toml").write_text(drawing_toml())
    p = subprocess.run([sys.executable, "-c", CHILD, str(tmp_path / "s.toml")], capture_output=True, text=True,
                       timeout=60)
    assert "fit points" in holds(p.returncode, p.stderr)


@profile(5)
@given(extra=st.integers(1, 200), command=st.sampled_from(["map", "plan", "mc"]))
def test_an_output_name_too_long_is_refused_before_the_work(tmp_path_factory, no_work, extra, command):
    folder = tmp_path_factory.mktemp("out")
    (folder / "s.toml").write_text(mini())
    name = "x" * (MAX_NAME_BYTES + extra)
    if command == "mc":  # the default folder mc-<scenario name>
        (folder / "s.toml").write_text(mini().replace('name = "mini"', f'name = "{name}"'))
        argv = ["mc", str(folder / "s.toml"), "--runs", "1", "--workers", "1"]
    else:
        argv = [command, str(folder / "s.toml"), "-o", str(folder / f"{name}.png")]
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        line = holds(*run(argv))
    finally:
        os.chdir(cwd)
    assert "file name too long" in line and f"at most {MAX_NAME_BYTES}" in line, line
    assert sorted(p.name for p in folder.iterdir()) == ["s.toml"]  # nothing made


# --- class 2: a library warning (measurement_time = 0) --------------------------------------------

@profile(20)
@given(v=st.lists(st.floats(0.05, 2.0), min_size=2, max_size=6), ds=st.lists(st.floats(0.1, 5.0), min_size=5,
                                                                              max_size=5),
       frac=st.floats(0.0, 1.2))
def test_an_instantaneous_fix_has_the_speed_where_it_is_taken(v, ds, frac):
    """``mean_speed(..., 0)`` is the limit of ever shorter fixes: the mean speed of a 1e-6 s fix.

    Bound: the acceleration between vertices is at most (2 m/s)^2 / (2 * 0.1 m) = 20 m/s^2, so
    over d = 1e-6 s the mean speed differs from the speed at the start by at most 20 d / 2 =
    1e-5 m/s; rounding of s (<= 25 m, two ulps of 3.6e-15 m) adds at most 7.2e-15 / d < 1e-8 m/s.
    """
    from planner.schedule.pathtime import Kinematics, mean_speed

    s_v = np.concatenate([[0.0], np.cumsum(ds[: len(v) - 1])])
    kin = Kinematics(s_v, np.array(v))
    t = np.array([frac * kin.t_v[-1]])
    at = mean_speed(kin, t, 0.0)
    assert np.isfinite(at).all()
    if t[0] + 1e-6 < kin.t_v[-1]:
        assert abs(at[0] - mean_speed(kin, t, 1e-6)[0]) <= 1e-5 + 1e-8
    else:
        assert at[0] == 0.0  # the path is done


def test_measurement_time_zero_plans_without_nan_or_warnings():
    """An instantaneous fix plans: finite speeds everywhere, no numpy warning (run with every warning an error)."""
    import pefsim
    from scenarios import loads

    text = (Path(__file__).resolve().parents[1] / "scenarios" / "library" / "paper-docks.toml").read_text()
    assert "measurement_time = 0.02" in text
    sc = loads(text.replace("measurement_time = 0.02", "measurement_time = 0.0"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        plan = pefsim.plan(sc)
    assert np.isfinite(plan.speed).all() and plan.schedule
    assert all(math.isfinite(f.speed) for f in plan.schedule.fixes)


# --- class 3: sizes with no budget ----------------------------------------------------------------

@profile(3)
@given(over=st.integers(1, 50))
def test_markers_over_budget_are_refused_before_they_are_read(tmp_path, over):
    n = MAX_MARKERS + over
    markers = "".join(f'[[markers]]\nid = "m{i}"\nposition = [{(i % 90) * 0.1:.1f}, {i // 90 * 0.001:.3f}]\n'
                      for i in range(n))
    refused(tmp_path, mini(extra=markers), "markers:", f"at most {MAX_MARKERS} markers", f"got {n + 2}")


@profile(3)
@given(over=st.integers(1, 1000))
def test_placement_candidates_over_budget_are_refused(tmp_path, over):
    n = MAX_CANDIDATES + over
    refused(tmp_path, mini(extra="[placement]\ncandidates = [" + ", ".join(["[1.0, 1.0]"] * n) + "]\n"),
            "placement.candidates", f"at most {MAX_CANDIDATES}", f"got {n}")


def test_a_scenario_file_over_budget_is_refused_before_it_is_parsed(tmp_path):
    text = mini() + "# " + "x" * MAX_SCENARIO_BYTES + "\n"
    refused(tmp_path, text, "s.toml", f"at most {MAX_SCENARIO_BYTES:.0e}")


@profile(2)
@given(kind=st.sampled_from(["nav2", "lif"]), over=st.integers(1, 100))
def test_a_route_graph_over_its_node_budget_is_refused(tmp_path, kind, over):
    n = MAX_GRAPH_NODES + over
    if kind == "nav2":
        node = '{"type":"Feature","geometry":{"type":"Point","coordinates":[1,1]},"properties":{"id":%d}}'
        text = '{"type":"FeatureCollection","features":[' + ",".join(node % i for i in range(n)) + "]}"
    else:
        node = '{"nodeId":"%d","nodePosition":{"x":1,"y":1}}'
        text = '{"layouts":[{"layoutId":"L","nodes":[' + ",".join(node % i for i in range(n)) + '],"edges":[]}]}'
    (tmp_path / "g.json").write_text(text)
    refused(tmp_path, graph_toml(), "g.json", f"a route graph of {n} nodes", f"at most {MAX_GRAPH_NODES}")


@profile(5)
@given(exponent=st.integers(-320, -6))
def test_a_map_resolution_over_the_cell_budget_is_refused_before_allocation(tmp_path, exponent):
    (tmp_path / "s.toml").write_text(mini())
    line = holds(*run(["map", str(tmp_path / "s.toml"), "--resolution", f"1e{exponent}"]))
    assert "resolution" in line and "cells (at most" in line, line


def test_a_map_resolution_of_1e_7_under_a_small_memory_cap(tmp_path):
    """1e-7 m used to allocate 1.2 GB of cell centres before refusing: now refused under a 1 GB cap."""
    (tmp_path / "s.toml").write_text(mini())
    child = CHILD.replace("8_000_000_000", "1_000_000_000").replace('["map", sys.argv[1]]',
                                                                        '["map", sys.argv[1], "--resolution", "1e-7"]')
    p = subprocess.run([sys.executable, "-c", child, str(tmp_path / "s.toml")], capture_output=True, text=True,
                       timeout=60)
    assert "cells (at most" in holds(p.returncode, p.stderr)


def test_worlds_count_over_budget_is_refused_before_anything_is_made(tmp_path):
    line = holds(*run(["worlds", "--count", str(MAX_WORLDS + 1), "--out", str(tmp_path / "w")]))
    assert f"at most {MAX_WORLDS} worlds" in line and not (tmp_path / "w").exists()


def test_worlds_are_written_as_they_are_drawn(tmp_path, monkeypatch):
    """A run stopped at world 2 keeps worlds 0 and 1 on disk (they used to be written only at the end)."""
    import pefsim
    from planner import worlds as planner_worlds
    from planner.worlds import PlannedWorld

    def fake(seed, index, **_k):
        if index == 2:
            assert (tmp_path / "w" / "random-0-1.toml").exists()  # written before the next is drawn
            raise KeyboardInterrupt
        return PlannedWorld(name=f"random-0-{index}", text=f"# world {index}\n", scenario=None, attempts=1,
                            summary=("drawn",))

    monkeypatch.setattr(planner_worlds, "plannable_world", fake)
    with pytest.raises(KeyboardInterrupt):
        pefsim.worlds(5, out=tmp_path / "w")
    assert sorted(p.name for p in (tmp_path / "w").iterdir()) == ["random-0-0.toml", "random-0-1.toml"]


# --- class 4: geometry dropped in silence ---------------------------------------------------------

def open_room() -> ezdxf.document.Drawing:
    """Return a 20 x 20 m room drawn as four wall lines on layer W (its inside is free)."""
    doc = ezdxf.new("R2018")
    doc.layers.add("W")
    msp = doc.modelspace()
    for a, b in (((0, 0), (20, 0)), ((20, 0), (20, 20)), ((20, 20), (0, 20)), ((0, 20), (0, 0))):
        msp.add_line(a, b, dxfattribs={"layer": "W"})
    return doc


def obstacle_area(tmp_path) -> "shapely.Geometry":  # noqa: F821
    import shapely

    from scenarios.floorplan.dxf import read_dxf

    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        found = read_dxf(tmp_path / "f.dxf", obstacle_layers=["W"], units="m", simplify=0.0)
    return shapely.union_all([shapely.Polygon(o["polygon"], o.get("holes", [])) if "polygon" in o
                              else shapely.Point(o["center"]).buffer(o["radius"]) for o in found.obstacles])


BOX = st.tuples(st.floats(3.0, 15.0), st.floats(3.0, 15.0), st.floats(0.3, 2.0), st.floats(0.3, 2.0))


@profile(8)
@given(box=BOX, z=st.floats(-5.0, 5.0), kind=st.sampled_from(["3dface", "polyface", "polymesh"]))
def test_faces_and_meshes_are_read_as_their_footprint(tmp_path, box, z, kind):
    import shapely

    x, y, w, h = box
    corners = [(x, y, z), (x + w, y, z), (x + w, y + h, z + 1.0), (x, y + h, z + 1.0)]
    doc = open_room()
    msp = doc.modelspace()
    if kind == "3dface":
        msp.add_3dface(corners, dxfattribs={"layer": "W"})
    elif kind == "polyface":
        pf = msp.add_polyface(dxfattribs={"layer": "W"})
        pf.append_face(corners)
    else:
        pm = msp.add_polymesh((2, 2), dxfattribs={"layer": "W"})
        for (i, j), p in zip([(0, 0), (1, 0), (1, 1), (0, 1)], corners, strict=True):
            pm.set_mesh_vertex((i, j), p)
    doc.saveas(tmp_path / "f.dxf")
    footprint = shapely.box(x, y, x + w, y + h)
    assert obstacle_area(tmp_path).intersection(footprint).area == pytest.approx(footprint.area, rel=1e-6)
    (tmp_path / "s.toml").write_text(drawing_toml())
    code, err, said = run_warned(["map", str(tmp_path / "s.toml")])
    assert holds(code, err) == "" and said == []


@profile(8)
@given(widths=st.lists(st.tuples(st.floats(0.0, 1.0), st.floats(0.0, 1.0)), min_size=3, max_size=3))
def test_an_open_polyline_with_widths_is_a_wall_of_its_largest_width(tmp_path, widths):
    import shapely

    doc = open_room()
    pts = [(4.0, 10.0), (10.0, 10.0), (16.0, 10.0)]
    doc.modelspace().add_lwpolyline([(*p, *w, 0.0) for p, w in zip(pts, widths, strict=True)], format="xyseb",
                                    dxfattribs={"layer": "W"})
    doc.saveas(tmp_path / "f.dxf")
    widest = max(max(w) for w in widths)
    assume(widest > 0.01)
    band = obstacle_area(tmp_path).intersection(shapely.box(5.0, 1.0, 15.0, 19.0))  # not the room walls
    assert band.area == pytest.approx(10.0 * widest, rel=1e-6)  # 10 m of wall, widest across


@profile(8)
@given(texts=st.integers(0, 3), points=st.integers(0, 3), xrefs=st.integers(0, 3))
def test_what_is_not_read_on_an_obstacle_layer_is_said_in_one_line(tmp_path, texts, points, xrefs):
    doc = open_room()
    msp = doc.modelspace()
    for i in range(texts):
        msp.add_text(f"T{i}", dxfattribs={"layer": "W"})
    for i in range(points):
        msp.add_point((5 + i, 5), dxfattribs={"layer": "W"})
    if xrefs:
        doc.blocks.new("XREF1", dxfattribs={"flags": 4, "xref_path": "other.dxf"})
        for i in range(xrefs):
            msp.add_blockref("XREF1", (2 + i, 2), dxfattribs={"layer": "W"})
    doc.saveas(tmp_path / "f.dxf")
    (tmp_path / "s.toml").write_text(drawing_toml())
    code, err, said = run_warned(["map", str(tmp_path / "s.toml")])
    assert code == 0 and "Traceback" not in err
    if not (texts or points or xrefs):
        assert said == []
        return
    assert len(said) == 1, said
    for n, what in ((texts, "TEXT"), (points, "POINT")):
        assert (f"{n} {what}" in said[0]) == bool(n), said
    assert (f'{xrefs} of "XREF1"' in said[0]) == bool(xrefs), said


# --- class 5: ambiguity accepted ------------------------------------------------------------------

@profile(5)
@given(lid=st.text(st.characters(min_codepoint=48, max_codepoint=122), min_size=1, max_size=5),
       extra=st.integers(0, 2))
def test_two_lif_layouts_with_one_id_are_refused(tmp_path, lid, extra):
    layouts = [{"layoutId": f"other{i}", "nodes": [], "edges": []} for i in range(extra)]
    layouts += [{"layoutId": lid, "nodes": [], "edges": []}, {"layoutId": lid, "nodes": [], "edges": []}]
    (tmp_path / "g.json").write_text(json.dumps({"layouts": layouts}))
    toml = graph_toml().replace('file = "g.json"\n', f'file = "g.json"\nlayout = {json.dumps(lid)}\n')
    refused(tmp_path, toml, f"layouts[{extra + 1}].layoutId", "unique layout id", f"layouts[{extra}]")


@profile(6)
@given(key=st.sampled_from(["image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh"]))
def test_a_map_yaml_key_written_twice_is_refused_by_name(tmp_path, key):
    text = map_yaml()
    line = next(ln for ln in text.splitlines() if ln.startswith(f"{key}:"))
    (tmp_path / "m.yaml").write_text(text + line + "\n")
    (tmp_path / "m.pgm").write_bytes(b"P5\n40 40\n255\n" + bytes([254] * 1600))
    refused(tmp_path, map_toml(), "m.yaml", f"duplicate key '{key}'")


@profile(6)
@given(pair=st.sampled_from([("--routes", "--lif", ".json"), ("--lif", "--routes", ".json")]),
       spelling=st.sampled_from(["same", "./same", "sub/../same"]))
def test_two_outputs_at_one_path_are_refused_before_the_work(tmp_path_factory, no_work, pair, spelling):
    folder = tmp_path_factory.mktemp("export")
    (folder / "sub").mkdir()
    (folder / "s.toml").write_text(mini())
    a, b, suffix = pair
    argv = ["export", str(folder / "s.toml"), a, str(folder / f"same{suffix}"), b, str(folder / f"{spelling}{suffix}")]
    line = holds(*run(argv))
    assert "name the same file" in line and a.lstrip("-") in line and b.lstrip("-") in line, line
    assert sorted(p.name for p in folder.iterdir()) == ["s.toml", "sub"]


# --- class 6: messages that named the wrong cause -------------------------------------------------

@profile(5)
@given(cut=st.floats(0.05, 0.95))
def test_a_drawing_cut_short_is_named_truncated(tmp_path, cut):
    walled().saveas(tmp_path / "whole.dxf")
    data = (tmp_path / "whole.dxf").read_bytes()
    (tmp_path / "f.dxf").write_bytes(data[: int(cut * len(data))])
    line = refused(tmp_path, drawing_toml(), "f.dxf", "truncated")
    assert "expected a layer" not in line


@profile(5)
@given(text=st.sampled_from([mini(), map_toml(), drawing_toml()]))
def test_a_byte_order_mark_is_read(tmp_path, text):
    from scenarios import loads

    walled().saveas(tmp_path / "f.dxf")
    (tmp_path / "m.yaml").write_text(map_yaml())
    (tmp_path / "m.pgm").write_bytes(b"P5\n40 40\n255\n" + bytes([254] * 1600))
    (tmp_path / "s.toml").write_text("\ufeff" + text, encoding="utf-8")
    from scenarios import load

    assert load(tmp_path / "s.toml").obstacles == loads(text, base=tmp_path).obstacles


@profile(5)
@given(n=st.integers(1, 3), clash=st.integers(1, 3))
def test_a_clash_with_a_generated_reflector_id_names_it_as_generated(tmp_path, n, clash):
    assume(clash <= n)
    doc = walled()
    for i in range(n):
        doc.modelspace().add_point((11.0 + i, 1.0), dxfattribs={"layer": "M"})
    doc.saveas(tmp_path / "f.dxf")
    toml = drawing_toml(marker=True) + f'[[markers]]\nid = "R{clash}"\nposition = [10.5, 5.0]\n'
    line = refused(tmp_path, toml, "markers[0].id", f'"R{clash}"', "generated", "f.dxf")
    assert f"markers[{clash}]" not in line


@pytest.mark.parametrize("key,value,message", [
    ("seed", str(2**70), "at most 9.22e+18"), ("seed", "-1", "expected an integer >= 0"),
    ("name", '""', "expected a non-empty name"), ("name", '"   "', "expected a non-empty name")])
def test_top_level_values_the_readme_refuses(tmp_path, key, value, message):
    text = mini().replace('name = "mini"\n', "" if key == "name" else 'name = "mini"\n')
    refused(tmp_path, f"{key} = {value}\n" + text, f"{key}:", message)
