"""``pefsim export``: results back to the user's tools — route graph, markers, drawing.

``--routes`` writes the route network as a Nav2 route graph (GeoJSON) whose edges carry the
PEF along them (:mod:`sim.export.routegraph`); ``--markers`` the markers as CSV
(:mod:`sim.export.markers`); ``--dxf`` a drawing with the navigation region's contour
τ = ε_max and the route lines (:func:`sim.export.dxf.write_dxf`). Only the files asked for are
written; at least one must be.
"""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("export", help="route graph (Nav2 GeoJSON), markers (CSV), drawing (DXF)",
                       description="Write the scenario's results for the user's tools.")
    p.add_argument("scenario", help="scenario file or built-in name")
    p.add_argument("--routes", metavar="GEOJSON",
                   help="the route network as a Nav2 route graph, edges with max_tau, mean_tau [m], "
                        "min_visible, admissible, why_not")
    p.add_argument("--markers", metavar="CSV", help="markers: id,x,y [m],x_mm,y_mm")
    p.add_argument("--dxf", metavar="DXF", help="drawing: obstacles, markers, the contour tau = eps_max, routes")
    p.add_argument("--json", action="store_true", help="print what was written as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import scenarios
    from planner.pef.map import PEF
    from scenarios.errors import OutputError, PefsimError
    from sim.cli import print_json

    if not (args.routes or args.markers or args.dxf):
        raise PefsimError("export: give at least one of --routes, --markers, --dxf")
    sc = scenarios.load(args.scenario)
    if args.routes and sc.routes is None:
        raise PefsimError(f"--routes: scenario {sc.name!r} has no route network ([routes]) to export")
    write_dxf = None
    if args.dxf:
        try:
            from sim.export.dxf import write_dxf
        except ImportError:
            raise OutputError(f"{args.dxf}: cannot write the drawing: DXF export (sim.export.dxf) is not "
                              "available in this installation") from None
    pef = PEF(sc)
    written = []
    if args.routes:
        from planner.routes.edges import segment_reports
        from sim.export.routegraph import write_route_graph

        written.append(("routes", str(write_route_graph(args.routes, sc, segment_reports(sc, pef)))))
    if args.markers:
        from sim.export.markers import write_markers_csv

        written.append(("markers", str(write_markers_csv(args.markers, sc))))
    if write_dxf is not None:
        from sim.export.region import region_contours, route_lines

        contours = region_contours(pef.grid(), sc.planning.eps_max, sc.workspace.bounds)
        write_dxf(sc, args.dxf, region_contours=contours, route_lines=route_lines(sc))
        written.append(("dxf", str(args.dxf)))
    if args.json:
        print_json(dict(written))
        return 0
    for _, path in written:
        print(f"wrote {path}")
    return 0
