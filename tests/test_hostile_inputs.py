"""Hostile inputs: files from other people's tools, bounded in time and memory, refused in one line.

Each case runs ``pefsim map`` in-process through :func:`sim.cli.main` with stderr captured and
every warning recorded, and holds the input contract: exit 0, or exit 2 with exactly one line
``pefsim: error: ...`` of at most 1000 characters; no traceback, no library warning. A few
cases that used to exhaust memory or hang run in a child process under an address-space cap
(``resource.setrlimit``) and a time limit.

- one test per defect of issue 27 (a DXF block that inserts itself, a NaN arc, a 50000 x 50000
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

from scenarios.errors import MAX_MESSAGE
from scenarios.limits import MAX_DXF_ENTITIES, MAX_MAP_PIXELS, MAX_NESTING, MAX_YAML_NODES
from sim.cli import main

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
from sim.cli import main
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
