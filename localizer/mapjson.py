"""The map document: the topological map and its visits as deterministic JSON.

One format for every producer (``pipemap map`` over image folders, and replays of
logs): ``{"nodes": [{"id", "ports": [{"port", "angle_rad"}]}], "edges": [{"u",
"u_port", "v", "v_port", "label", "length_m"}], "visits": [{"set", "node", "known",
"similarity", "margin", ..., "arrival_port", "departure_port"}]}``. A node's ports
are empty, and the edges' ports ``null``, when the robot reported no exits. Floats
are rounded to 6 decimals so that the same input gives the same bytes on any
machine.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any

from pipemap.localizer.decision import Decision
from pipemap.localizer.topomap import MapVisit, TopoMap

__all__ = ["FLOAT_DECIMALS", "decision_record", "dumps_document", "map_document"]

#: Decimals kept in JSON floats: far below any meaningful similarity difference.
FLOAT_DECIMALS = 6


def _round(value: float | None) -> float | None:
    if value is None:
        return None
    rounded = round(float(value), FLOAT_DECIMALS)
    return 0.0 if rounded == 0 else rounded  # no "-0.0"


def decision_record(
    label: str, decision: Decision, visit: MapVisit | None = None
) -> dict[str, Any]:
    """One visit of the map document; ``visit`` (the map's record of it) adds the
    port it left by and any conflict its arrival met."""
    match, fit = decision.match, decision.two_view
    exits = decision.exits_rad
    node = decision.node if visit is None else visit.node
    return {
        "set": label,
        "node": node,
        # Where the map's hypotheses changed it: what the decision said at the time.
        **({"decided_node": decision.node} if node != decision.node else {}),
        "known": decision.known,
        # No candidate (the first visits): nothing was compared, so no similarity.
        "similarity": None if decision.candidate is None else _round(decision.similarity),
        "margin": _round(decision.margin),
        "candidate": decision.candidate,
        "image_shift": None if match is None else match.image_shift,
        "pixel_shift": None if match is None else _round(match.pixel_shift),
        "rotation_rad": None if match is None else _round(match.rotation_rad),
        "rotation_pinhole_rad": None if match is None else _round(match.rotation_pinhole_rad),
        "rotation_two_view_rad": None if fit is None else _round(fit.rotation_rad),
        "two_view_inliers": None if fit is None else fit.inliers,
        # Set when the fit matched only the first stages of the candidate's keypoints
        # (its inliers count those): TwoViewConfig.accept_share.
        "two_view_stages": None if fit is None else fit.stages,
        "probes": [
            {
                "kind": p.request.kind.value,
                "similarity": _round(p.similarity),
                "improved": p.improved,
            }
            for p in decision.probes
        ],
        "exits_rad": None if exits is None else [_round(e) for e in exits],
        "exit_ports": None if decision.exit_ports is None else list(decision.exit_ports),
        "arrival_port": decision.arrival_port,
        "departure_port": None if visit is None else visit.departure_port,
        "port_residual_rad": _round(decision.port_residual_rad),
        "rejected": [{"candidate": c, "reason": r} for c, r in decision.rejected],
        "conflict": None if visit is None else visit.conflict,
        **_hypotheses(decision),
    }


def _hypotheses(decision: Decision) -> dict[str, Any]:
    """The decision's hypotheses (:mod:`localizer.hypotheses`), when there were
    more than one map: how many lived after it, the junctions it was deferred
    among, the earlier visits it settled."""
    if decision.hypotheses == 1 and not decision.deferred and not decision.settled:
        return {}
    return {
        "hypotheses": decision.hypotheses,
        "deferred": list(decision.deferred),
        "settled": [{"visit": i, "node": n} for i, n in decision.settled],
    }


def map_document(
    topomap: TopoMap,
    visits: Sequence[tuple[str, Decision]],
    open_visits: Mapping[int, Sequence[int]] | None = None,
) -> dict[str, Any]:
    """The whole document: the map, then each visit with its label and decision (in
    the map's visit order, one decision per visit), and, when its hypotheses
    disagree on some visits (:attr:`Localizer.open_visits`), those visits with the
    junctions each may be, the map's first (``"open"``): nothing told them apart."""
    doc = topomap.to_dict()
    records = topomap.visit_records
    doc["visits"] = [
        decision_record(label, d, records[i] if i < len(records) else None)
        for i, (label, d) in enumerate(visits)
    ]
    if open_visits:
        doc["open"] = [{"visit": i, "nodes": list(n)} for i, n in sorted(open_visits.items())]
    return doc


def dumps_document(doc: dict[str, Any]) -> str:
    """Deterministic JSON text of a document (key order as built, two-space indent)."""
    return json.dumps(doc, indent=2, allow_nan=False) + "\n"
