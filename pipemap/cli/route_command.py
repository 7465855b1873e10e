"""``pipemap route``: the way through a map from one junction to another.

Reads a map document (``pipemap replay -o MAP.json``, ``pipemap map --json``),
plans the shortest route by the pipes' driven lengths (:mod:`localizer.routes`) and
prints it junction by junction, or as a JSON list with ``--json``. A file that is
not a map, a map without ports, or a node the map does not have: one line, exit 2.
No way between the two junctions in the map: one line, exit 1.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TextIO

__all__ = ["run_route"]


def run_route(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    """Load the map, plan the route, print it; exit 1 when there is none."""
    from pipemap import api
    from pipemap.localizer import describe_step, route_length_m

    path = Path(args.map)
    topomap = api.load_map(path)
    route = api.route(topomap, args.start, args.goal, str(path))
    if route is None:
        out.write(f"no route from node {args.start} to node {args.goal} in {path}\n")
        return 1
    if args.json:
        out.write(json.dumps(api.route_document(route), indent=2) + "\n")
        return 0
    for step in route:
        out.write(describe_step(step) + "\n")
    pipes = len(route) - 1
    length = route_length_m(topomap, route)
    out.write(f"{pipes} pipe{'s' if pipes != 1 else ''}, {length:.2f} m by the map\n")
    return 0
