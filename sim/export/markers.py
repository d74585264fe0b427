"""Markers as CSV: ``id,x,y,x_mm,y_mm``, positions in the scenario's (the user's) frame."""

from __future__ import annotations

import csv
import io
from pathlib import Path

from scenarios.errors import output_errors
from scenarios.schema import Scenario

HEADER = ("id", "x", "y", "x_mm", "y_mm")


def markers_csv(scenario: Scenario) -> str:
    """Return the CSV text: a header and one row per marker, x, y in metres (6 decimals) and mm (3)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(HEADER)
    for m in scenario.markers:
        x, y = m.position
        w.writerow([m.id, f"{x:.6f}", f"{y:.6f}", f"{x * 1000:.3f}", f"{y * 1000:.3f}"])
    return buf.getvalue()


def write_markers_csv(path: str | Path, scenario: Scenario) -> Path:
    """Write :func:`markers_csv` to ``path``; raises OutputError if it cannot."""
    out = Path(path)
    text = markers_csv(scenario)
    with output_errors(out, "write the markers"):
        out.write_text(text, encoding="utf-8")
    return out
