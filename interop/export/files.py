"""The ``export`` of a scenario: which files were asked for, checked before the work, then written.

Each output comes from its own writer (:mod:`interop.export.routegraph`, ``markers``, ``dxf``,
``lif``, ``keepout``); this module checks the paths asked for (the extension names the format,
the names fit the file system, no two at one path), computes the PEF and the route reports once
for the outputs that need them, and calls the writers.
"""

from __future__ import annotations

import os
from pathlib import Path

from scenarios.errors import OutputError
from scenarios.output_names import check_output_names
from scenarios.schema import Scenario

EXPORT_FORMATS = {"routes": (".geojson", ".json"), "markers": (".csv",), "dxf": (".dxf",), "lif": (".json", ".lif"),
                  "keepout": (".yaml", ".yml")}
"""File extensions each output accepts (its format comes from them)."""


class Exported(dict):
    """What :func:`write_exports` wrote: output name -> tuple of paths (``keepout``: the YAML and the PGM)."""

    def to_dict(self) -> dict[str, str | list[str]]:
        """Return the paths as JSON holds them (what ``pefsim export --json`` prints): one path a string."""
        return {k: str(v[0]) if len(v) == 1 else [str(p) for p in v] for k, v in self.items()}


def check_exports(**outputs: str | os.PathLike[str] | None) -> dict[str, Path]:
    """Check the outputs asked for (None: not asked) before any work; return them as paths.

    Parameters
    ----------
    **outputs : str, path or None
        ``routes``, ``markers``, ``dxf``, ``lif``, ``keepout`` -> where to write it.

    Raises
    ------
    OutputError
        Nothing asked for, an extension that does not name the output's format, a name the file
        system cannot take, or two outputs at one path.
    """
    asked = {k: Path(v) for k, v in outputs.items() if v is not None}
    if not asked:
        raise OutputError(f"export: give at least one of {', '.join(EXPORT_FORMATS)}")
    for name, path in asked.items():
        if path.suffix.lower() not in EXPORT_FORMATS[name]:
            raise OutputError(f"{path}: {name}: expected a {' or '.join(EXPORT_FORMATS[name])} file, got "
                              f"{path.suffix or 'no extension'!r}")
    keepout_pgm = {"keepout (its image)": asked["keepout"].with_suffix(".pgm")} if "keepout" in asked else {}
    check_output_names({**asked, **keepout_pgm})
    return asked


def write_exports(scenario: Scenario, asked: dict[str, Path]) -> Exported:
    """Write the outputs ``asked`` (from :func:`check_exports`) for ``scenario``.

    Raises
    ------
    OutputError
        A route export (``routes``, ``lif``) of a scenario without a route network, before anything
        is computed; a file that cannot be written.
    """
    sc = scenario
    for name in ("routes", "lif"):
        if name in asked and sc.routes is None:
            raise OutputError(f"{name}: scenario {sc.name!r} has no route network ([routes]) to export")
    from planner.pef.map import PEF

    pef = PEF(sc)
    written = Exported()
    reports = None
    if sc.routes is not None and ("routes" in asked or "dxf" in asked):
        from planner.routes.edges import segment_reports

        reports = segment_reports(sc, pef)
    if "routes" in asked:
        from interop.export.routegraph import write_route_graph

        written["routes"] = (write_route_graph(asked["routes"], sc, reports),)
    if "markers" in asked:
        from interop.export.markers import write_markers_csv

        written["markers"] = (write_markers_csv(asked["markers"], sc),)
    if "dxf" in asked:
        from interop.export.dxf import write_dxf
        from interop.export.region import region_contours, route_lines

        contours = region_contours(pef.grid(), sc.planning.eps_max, sc.workspace.bounds)
        written["dxf"] = (write_dxf(sc, asked["dxf"], region_contours=contours, route_lines=route_lines(sc),
                                    route_reports=reports),)
    if "lif" in asked:
        from interop.export.lif import write_lif
        from planner.routes.admissible import tau_along

        names = list(sc.routes.nodes)
        # a node's deviation as its segments' end samples are judged (planner.routes.admissible)
        tau = tau_along(pef, [sc.routes.nodes[n] for n in names], sc.planning.resolution, sc.planning.eps_max)
        written["lif"] = (write_lif(asked["lif"], sc, dict(zip(names, map(float, tau), strict=True))),)
    if "keepout" in asked:
        from interop.export.keepout import write_keepout

        written["keepout"] = write_keepout(asked["keepout"], sc, pef)
    return written
