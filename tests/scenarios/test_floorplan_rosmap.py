"""ROS map_server maps: PGM and PNG written with Pillow, map_server thresholds, traced polygons, errors."""

from __future__ import annotations

import time

import numpy as np
import pytest
import shapely

from scenarios import ScenarioError
from scenarios.floorplan.rosmap import read_rosmap
from scenarios.floorplan.trace import trace
from tests.scenarios import drawings as dr

RES = 0.05


def union(data, parts=("obstacles", "unknown")):
    """Return the area the map does not know as free: its obstacles and its unknown areas."""
    return shapely.union_all([shapely.Polygon(o["polygon"], o.get("holes", []))
                              for part in parts for o in getattr(data, part)])


def expected_area(img, obstacle):
    return float(obstacle(img).sum()) * RES * RES


def not_free(img):
    """map_server trinary, negate 0: free iff (255 - v) / 255 < 0.196."""
    return ~((255.0 - img) / 255.0 < 0.196)


@pytest.mark.parametrize("suffix", [".pgm", ".png"])
def test_trinary_map_occupied_cells_are_obstacles_unknown_cells_unknown(tmp_path, suffix):
    img = dr.map_image()
    path = dr.write_map(tmp_path, img, suffix=suffix)
    if suffix == ".pgm":
        assert (tmp_path / "map.pgm").read_bytes()[:2] == b"P5"
    data = read_rosmap(path, simplify=0.0)
    area = union(data)
    assert area.area == pytest.approx(expected_area(img, not_free))
    assert union(data, ("obstacles",)).area == pytest.approx(expected_area(img, lambda i: i == dr.OCCUPIED))
    assert union(data, ("unknown",)).area == pytest.approx(expected_area(img, lambda i: i == dr.UNKNOWN))
    # The map: origin (-1, -2), 100 x 80 cells of 5 cm, all of it known (its border is walls).
    assert data.extent == pytest.approx((-1.0, -2.0, -1.0 + 5.0, -2.0 + 4.0))
    assert data.known == pytest.approx(data.extent) and not data.walls and data.resolution == RES
    # Image row r is y = -2 + (80 - r) * 0.05 at its top edge: the block's rows 20..29 and
    # columns 40..49 are y in [0.5, 1.0], x in [1.0, 1.5]; its hole rows 23..26, columns 43..46.
    block = [shapely.Polygon(o["polygon"], o.get("holes", [])) for o in data.obstacles]
    block = [p for p in block if p.covers(shapely.Point(1.01, 0.51))]
    assert len(block) == 1 and block[0].bounds == pytest.approx((1.0, 0.5, 1.5, 1.0))
    assert len(block[0].interiors) == 1
    assert shapely.Polygon(block[0].interiors[0]).bounds == pytest.approx((1.15, 0.65, 1.35, 0.85))
    # The unknown patch (shade 205: p = 0.196..., between the thresholds) is unknown.
    assert union(data, ("unknown",)).covers(shapely.Point(-1.0 + 12 * RES, -2.0 + (80 - 62) * RES))
    assert not area.covers(shapely.Point(2.0, 1.5))


def test_negate_inverts_the_shades(tmp_path):
    img = dr.map_image()
    plain = read_rosmap(dr.write_map(tmp_path, img, name="a"), simplify=0.0)
    neg = read_rosmap(dr.write_map(tmp_path, 255 - img, name="b", negate=1), simplify=0.0)
    assert union(neg).symmetric_difference(union(plain)).area == pytest.approx(0.0)


def test_threshold_edges_follow_map_server(tmp_path):
    # p exactly free_thresh is not free (map_server: free iff p < free_thresh); just below is.
    img = np.full((10, 10), 254, dtype=np.uint8)
    img[0, 0] = 204  # p = 51/255 = 0.2
    img[0, 5] = 205  # p = 0.1961 < 0.2
    path = dr.write_map(tmp_path, img, yaml_extra="")
    path.write_text(path.read_text().replace("free_thresh: 0.196", "free_thresh: 0.2"))
    data = read_rosmap(path, simplify=0.0)
    assert len(data.obstacles) + len(data.unknown) == 1
    assert union(data).area == pytest.approx(RES * RES)
    assert union(data).bounds == pytest.approx((-1.0, -2.0 + 9 * RES, -1.0 + RES, -2.0 + 10 * RES))


def test_scale_mode_png_transparent_pixels_are_unknown(tmp_path):
    rgba = np.zeros((20, 20, 4), dtype=np.uint8)
    rgba[..., :3] = 254
    rgba[..., 3] = 255
    rgba[5:8, 5:8, 3] = 0        # transparent free-looking pixels: unknown in scale mode
    rgba[12:14, 12:16, :3] = 100  # p = 0.61: between the thresholds, unknown too
    path = dr.write_map(tmp_path, rgba, suffix=".png", mode="scale")
    data = read_rosmap(path, simplify=0.0)
    assert union(data).area == pytest.approx((9 + 8) * RES * RES)


