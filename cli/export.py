"""``pefsim export``: results back to the user's tools — route graph, markers, drawing, LIF, keepout mask.

``--routes`` writes the route network as a Nav2 route graph (GeoJSON) whose edges carry the
PEF along them; ``--markers`` the markers as CSV (with kind and facing); ``--dxf`` a drawing
with the navigation region's contour τ = ε_max and the route lines labelled with their worst τ
(inadmissible ones on their own layer); ``--lif`` a VDA LIF file keeping every id, each node
with its τ as ``allowedDeviationXY``; ``--keepout`` a Nav2 keepout mask (YAML + PGM). Each
file's format comes from its extension (else one error line, before any work). Only the files
asked for are written; at least one must be. The work is :func:`pefsim.export`.
"""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("export", help="route graph (Nav2 GeoJSON, VDA LIF), markers (CSV), drawing (DXF), "
                                      "Nav2 keepout mask",
                       description="Write the scenario's results for the user's tools.")
    p.add_argument("scenario", help="scenario file or built-in name")
    p.add_argument("--routes", metavar="GEOJSON",
                   help="the route network as a Nav2 route graph, edges with max_tau, mean_tau [m], "
                        "min_visible, admissible, why_not")
    p.add_argument("--markers", metavar="CSV", help="markers: id,x,y [m],x_mm,y_mm,kind,facing_deg")
    p.add_argument("--dxf", metavar="DXF", help="drawing: obstacles, markers, the contour tau = eps_max, routes "
                                                "labelled with their worst tau, inadmissible ones on their own layer")
    p.add_argument("--lif", metavar="JSON", help="the route network as a VDA LIF file, every id kept, each node's "
                                                 "tau as nodePosition.allowedDeviationXY [m]")
    p.add_argument("--keepout", metavar="YAML", help="Nav2 keepout mask: this map_server YAML and a PGM beside it, "
                                                     "occupied outside the navigation region")
    p.add_argument("--json", action="store_true", help="print what was written as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import pefsim
    from cli import print_json

    written = pefsim.export(args.scenario, routes=args.routes, markers=args.markers, dxf=args.dxf, lif=args.lif,
                            keepout=args.keepout)
    if args.json:
        print_json(written.to_dict())
        return 0
    for paths in written.values():
        for path in paths:
            print(f"wrote {path}")
    return 0
