"""Markers as CSV: ``id,x,y,x_mm,y_mm,kind,facing_deg``, positions in the scenario's (the user's) frame.

``kind`` is ``post`` or ``flat``; ``facing_deg`` the direction a flat reflector faces
(degrees, counter-clockwise from +x, in [0, 360)), empty when the marker has none.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

from scenarios.errors import output_errors
from scenarios.schema import Scenario

HEADER = ("id", "x", "y", "x_mm", "y_mm", "kind", "facing_deg")


def markers_csv(scenario: Scenario) -> str:
    """Return the CSV text: a header and one row per marker, x, y in metres (6 decimals) and mm (3)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(HEADER)
    for m in scenario.markers:
        x, y = m.position
        facing = "" if m.facing is None else f"{math.degrees(m.facing) % 360.0:.6f}"
        w.writerow([m.id, f"{x:.6f}", f"{y:.6f}", f"{x * 1000:.3f}", f"{y * 1000:.3f}", m.kind.value, facing])
    return buf.getvalue()


def write_markers_csv(path: str | Path, scenario: Scenario) -> Path:
    """Write :func:`markers_csv` to ``path``; raises OutputError if it cannot."""
    out = Path(path)
    text = markers_csv(scenario)
    with output_errors(out, "write the markers"):
        out.write_text(text, encoding="utf-8")
    return out
