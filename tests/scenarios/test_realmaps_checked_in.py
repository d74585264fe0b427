"""The public maps in ``tests/data/realmaps`` are the files their authors published, and load.

The digests are those of ``tests/data/realmaps/README.md`` (its table, read here, so the two
cannot drift apart); a changed byte fails. The scenarios around them load with their map read
relative to the scenario, and the depot's route graph with the repeated edge ids its authors
wrote said once.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

import pytest

import scenarios
from scenarios.errors import ScenarioWarning

HERE = Path(__file__).resolve().parents[1] / "data" / "realmaps"


def _published() -> dict[str, str]:
    rows = re.findall(r"^\| `([^`]+)` \|.*\| `([0-9a-f]{64})` \|$", (HERE / "README.md").read_text(), re.M)
    return dict(rows)


def test_every_map_file_is_the_published_one():
    digests = _published()
    assert set(digests) == {"tb3_world.pgm", "tb3_world.yaml", "depot.pgm", "depot.yaml", "depot_graph.geojson"}
    for name, want in digests.items():
        assert hashlib.sha256((HERE / name).read_bytes()).hexdigest() == want, name
    assert "Apache License" in (HERE / "LICENSE-Apache-2.0.txt").read_text()


def test_a_changed_byte_is_told():
    """Negative control: the digest of a map with one byte changed is not the published one."""
    data = bytearray((HERE / "tb3_world.pgm").read_bytes())
    data[-1] ^= 1
    assert hashlib.sha256(bytes(data)).hexdigest() != _published()["tb3_world.pgm"]


def test_the_scenarios_load_their_maps_where_they_lie():
    tb3 = scenarios.load(str(HERE / "tb3_world.toml"))
    assert tb3.floorplan is not None and not tb3.markers
    with pytest.warns(ScenarioWarning, match="repeated edge ids"):
        depot = scenarios.load(str(HERE / "depot.toml"))
    assert len(depot.routes.nodes) == 34 and len(depot.routes.segments) == 39