def test_raw_mode_values_are_percent(tmp_path):
    img = np.zeros((10, 10), dtype=np.uint8)  # 0 = free
    img[1, 1] = 100                           # occupied
    img[2, 5] = 255                           # unknown
    img[7, 7] = 10                            # p = 0.1 < free_thresh: free
    img[8, 8] = 50                            # between: unknown
    data = read_rosmap(dr.write_map(tmp_path, img, mode="raw"), simplify=0.0)
    assert union(data).area == pytest.approx(3 * RES * RES)


def test_simplify_defaults_to_the_resolution_and_removes_staircases(tmp_path):
    img = np.full((200, 200), 254, dtype=np.uint8)
    r, c = np.mgrid[:200, :200]
    img[(np.abs(r - c) <= 3)] = 0  # a diagonal wall: a staircase of cells
    data = read_rosmap(dr.write_map(tmp_path, img))
    assert data.simplify == RES
    exact = read_rosmap(dr.write_map(tmp_path, img, name="b"), simplify=0.0)
    n = sum(len(o["polygon"]) for o in data.obstacles)
    n_exact = sum(len(o["polygon"]) for o in exact.obstacles)
    assert n < n_exact / 20
    assert union(data).hausdorff_distance(union(exact)) <= RES + 1e-9  # within the tolerance


def test_trace_matches_the_cells_and_is_fast_on_a_2000_square_map():
    rng = np.random.default_rng(5)
    occ = np.zeros((2000, 2000), dtype=bool)
    occ[:4], occ[-4:], occ[:, :4], occ[:, -4:] = True, True, True, True
    for _ in range(300):  # racks, rooms and clutter
        y, x = rng.integers(10, 1950, size=2)
        h, w = rng.integers(2, 60, size=2)
        occ[y:y + h, x:x + w] = True
    occ |= rng.random(occ.shape) < 0.002  # sensor specks
    t0 = time.perf_counter()
    polys = trace(occ)
    dt = time.perf_counter() - t0
    assert sum(p.area for p in polys) == pytest.approx(occ.sum(), abs=200)  # saddles filled: a few cells more
    assert all(shapely.is_valid(polys))
    assert dt < 10.0, f"tracing 2000 x 2000 took {dt:.1f} s"


def test_diagonal_cells_are_joined_so_polygons_stay_valid():
    occ = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=bool)
    polys = trace(occ)
    assert len(polys) == 1 and polys[0].is_valid and polys[0].area == 5.0


@pytest.mark.parametrize("edit, pattern", [
    (lambda t: t.replace("resolution: 0.05", "resolution: -1"), r"map.yaml: resolution: expected a number > 0, got -1"),
    (lambda t: t.replace("resolution: 0.05\n", ""), r"map.yaml: resolution: missing required key"),
    (lambda t: t + "mode: fancy\n", r'map.yaml: mode: expected one of "trinary", "scale", "raw", got "fancy"'),
    (lambda t: t + "colour: red\n", r'map.yaml: colour: unknown key, got "red"'),
    (lambda t: t.replace("[-1.0, -2.0, 0.0]", "[-1.0, -2.0, 0.5]"), r"map.yaml: origin: expected yaw 0"),
    (lambda t: t.replace("[-1.0, -2.0, 0.0]", "[-1.0, -2.0]"), r"map.yaml: origin: expected \[x, y, yaw\]"),
    (lambda t: t.replace("image: map.pgm", "image: other.pgm"), r"map.yaml: image: cannot read the map image .*other"),
    (lambda t: "image: [unclosed\n", r"map.yaml: malformed YAML"),
    (lambda t: "- just a list\n", r"map.yaml: expected a map_server YAML mapping"),
])
def test_bad_yaml(tmp_path, edit, pattern):
    path = dr.write_map(tmp_path, dr.map_image())
    path.write_text(edit(path.read_text()))
    with pytest.raises(ScenarioError, match=pattern):
        read_rosmap(path, where="hall.toml: floorplan", shown="map.yaml")


def test_truncated_and_unreadable_images(tmp_path):
    path = dr.write_map(tmp_path, dr.map_image())
    pgm = tmp_path / "map.pgm"
    pgm.write_bytes(pgm.read_bytes()[:-500])  # the header's 100 x 80 no longer matches the data
    with pytest.raises(ScenarioError, match=r"floorplan.file: map.yaml: image: cannot read the map image .*map.pgm"):
        read_rosmap(path, where="hall.toml: floorplan", shown="map.yaml")
    pgm.write_text("not an image")
    with pytest.raises(ScenarioError, match=r"image: expected a PGM or PNG image"):
        read_rosmap(path, shown="map.yaml")
    with pytest.raises(ScenarioError, match=r"floorplan.file: cannot read gone.yaml: No such file"):
        read_rosmap(tmp_path / "gone.yaml", shown="gone.yaml")
