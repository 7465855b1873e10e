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
from typing import Any, TextIO

from pipemap.errors import InputError

__all__ = ["load_map", "route_document", "run_route"]


def load_map(path: Path) -> Any:
    """The :class:`localizer.TopoMap` of a map document, with its ports; ``InputError``
    naming the file and the problem otherwise."""
    from pipemap.localizer import TopoMap

    if not path.is_file():
        raise InputError(f"{path}: no such file")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{path}: not a JSON map document ({exc})") from None
    try:
        topomap = TopoMap.from_dict(doc)
    except ValueError as exc:
        raise InputError(f"{path}: malformed map: {exc}") from None
    if not topomap.node_count:
        raise InputError(f"{path}: the map has no junctions")
    if not topomap.has_ports:
        raise InputError(
            f"{path}: the map has no ports (it was made without the robot's exit scans); "
            "routes need them"
        )
    return topomap


def route_document(route: list[Any]) -> list[dict[str, Any]]:
    """A route as ``--json`` prints it: one object per junction."""
    return [
        {"node": s.node, "arrive_port": s.arrive_port, "leave_port": s.leave_port, "edge": s.edge}
        for s in route
    ]


def run_route(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    """Load the map, plan the route, print it; exit 1 when there is none."""
    from pipemap.localizer import describe_step, plan_route, route_length_m

    path = Path(args.map)
    topomap = load_map(path)
    for name, node in (("--from", args.start), ("--to", args.goal)):
        if node >= topomap.node_count:
            raise InputError(
                f"{name} {node}: no such node in {path} (nodes 0..{topomap.node_count - 1})"
            )
    route = plan_route(topomap, args.start, args.goal)
    if route is None:
        out.write(f"no route from node {args.start} to node {args.goal} in {path}\n")
        return 1
    if args.json:
        out.write(json.dumps(route_document(route), indent=2) + "\n")
        return 0
    for step in route:
        out.write(describe_step(step) + "\n")
    pipes = len(route) - 1
    length = route_length_m(topomap, route)
    out.write(f"{pipes} pipe{'s' if pipes != 1 else ''}, {length:.2f} m by the map\n")
    return 0
