"""Routes through a map document: what ``pipemap route`` prints, for a script too.

:func:`load_map` reads a map document (``pipemap replay -o MAP.json``, ``pipemap map
--json``) and checks that it can be routed in; :func:`route` plans the shortest way
between two of its junctions by the pipes' driven lengths
(:func:`pipemap.localizer.plan_route`). A file that is not a map, a map without
ports, or a node the map does not have raises :class:`~pipemap.errors.InputError`.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from pipemap.errors import InputError
from pipemap.localizer import RouteStep, TopoMap, plan_route

__all__ = ["load_map", "route", "route_document"]


def load_map(path: str | Path) -> TopoMap:
    """The :class:`~pipemap.localizer.TopoMap` of a map document, with its ports;
    ``InputError`` naming the file and the problem otherwise."""
    path = Path(path)
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


def route_document(route: list[RouteStep]) -> list[dict[str, Any]]:
    """A route as ``--json`` prints it: one object per junction."""
    return [
        {"node": s.node, "arrive_port": s.arrive_port, "leave_port": s.leave_port, "edge": s.edge}
        for s in route
    ]


def route(topomap: TopoMap, start: int, goal: int, name: str = "the map") -> list[RouteStep] | None:
    """The shortest route from junction ``start`` to ``goal`` of ``topomap`` (``name``
    in messages), one step a junction; ``None`` when no pipe of the map joins them."""
    for flag, node in (("--from", start), ("--to", goal)):
        if not 0 <= node < topomap.node_count:
            raise InputError(
                f"{flag} {node}: no such node in {name} (nodes 0..{topomap.node_count - 1})"
            )
        if topomap.unused(node):
            raise InputError(f"{flag} {node}: {name} leaves that id unused (no junction)")
    return plan_route(topomap, start, goal)
