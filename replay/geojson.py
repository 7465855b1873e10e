"""A replayed map as GeoJSON for GIS tools (``pipemap export RUN.mcap --geojson``).

Junctions are points, placed where the robot's dead reckoning was at the exit scan of
each junction's first visit (:func:`replay.results_log.junction_places`); pipes are
lines between the junctions they join, with the driven length and the ports at both
ends as properties. The coordinates are metres in a local frame, not longitude and
latitude: the frame of the robot's dead reckoning, with its start at the origin
(right-handed, z up, REP 103). The file says so in its ``frame`` member, and a
GIS layer takes it as a local engineering frame (in QGIS: set the layer's CRS to a
projected one of the site, then move the origin).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from pipemap.errors import WriteError
from pipemap.replay.replayer import ReplayResult
from pipemap.replay.results_log import junction_places

__all__ = ["FRAME", "map_geojson", "write_geojson"]

FRAME = (
    "local metric frame: metres, the frame of the robot's dead reckoning "
    "(/robot/controller), origin at its start, right-handed with z up (REP 103); "
    "not longitude/latitude"
)


def map_geojson(result: ReplayResult, name: str = "pipemap") -> dict[str, Any]:
    """The replay's map as a GeoJSON FeatureCollection (junctions without a place and
    the pipes that meet them are left out, and counted in ``unplaced``)."""
    document = result.document()
    places = junction_places(result)
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
        "frame": FRAME,
        "unplaced": {
            "junctions": len(document["nodes"]) - len(places),
            "pipes": len(document["edges"]) - placed_edges,
        },
        "features": features,
    }


def write_geojson(result: ReplayResult, output: str | Path, name: str = "pipemap") -> int:
    """Write :func:`map_geojson` to ``output``; returns the features written."""
    collection = map_geojson(result, name)
    try:
        Path(output).write_text(json.dumps(collection, indent=1) + "\n")
    except OSError as exc:
        raise WriteError(f"{output}: cannot write ({exc.strerror or exc})") from None
    return len(collection["features"])
