"""A replayed map as GeoJSON for GIS tools (``pipemap export RUN.mcap --geojson``).

Junctions are points, placed where the robot's dead reckoning was at the exit scan of
each junction's first visit (:func:`replay.results_log.junction_places`); pipes are
lines between the junctions they join, with the driven length and the ports at both
ends as properties. The coordinates are metres in a local frame, not longitude and
latitude: the frame of the robot's dead reckoning, with its start at the origin
(right-handed, z up, REP 103). The file says so in its ``frame`` member, and a
GIS layer takes it as a local engineering frame (in QGIS: set the layer's CRS to a
projected one of the site, then move the origin).

A map document alone (``pipemap export MAP.json --geojson``) holds no positions: its
junctions are placed by chaining its ports and driven pipe lengths from junction 0
(:func:`chained_places`), in a frame the file names as well.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from pipemap.errors import InputError, WriteError
from pipemap.localizer import TopoMap
from pipemap.replay.replayer import ReplayResult
from pipemap.replay.results_log import junction_places

__all__ = [
    "CHAINED_FRAME",
    "FRAME",
    "chained_places",
    "document_geojson",
    "map_geojson",
    "read_map_document",
    "write_geojson",
]

FRAME = (
    "local metric frame: metres, the frame of the robot's dead reckoning "
    "(/robot/controller), origin at its start, right-handed with z up (REP 103); "
    "not longitude/latitude"
)
CHAINED_FRAME = (
    "local metric frame: metres, origin at junction 0, x along the heading the robot "
    "arrived at it with, right-handed with z up (REP 103); junctions placed by chaining "
    "the map's ports and driven pipe lengths, pipes taken as straight; "
    "not longitude/latitude"
)


def map_geojson(result: ReplayResult, name: str = "pipemap") -> dict[str, Any]:
    """The replay's map as a GeoJSON FeatureCollection (junctions without a place and
    the pipes that meet them are left out, and counted in ``unplaced``)."""
    return _collection(result.document(), junction_places(result), name, FRAME)


def read_map_document(path: str | Path) -> dict[str, Any]:
    """A map document (``pipemap replay -o MAP.json``, ``pipemap map --json``), checked
    as :meth:`TopoMap.from_dict` checks it; an :class:`InputError` naming the file
    and the problem otherwise."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
        TopoMap.from_dict(document)
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{path}: not a JSON map document ({exc})") from None
    except ValueError as exc:
        raise InputError(f"{path}: malformed map: {exc}") from None
    if not document["nodes"]:
        raise InputError(f"{path}: the map has no junctions")
    return dict(document)


def chained_places(document: dict[str, Any]) -> dict[int, tuple[float, float]]:
    """Junction places from the map alone, by chaining its own dead reckoning.

    Junction 0 is at the origin, its arrival heading along x. Leaving a placed
    junction by a port, the pipe runs straight along the port's angle for its driven
    length (``length_m``) to the next junction, which the robot enters by the edge's
    port there: that port points back along the pipe, which fixes the junction's own
    arrival heading, and so on, along every edge with both ports and a length, in
    the document's edge order, until nothing more can be placed. Junctions not
    reached so (another component, pipes without ports) have no place.
    """
    angles = {n["id"]: [p["angle_rad"] for p in n["ports"]] for n in document["nodes"]}
    placed: dict[int, tuple[float, float, float]] = {0: (0.0, 0.0, 0.0)}  # x, y, heading
    grew = True
    while grew:
        grew = False
        for edge in document["edges"]:
            ends = ((edge["u"], edge.get("u_port")), (edge["v"], edge.get("v_port")))
            length = edge.get("length_m")
            for (a, a_port), (b, b_port) in (ends, ends[::-1]):
                if a not in placed or b in placed or None in (a_port, b_port, length):
                    continue
                x, y, heading = placed[a]
                out = heading + angles[a][a_port]
                x, y = x + length * math.cos(out), y + length * math.sin(out)
                placed[b] = (x, y, out + math.pi - angles[b][b_port])
                grew = True
    return {node: (x, y) for node, (x, y, _) in placed.items()}


def document_geojson(document: dict[str, Any], name: str = "pipemap") -> dict[str, Any]:
    """A map document as GeoJSON, its junctions placed by :func:`chained_places`."""
    return _collection(document, chained_places(document), name, CHAINED_FRAME)


def _collection(
    document: dict[str, Any], places: dict[int, tuple[float, float]], name: str, frame: str
) -> dict[str, Any]:
    visits: dict[int, int] = {}
    for v in document["visits"]:
        visits[v["node"]] = visits.get(v["node"], 0) + 1
    features: list[dict[str, Any]] = []
    for node in document["nodes"]:
        if node["id"] not in places:
            continue
        x, y = places[node["id"]]
        features.append(
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [x, y]},
                "properties": {
                    "kind": "junction",
                    "node": node["id"],
                    "visits": visits.get(node["id"], 0),
                    "ports": len(node["ports"]),
                    "port_angles_rad": [p["angle_rad"] for p in node["ports"]],
                },
            }
        )
    placed_edges = 0
    for edge in document["edges"]:
        if edge["u"] not in places or edge["v"] not in places:
            continue
        placed_edges += 1
        features.append(
            {
                "type": "Feature",
                "geometry": {
                    "type": "LineString",
                    "coordinates": [list(places[edge["u"]]), list(places[edge["v"]])],
                },
                "properties": {
                    "kind": "pipe",
                    "from_node": edge["u"],
                    "from_port": edge.get("u_port"),
                    "to_node": edge["v"],
                    "to_port": edge.get("v_port"),
                    "length_m": edge.get("length_m"),
                },
            }
        )
    return {
        "type": "FeatureCollection",
        "name": name,
        "frame": frame,
        "unplaced": {
            "junctions": len(document["nodes"]) - len(places),
            "pipes": len(document["edges"]) - placed_edges,
        },
        "features": features,
    }


def write_geojson(
    result: ReplayResult | dict[str, Any], output: str | Path, name: str = "pipemap"
) -> int:
    """Write :func:`map_geojson` of a replay's result, or :func:`document_geojson` of
    a map document, to ``output``; returns the features written."""
    if isinstance(result, ReplayResult):
        collection = map_geojson(result, name)
    else:
        collection = document_geojson(result, name)
    try:
        Path(output).write_text(json.dumps(collection, indent=1) + "\n")
    except OSError as exc:
        raise WriteError(f"{output}: cannot write ({exc.strerror or exc})") from None
    return len(collection["features"])
